"""The node kit: descriptors from the parameter table, time conversions, the main() policy."""

import math

from builtin_interfaces.msg import Time
import pytest
import rclpy
from rclpy.parameter import Parameter
from stealth_node_kit import running
from stealth_node_kit.conversions import quaternion_yaw, seconds, time_msg, yaw_quaternion
from stealth_node_kit.param_table import Unset, as_declared, value_problem
from stealth_node_kit.parameters import Param, StartupError, descriptor, non_finite
from stealth_node_kit.running import EXIT_CANNOT_START, run_node


def test_integer_and_float_bounds_become_the_matching_ranges():
    ints = descriptor(Param(3, 'count', (0, 10), read_only=True))
    assert ints.read_only and ints.description == 'count'
    assert (ints.integer_range[0].from_value, ints.integer_range[0].to_value) == (0, 10)
    assert not ints.floating_point_range
    floats = descriptor(Param(0.5, 'rate', (0.0, math.pi)))
    assert floats.floating_point_range[0].to_value == math.pi and not floats.integer_range
    assert not floats.read_only
    free = descriptor(Param('x', 'free'))
    assert not free.integer_range and not free.floating_point_range


@pytest.mark.parametrize(
    ('param', 'value', 'problem'),
    [
        (Param(0.5, 'rate', (0.0, 1.0)), 1, None),
        (Param(0.5, 'rate', (0.0, 1.0)), 1.5, 'expected a number from 0 to 1, got 1.5'),
        (Param(0.5, 'rate', (0.0, 1.0)), 'abc', "expected a number from 0 to 1, got 'abc'"),
        (Param(0.5, 'rate', (0.0, 1.0)), math.nan, 'expected a number from 0 to 1, got nan'),
        (Param(0.5, 'free'), math.inf, 'expected a finite number, got inf'),
        (Param(3, 'count', (0, 10)), 2.0, 'expected a whole number from 0 to 10, got 2.0'),
        (Param(3, 'count', (0, 10)), True, 'expected a whole number from 0 to 10, got True'),
        (Param(False, 'flag'), 0, 'expected true or false, got 0'),
        (Param('x', 'name'), 5, 'expected a string, got 5'),
        (Param(Unset('DOUBLE_ARRAY'), 'pose'), [1, 2.5], None),
        (Param(Unset('DOUBLE_ARRAY'), 'pose'), ['a'], "expected a list of numbers, got ['a']"),
        (Param(Unset('STRING_ARRAY'), 'topics'), [], None),
    ],
)
def test_a_value_is_checked_as_rclpy_declares_the_parameter(param, value, problem):
    assert value_problem(param, value) == problem


def test_a_whole_number_for_a_double_is_made_a_float():
    made = as_declared(Param(0.5, 'rate'), 1)
    assert made == 1.0 and isinstance(made, float)
    assert as_declared(Param(Unset('DOUBLE_ARRAY'), 'pose'), [1, 2]) == [1.0, 2.0]
    assert as_declared(Param(3, 'count'), 1) == 1 and as_declared(Param(0.5, 'rate'), True) is True


def test_non_finite_names_the_parameter():
    changes = [Parameter('alpha', value=0.5), Parameter('gamma', value=math.nan)]
    assert non_finite(changes) == 'gamma must be finite, got nan'
    assert non_finite([Parameter('n', value=3), Parameter('e', value=0.1)]) is None


@pytest.mark.parametrize('value', [0.0, 1.5, 1e-9, 12345.000000001, 1.999999999])
def test_time_conversions_round_trip_to_the_nanosecond(value):
    stamp = time_msg(value)
    assert 0 <= stamp.nanosec < 1_000_000_000
    assert seconds(stamp) == pytest.approx(value, abs=1e-9)
    assert seconds(Time(sec=2, nanosec=500_000_000)) == 2.5


@pytest.mark.parametrize('yaw', [0.0, 0.3, -2.0, math.pi - 1e-9])
def test_yaw_quaternion_round_trip(yaw):
    assert quaternion_yaw(yaw_quaternion(yaw)) == pytest.approx(yaw)


