"""The service robot's calls: answers, failures, deadlines and cancels, without a ROS graph (the
simulator's handlers are called in-process, as under stealth_bringup.sim_env)."""

import math
import time

from geometry_msgs.msg import Pose as PoseMsg
import pytest
from rclpy.task import Future
from stealth_env.service_robot import MOVE_SERVICE, ServiceCalls, ServiceRobot, Teleport
from stealth_env.topic_moves import Pose, go_to, hold_goal
from stealth_interfaces.srv import ExecuteMove, ResetRobot
from stealth_node_kit.conversions import time_msg, yaw_quaternion
from stealth_node_kit.in_process import InProcessServices


class Graph:
    """The part of a node the service robot uses: names and servers, no middleware."""

    def __init__(self):
        self.servers = {}

    def resolve_service_name(self, name):
        return name if name.startswith('/') else f'/{name}'

    def create_service(self, srv_type, name, handler):
        service = type('Service', (), {'service_name': self.resolve_service_name(name)})()
        self.servers[service.service_name] = handler
        return service


class Silent:
    """A client of a simulator that never answers."""

    def __init__(self):
        self.removed = []

    def call_async(self, request):
        return Future()

    def service_is_ready(self):
        return True

    def remove_pending_request(self, future):
        self.removed.append(future)


def answers():
    """on_answer and on_timeout that note what they get."""
    got = []
    return got, (lambda response, problem: got.append((response, problem))), got.append


def test_an_answer_comes_through_and_ends_the_wait():
    calls = ServiceCalls(lambda: 60.0)
    got, on_answer, on_timeout = answers()
    future = Future()
    future.set_result('response')
    client = Silent()
    client.call_async = lambda request: future
    calls.send(client, 'request', 'sim/x', on_answer, on_timeout, timeout=0.0)
    assert got == [('response', '')]
    calls.tick()  # answered: no deadline left to pass
    assert got == [('response', '')] and client.removed == []


def test_a_request_without_an_answer_is_given_up_at_its_deadline():
    calls = ServiceCalls(lambda: 60.0)
    got, on_answer, on_timeout = answers()
    client = Silent()
    calls.send(client, 'request', 'sim/reset', on_answer, on_timeout, timeout=0.01)
    calls.tick()
    assert got == []  # not yet
    time.sleep(0.02)
    calls.tick()
    assert got == ['no answer from sim/reset within 0.01 s (is the simulator running?)']
    assert len(client.removed) == 1
    # At move_timeout or beyond, the deadline is move_timeout and says so.
    calls = ServiceCalls(lambda: 0.01)
    got, on_answer, on_timeout = answers()
    calls.send(client, 'request', MOVE_SERVICE, on_answer, on_timeout)
    time.sleep(0.02)
    calls.tick()
    assert got == [f'no answer from {MOVE_SERVICE} within move_timeout 0.01 s (is the '
                   'simulator running?)']  # fmt: skip


def test_a_cancelled_request_is_removed_and_never_times_out():
    calls = ServiceCalls(lambda: 0.01)
    got, on_answer, on_timeout = answers()
    client = Silent()
    calls.send(client, 'request', 'sim/reset', on_answer, on_timeout)
    calls.cancel()
    time.sleep(0.02)
    calls.tick()
    assert got == [] and len(client.removed) == 1


def test_a_failed_call_says_why():
    calls = ServiceCalls(lambda: 60.0)
    got, on_answer, on_timeout = answers()
    future = Future()
    future.set_exception(RuntimeError('gone'))
    client = Silent()
    client.call_async = lambda request: future
    calls.send(client, 'request', 'sim/x', on_answer, on_timeout)
    assert got == [(None, "the call failed: RuntimeError('gone')")]


def in_process_robot(on_move, on_reset):
    graph, services = Graph(), InProcessServices()
    services.serve(graph, ExecuteMove, MOVE_SERVICE, on_move)
    services.serve(graph, ResetRobot, 'sim/reset', on_reset)
    teleport = Teleport(graph, services, 'sim/reset', lambda: 60.0)
    return ServiceRobot(graph, services, teleport, lambda: 60.0)


def pose_msg(x, y, yaw):
    message = PoseMsg()
    message.position.x, message.position.y = x, y
    message.orientation = yaw_quaternion(yaw)
    return message


def test_moves_and_resets_of_the_simulator_in_this_process():
    requests = []

    def on_move(request, response):
        requests.append(request)
        if request.kind == ExecuteMove.Request.HOLD:
            response.outcome, response.message = ExecuteMove.Response.REJECTED, 'no holds'
            return response
        response.outcome, response.message = ExecuteMove.Response.BUMPED, 'a wall'
        response.estimate.pose = pose_msg(1.0, 2.0, 0.5)
        response.true_pose = pose_msg(1.1, 2.1, 0.4)
        response.stamp = time_msg(12.5)
        return response

    def on_reset(request, response):
        response.success = request.x >= 0
        response.message = '' if response.success else 'outside the map'
        return response

    robot = in_process_robot(on_move, on_reset)
    assert robot.ready() and robot.not_responding() == ''
    assert robot.describe() == (
        f'the simulator in this process (called directly: {MOVE_SERVICE}, /sim/reset)'
    )
    ends = []
    robot.run(go_to(1.0, 2.0), ends.append)
    assert (requests[-1].kind, requests[-1].x, requests[-1].y) == (ExecuteMove.Request.GO_TO, 1, 2)
    end = ends[-1]
    assert (end.outcome, end.message, end.t, end.moved) == (1, 'a wall', 12.5, True)
    assert end.estimate == pytest.approx((1.0, 2.0, 0.5))
    assert end.truth == pytest.approx((1.1, 2.1, 0.4))
    robot.run(hold_goal(1.0), ends.append)
    assert ends[-1].outcome is None
    assert ends[-1].message == 'the simulator rejected the move: no holds'
    resets = []
    robot.reset(Pose(1.5, 1.5, 0.0), lambda problem, t: resets.append((problem, t)))
    robot.reset(Pose(-1.0, 1.5, 0.0), lambda problem, t: resets.append((problem, t)))
    assert resets == [('', -math.inf), ('outside the map', -math.inf)]