def test_a_node_that_cannot_start_gives_exit_code_2_and_one_line(capfd):
    def broken():
        raise RuntimeError('parameter scenario: required, at /src/rcl/arguments.c:42')

    assert run_node(broken, 'kit_test', args=[]) == EXIT_CANNOT_START
    err = capfd.readouterr().err
    assert 'not starting: parameter scenario: required' in err
    assert 'arguments.c' not in err and 'Traceback' not in err


def test_bad_arguments_give_exit_code_2_without_building_the_node(capfd):
    built = []
    args = ['prog', '--ros-args', '--params-file', '/nonexistent/params.yaml']
    assert run_node(lambda: built.append(1), 'kit_test', args=args) == EXIT_CANNOT_START
    assert not built
    assert 'not starting: bad arguments' in capfd.readouterr().err


def test_a_node_stopped_while_it_starts_exits_quietly(capfd):
    def interrupted():
        raise KeyboardInterrupt

    assert run_node(interrupted, 'kit_test', args=[]) == 0
    assert 'Traceback' not in capfd.readouterr().err


def test_a_node_whose_context_is_shut_down_while_it_starts_exits_quietly(capfd):
    """The context shut down from elsewhere while the node is built, an rcl call failing on
    it: a stop, not a node that cannot start."""

    def stopped_mid_build():
        rclpy.shutdown()
        raise RuntimeError('rcl node creation failed: the given context is not valid')

    assert run_node(stopped_mid_build, 'kit_test', args=[]) == 0
    assert 'not starting' not in capfd.readouterr().err


@pytest.mark.parametrize('error', [StartupError('parameter map: required'), KeyboardInterrupt()])
def test_a_node_whose_set_up_fails_destroys_itself(error, monkeypatch):
    import rclpy

    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')  # this machine only
    monkeypatch.delenv('ROS_LOCALHOST_ONLY', raising=False)
    from stealth_node_kit.running import StartupNode

    destroyed = []

    class Refusing(StartupNode):
        def set_up(self):
            raise error

        def destroy_node(self):
            destroyed.append(self.get_name())
            return super().destroy_node()

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=231)
    try:
        with pytest.raises(type(error)):
            Refusing('refusing', context=context)
        assert destroyed == ['refusing']
    finally:
        context.try_shutdown()


@pytest.mark.parametrize('cause', ['context down', 'stop signal', None])
def test_an_error_while_spinning_is_the_stop_only_after_a_stop(cause, monkeypatch):
    """A stop signal's KeyboardInterrupt raised while pybind11 converts a message being taken
    comes out as a plain RuntimeError (seen: an agent's exit code 1 at a run's end), and so can
    a context shut down from elsewhere: the stop (exit 0). The same error otherwise is a real
    failure."""
    import rclpy

    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')  # this machine only
    monkeypatch.delenv('ROS_LOCALHOST_ONLY', raising=False)
    finished = []

    def failing_spin(nodes, stop):
        if cause == 'context down':
            rclpy.try_shutdown()
        elif cause == 'stop signal':
            stop.received = True
        raise RuntimeError("Unable to convert call argument '0' to Python object")

    monkeypatch.setattr(running, 'spin_until_shutdown', failing_spin)

    def make():
        return rclpy.create_node('kit_spin_test')

    if cause:
        assert run_node(make, 'kit_test', args=[], on_exit=finished.append) == 0
    else:
        with pytest.raises(RuntimeError, match='Unable to convert'):
            run_node(make, 'kit_test', args=[], on_exit=finished.append)
        rclpy.try_shutdown()
    assert len(finished) == 1  # on_exit ran either way (the policy is saved, totals logged)


def test_a_node_that_asks_to_stop_stops_in_order(monkeypatch):
    """StopRequested from a callback: the exit hook runs with the context still up, the node's
    reliable messages are waited for (none unacknowledged: nobody subscribes), exit 0."""
    from std_msgs.msg import String
    from stealth_node_kit.running import StopRequested

    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')  # this machine only
    monkeypatch.delenv('ROS_LOCALHOST_ONLY', raising=False)
    seen = []

    def make():
        node = rclpy.create_node('kit_stop_test')
        publisher = node.create_publisher(String, 'kit_stop_words', 10)

        def give_up():
            publisher.publish(String(data='the last word'))
            raise StopRequested('given up')

        node.create_timer(0.05, give_up)
        return node

    def on_exit(node):
        seen.append((rclpy.ok(), [p.topic_name for p in node.publishers]))

    assert run_node(make, 'kit_test', args=[], on_exit=on_exit) == 0
    assert seen and seen[0][0] and '/kit_stop_words' in seen[0][1]
    assert running.wait_for_acknowledgements([], 0.0) == []
    assert not rclpy.ok()


@pytest.mark.parametrize('orphaned', [False, True])
def test_an_orphan_stops_without_waiting_for_acknowledgements(orphaned, monkeypatch):
    """A node whose parent died (a killed orchestrator) does not wait for its subscribers: the
    dead parent's readers stay matched until their lease ends (5 s held every time)."""
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')  # this machine only
    monkeypatch.delenv('ROS_LOCALHOST_ONLY', raising=False)
    waited = []
    monkeypatch.setattr(
        running, 'wait_for_acknowledgements', lambda nodes, t, give_up: waited.append(t)
    )

    def stop_at_once(nodes, stop):
        if orphaned:  # the parent dies while the node spins: init adopts it
            monkeypatch.setattr(running.os, 'getppid', lambda: 1)
        raise KeyboardInterrupt

    monkeypatch.setattr(running, 'spin_until_shutdown', stop_at_once)
    assert run_node(lambda: rclpy.create_node('kit_orphan_test'), 'kit_test', args=[]) == 0
    assert waited == ([] if orphaned else [running.ACK_WAIT])


def test_waiting_for_acknowledgements_ends_at_the_deadline_or_when_told_to_give_up():
    """A reader that never acknowledges (a dead one, still matched): the wait ends at its
    deadline, or at the first look after give_up() turns true (the parent died meanwhile)."""
    import time
    from types import SimpleNamespace

    from rclpy.qos import ReliabilityPolicy

    waits = []

    def never_acked(timeout):
        waits.append(timeout.nanoseconds / 1e9)
        time.sleep(waits[-1])
        return False

    reliable = SimpleNamespace(reliability=ReliabilityPolicy.RELIABLE)
    node = SimpleNamespace(
        publishers=[SimpleNamespace(qos_profile=reliable, topic_name=f'/t{i}',
                                    wait_for_all_acked=never_acked) for i in range(2)]
    )  # fmt: skip
    started = time.monotonic()
    assert running.wait_for_acknowledgements([node], 0.35) == ['/t0', '/t1']
    assert 0.3 <= time.monotonic() - started < 1.0 and max(waits) <= running.ACK_SLICE
    waits.clear()
    assert running.wait_for_acknowledgements([node], 5.0, lambda: len(waits) >= 3) == [
        '/t0', '/t1'
    ]  # fmt: skip
    assert len(waits) == 4  # three slices for the first, then one look for the second


STUCK_STOP = """
import time
import rclpy
from stealth_node_kit import running
running.STOP_LIMIT = 1.0
running.wait_for_acknowledgements = lambda nodes, timeout, give_up: time.sleep(60)
def stop_at_once(nodes, stop):
    raise KeyboardInterrupt
running.spin_until_shutdown = stop_at_once
running.run_node(lambda: rclpy.create_node('kit_stuck_test'), 'kit_test', args=[])
"""


def test_a_stop_stuck_after_the_exit_hook_dumps_its_stacks_and_exits_1():
    """An orphan has no one to kill it: a stop that hangs prints where, and ends."""
    import os
    import subprocess
    import sys

    env = {**os.environ, 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'ROS_DOMAIN_ID': '230'}
    env.pop('ROS_LOCALHOST_ONLY', None)
    done = subprocess.run(
        [sys.executable, '-c', STUCK_STOP], env=env, capture_output=True, text=True, timeout=30
    )
    assert done.returncode == 1, done.stderr
    assert 'Timeout (0:00:01)!' in done.stderr, done.stderr
    assert 'in <lambda>' in done.stderr and 'in _finish' in done.stderr, done.stderr


@pytest.fixture
def ros_context(monkeypatch):
    """A private rclpy context on this machine only (nothing else hears its nodes)."""
    import rclpy

    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    monkeypatch.delenv('ROS_LOCALHOST_ONLY', raising=False)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=232)
    nodes = []

    def node(name, **kwargs):
        nodes.append(rclpy.create_node(name, context=context, **kwargs))
        return nodes[-1]

    yield node
    for made in nodes:
        made.destroy_node()
    context.try_shutdown()


def test_a_service_of_this_process_is_called_directly_under_its_resolved_name(ros_context):
    from std_srvs.srv import SetBool
    from stealth_node_kit.in_process import InProcessClient, InProcessServices

    services = InProcessServices()
    calls = []

    def switch(request, response):
        calls.append(request.data)
        response.success, response.message = True, f'set to {request.data}'
        return response

    server = ros_context('server', namespace='/robot')
    services.serve(server, SetBool, 'sim/switch', switch)
    assert services.names() == ['/robot/sim/switch']
    caller = ros_context('caller', namespace='/robot')
    client = services.client(caller, SetBool, 'sim/switch')
    assert isinstance(client, InProcessClient) and client.service_is_ready()
    future = client.call_async(SetBool.Request(data=True))
    assert future.done() and future.result().message == 'set to True' and calls == [True]
    answers = []
    future.add_done_callback(lambda done: answers.append(done.result().success))
    assert answers == [True]  # at once: no executor is needed for the answer
    client.remove_pending_request(future)  # nothing pending: a no-op, as for a stale request
    # Still a ROS service for everyone else.
    names = dict(server.get_service_names_and_types_by_node('server', '/robot'))
    assert names['/robot/sim/switch'] == ['std_srvs/srv/SetBool']


@pytest.mark.parametrize(
    'namespace, name, remap',
    [
        ('/', 'sim/switch', None),  # another namespace resolves to another service
        ('/robot', 'sim/other', None),  # another name
        ('/robot', 'sim/switch', 'sim/switch:=/elsewhere/switch'),  # remapped elsewhere
    ],
)
def test_any_other_service_gets_a_ros_client(ros_context, namespace, name, remap):
    from rclpy.client import Client
    from std_srvs.srv import SetBool
    from stealth_node_kit.in_process import InProcessServices

    services = InProcessServices()
    server = ros_context('server', namespace='/robot')
    services.serve(server, SetBool, 'sim/switch', lambda request, response: response)
    args = ['--ros-args', '-r', remap] if remap else None
    caller = ros_context('caller', namespace=namespace, cli_args=args)
    assert isinstance(services.client(caller, SetBool, name), Client)


def test_a_service_of_another_type_under_the_name_gets_a_ros_client(ros_context):
    import rclpy
    from rclpy.client import Client
    from std_srvs.srv import SetBool, Trigger
    from stealth_node_kit.in_process import InProcessServices

    services = InProcessServices()
    services.serve(ros_context('server'), Trigger, 'sim/switch', lambda request, answer: answer)
    # Fast DDS refuses two types on one service in one participant: the caller has its own.
    other = rclpy.Context()
    rclpy.init(context=other, domain_id=230)
    caller = rclpy.create_node('caller', context=other)
    try:
        assert isinstance(services.client(caller, SetBool, 'sim/switch'), Client)
    finally:
        caller.destroy_node()
        other.try_shutdown()


def test_kept_qos_keeps_the_last_messages_for_late_readers():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
    from stealth_node_kit.qos import kept_qos

    qos = kept_qos(7)
    assert (qos.history, qos.depth) == (HistoryPolicy.KEEP_LAST, 7)
    assert qos.reliability == ReliabilityPolicy.RELIABLE
    assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL


def _spin_until(context, node, done, timeout=10.0):
    import time

    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + timeout
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    executor.remove_node(node)


def test_an_on_demand_subscription_waits_for_drain_and_then_gets_every_message(ros_context):
    """The executor never runs its callback; drain() runs it once per message, oldest first,
    while an ordinary subscription of the same node keeps waking the executor."""
    import os

    from std_msgs.msg import Int64
    from stealth_node_kit.on_demand import OnDemand

    topic = f'on_demand_{os.getpid()}'
    node = ros_context('kit_on_demand')
    group = OnDemand()
    drained, woken = [], []
    node.create_subscription(Int64, topic, lambda m: drained.append(m.data), 10,
                             callback_group=group)  # fmt: skip
    node.create_subscription(Int64, topic + '_woken', lambda m: woken.append(m.data), 10)
    publisher = node.create_publisher(Int64, topic, 10)
    woken_publisher = node.create_publisher(Int64, topic + '_woken', 10)
    context = node.context
    _spin_until(context, node, lambda: publisher.get_subscription_count() == 1)
    for value in (1, 2, 3):
        publisher.publish(Int64(data=value))
    woken_publisher.publish(Int64(data=7))
    _spin_until(context, node, lambda: woken == [7])
    assert woken == [7]
    assert drained == []  # the executor spun, and never took it
    assert group.drain() == 3
    assert drained == [1, 2, 3]
    assert group.drain() == 0  # nothing is taken twice


def test_the_clock_on_demand_moves_the_node_clock_only_when_drained(ros_context):
    """Under use_sim_time the node's clock follows /clock once drained; without it there is no
    /clock subscription to move."""
    import os

    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock
    from stealth_node_kit.conversions import time_msg
    from stealth_node_kit.on_demand import OnDemand, clock_on_demand

    namespace = f'/on_demand_{os.getpid()}'
    assert not clock_on_demand(ros_context('kit_wall_clock', namespace=namespace), OnDemand())
    node = ros_context(
        'kit_sim_clock',
        namespace=namespace,
        parameter_overrides=[Parameter('use_sim_time', value=True)],
        cli_args=['--ros-args', '-r', f'/clock:={namespace}/clock'],
    )
    group = OnDemand()
    assert clock_on_demand(node, group)
    publisher = node.create_publisher(Clock, f'{namespace}/clock', 10)
    _spin_until(node.context, node, lambda: publisher.get_subscription_count() == 1)
    publisher.publish(Clock(clock=time_msg(42.5)))
    waits = []  # each wait set the executor builds asks the group once per entity
    group.can_execute = lambda entity: waits.append(entity) and False
    _spin_until(node.context, node, lambda: False, timeout=0.5)
    assert node.get_clock().now().nanoseconds == 0  # the executor did not take it
    # ...and did not busy-wait on it: a pending message raised its events (Fast DDS)
    assert len(waits) < 200
    assert group.drain() == 1
    assert node.get_clock().now().nanoseconds == 42_500_000_000


def test_qos_events_on_demand_are_not_waited_on_and_poll_runs_each_change_once(ros_context):
    """A publisher whose reader asks for more than it offers: its incompatible-QoS warning runs
    when polled, once per change, never from the executor."""
    import os

    from rclpy.event_handler import PublisherEventCallbacks
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Int64
    from stealth_node_kit.on_demand import OnDemand, events_on_demand

    topic = f'qos_events_{os.getpid()}'
    node = ros_context('kit_qos_events')
    warned = []
    callbacks = PublisherEventCallbacks(incompatible_qos=warned.append)
    best_effort = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    node.create_publisher(Int64, topic, best_effort, event_callbacks=callbacks)
    group = events_on_demand(node, OnDemand())
    handlers = [h for p in node.publishers for h in p.event_handlers]
    assert handlers and all(h.callback_group is group for h in handlers)
    reliable = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(Int64, topic, lambda m: None, reliable)
    ran = []
    _spin_until(node.context, node, lambda: ran.append(group.poll_events()) or warned)
    assert len(warned) == 1 and sum(ran) == 1  # the executor spun too, and never ran it
    assert warned[0].total_count_change == 1
    assert group.poll_events() == 0  # the same status is not reported twice
