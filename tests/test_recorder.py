"""The MCAP recorder and player for real: nodes in separate processes over DDS.

A traffic node publishes several types (std_msgs, nav_msgs, stealth_interfaces, one of them
latched); the recorder records it and is stopped with SIGINT, SIGTERM or SIGKILL; every message
is read back through mcap_ros2's decoder, which builds its CDR parser from nothing but the
stored definition text, so a wrong schema fails here.
"""

import os
import signal
import subprocess
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from ros_support import REPO_ROOT, remove_orphaned_shm, shm_segments, wait_for_output
from stealth_tools.bag_format import BagError, BagWriter
from stealth_tools.bag_reading import open_indexed_reader
from stealth_tools.interfaces import definition_text
from stealth_tools.qos_text import QosDescription, parse_offered_qos_yaml
import yaml

BIN = REPO_ROOT / 'ros2_ws' / 'install' / 'stealth_tools' / 'lib' / 'stealth_tools'
RECORDER = str(BIN / 'recorder')
STEALTH = str(BIN / 'stealth')
COUNT = 40
RATE = 40.0  # Hz
SIM_START = 1000  # s of sim time when the traffic node publishes /clock
OUR_TOPICS = ('/chatter', '/odom', '/rl_env/step_info', '/rl_env/rl_env_description')

# argv: message count (0: endless), rate in Hz, 'sim' to drive /clock or 'wall'.
TRAFFIC = f"""
import sys, time
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String
from stealth_interfaces.msg import RLEnvDescription, StepInfo

count, rate, sim = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3] == 'sim'
rclpy.init()
node = rclpy.create_node('traffic')
deep = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
latched = node.create_publisher(
    RLEnvDescription, 'rl_env/rl_env_description',
    QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
               durability=DurabilityPolicy.TRANSIENT_LOCAL))
latched.publish(RLEnvDescription(num_actions=4.0, title='traffic'))
chatter = node.create_publisher(String, 'chatter', deep)
odom = node.create_publisher(Odometry, 'odom', deep)
steps = node.create_publisher(StepInfo, 'rl_env/step_info', deep)
clock = node.create_publisher(Clock, '/clock', 10)

def tick(seconds):
    message = Clock()
    message.clock.sec, message.clock.nanosec = divmod(round(seconds * 1e9), 10**9)
    clock.publish(message)

try:
    while any(p.get_subscription_count() == 0 for p in (chatter, odom, steps)):
        if sim:
            tick({SIM_START})
        time.sleep(0.05)
    print('matched', flush=True)
    i = 0
    while count == 0 or i < count:
        if sim:
            tick({SIM_START} + i / rate)
        chatter.publish(String(data=f'message {{i}}'))
        message = Odometry()
        message.pose.pose.position.x = float(i)
        odom.publish(message)
        steps.publish(StepInfo(step=i, state=[float(i), 0.5]))
        i += 1
        time.sleep(1 / rate)
    print('done', flush=True)
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    node.destroy_node()
    rclpy.try_shutdown()
"""


def recover(node_processes, damaged, into) -> subprocess.CompletedProcess:
    """`stealth bag recover DAMAGED -o INTO` in the nodes' environment, which must succeed."""
    result = subprocess.run(
        [STEALTH, 'bag', 'recover', str(damaged), '-o', str(into)],
        env=node_processes.env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    return result


def read_back(path):
    """(summary, {topic: [(message record, decoded)]}, channels by topic, rosbag2 metadata)."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        by_topic = {}
        for _, channel, message, decoded in reader.iter_decoded_messages():
            by_topic.setdefault(channel.topic, []).append((message, decoded))
        metadata = [
            yaml.safe_load(record.metadata['serialized_metadata'])
            for record in reader.iter_metadata()
            if record.name == 'rosbag2'
        ]
    channels = {c.topic: c for c in summary.channels.values()}
    return summary, by_topic, channels, metadata


@pytest.mark.parametrize(
    ('stop_signal', 'clock', 'batch_period'),
    [(signal.SIGINT, 'wall', 0.3), (signal.SIGINT, 'wall', 0.0), (signal.SIGTERM, 'sim', None)],
)
def test_recording_stopped_by_a_signal_is_complete(
    node_processes, tmp_path, stop_signal, clock, batch_period
):
    started_ns = time.time_ns()
    traffic = node_processes.start_python(TRAFFIC, 'traffic', str(COUNT), str(RATE), clock)
    output = tmp_path / 'run.mcap'
    sim_args = ['-p', 'use_sim_time:=true'] if clock == 'sim' else []
    if batch_period is not None:  # None: the default
        sim_args += ['-p', f'batch_period:={batch_period}']
    recorder = node_processes.start(
        [RECORDER, '--ros-args', '-p', f'output:={output}', *sim_args], 'recorder'
    )
    wait_for_output(traffic, 'done')
    time.sleep(0.5)  # the last messages are on their way
    os.killpg(recorder.pid, stop_signal)
    assert recorder.wait(20) == 0, recorder.log_path.read_text()
    stopped_ns = time.time_ns()

    summary, by_topic, channels, metadata = read_back(output)
    assert summary.chunk_indexes and all(c.message_index_offsets for c in summary.chunk_indexes)
    for topic in OUR_TOPICS:
        schema = summary.schemas[channels[topic].schema_id]
        assert schema.encoding == 'ros2msg' and channels[topic].message_encoding == 'cdr'
        assert schema.data.decode() == definition_text(schema.name)
        assert channels[topic].metadata['topic_type_hash'].startswith('RIHS01_')
    # Reliable topics: every message, in order, intact.
    assert [m.data for _, m in by_topic['/chatter']] == [f'message {i}' for i in range(COUNT)]
    assert [m.pose.pose.position.x for _, m in by_topic['/odom']] == list(map(float, range(COUNT)))
    assert [m.step for _, m in by_topic['/rl_env/step_info']] == list(range(COUNT))
    assert list(by_topic['/rl_env/step_info'][-1][1].state) == [COUNT - 1, 0.5]
    # The latched description was published before the recorder existed.
    ((_, description),) = by_topic['/rl_env/rl_env_description']
    assert description.title == 'traffic'
    (offer,) = parse_offered_qos_yaml(
        channels['/rl_env/rl_env_description'].metadata['offered_qos_profiles']
    )
    assert (offer.reliability, offer.durability) == ('reliable', 'transient_local')
    (offer,) = parse_offered_qos_yaml(channels['/chatter'].metadata['offered_qos_profiles'])
    assert (offer.reliability, offer.durability) == ('reliable', 'volatile')
    # Log times: the recorder's ROS clock in ns, wall or sim.
    log_times = [m.log_time for topic in OUR_TOPICS for m, _ in by_topic[topic]]
    if clock == 'wall':
        assert started_ns <= min(log_times) and max(log_times) <= stopped_ns
        assert all(m.publish_time <= m.log_time for m, _ in by_topic['/chatter'])
        # Each message's reception time, also when taken in batches of ~12 per topic: a log
        # time taken at the batch would put most of a topic's gaps near 0, not near 1/RATE.
        for topic in ('/chatter', '/odom', '/rl_env/step_info'):
            gaps = np.diff([m.log_time for m, _ in by_topic[topic]]) / 1e9
            assert (gaps > 0).all() and np.median(gaps) > 0.5 / RATE, (topic, gaps)
    else:
        assert min(log_times) >= SIM_START * 10**9
        assert max(log_times) <= (SIM_START + COUNT / RATE + 1) * 10**9
    # rosbag2's metadata record, final version last.
    assert metadata[-1]['message_count'] == summary.statistics.message_count
    assert metadata[-1]['version'] == 9


def test_sigkill_loses_at_most_a_second_and_recover_restores_an_indexed_file(
    node_processes, tmp_path
):
    segments_before = shm_segments()
    traffic = node_processes.start_python(TRAFFIC, 'traffic', '0', '100', 'wall')
    output = tmp_path / 'killed.mcap'
    recorder = node_processes.start(
        [RECORDER, '--ros-args', '-p', f'output:={output}'], 'recorder'
    )
    wait_for_output(traffic, 'matched')
    time.sleep(2.5)
    killed_ns = time.time_ns()
    os.killpg(recorder.pid, signal.SIGKILL)
    recorder.wait(10)
    node_processes.stop_all()
    remove_orphaned_shm(segments_before)

    with open(output, 'rb') as stream, pytest.raises(BagError, match='not a complete MCAP'):
        open_indexed_reader(stream)
    recovered = tmp_path / 'recovered.mcap'
    assert 'cut off' in recover(node_processes, output, recovered).stdout

    summary, by_topic, _, _ = read_back(recovered)
    assert summary.chunk_indexes and all(c.message_index_offsets for c in summary.chunk_indexes)
    numbers = [int(m.data.split()[1]) for _, m in by_topic['/chatter']]
    assert numbers == list(range(numbers[0], numbers[0] + len(numbers)))  # no gap
    lost_ns = killed_ns - max(m.log_time for m, _ in by_topic['/chatter'])
    print(f'SIGKILL lost the last {lost_ns / 1e6:.0f} ms ({len(numbers)} chatter messages kept)')
    assert lost_ns < 1e9


STUCK_CLOSE = """
import sys, time
from stealth_tools import recorder
recorder.STOP_LIMIT = 1.0
recorder.Recorder.close = lambda self: time.sleep(60)
sys.exit(recorder.main(sys.argv[1:]))
"""


def test_a_stop_stuck_in_closing_dumps_its_stacks_and_exits_1(node_processes, tmp_path):
    """An orphaned recorder (its orchestrator SIGKILLed) has no one to kill it: a stop that
    hangs says where, and ends (the file is then recovered as after a SIGKILL)."""
    recorder = node_processes.start_python(
        STUCK_CLOSE, 'recorder', '--ros-args', '-p', f'output:={tmp_path / "stuck.mcap"}'
    )
    wait_for_output(recorder, 'Recording to')
    os.killpg(recorder.pid, signal.SIGTERM)
    assert recorder.wait(20) == 1
    log = recorder.log_path.read_text()
    assert 'Timeout (0:00:01)!' in log and 'in <lambda>' in log and 'in _record' in log, log


def test_a_burst_beyond_one_batch_is_all_written_without_more_traffic(node_processes, tmp_path):
    """DDS wakes a subscription for new data, not for data left over: what a burst leaves
    queued beyond one batch's take must still reach the file, with nothing more arriving and
    before any stop (a SIGKILL, then recover, shows what was written)."""
    burst = 3000
    segments_before = shm_segments()
    traffic = node_processes.start_python(TRAFFIC, 'traffic', str(burst), '1e9', 'wall')
    output = tmp_path / 'burst.mcap'
    recorder = node_processes.start(
        [RECORDER, '--ros-args', '-p', f'output:={output}', '-p', 'batch_period:=0.2'],
        'recorder',
    )
    wait_for_output(traffic, 'done')
    time.sleep(3.0)  # a few batch periods and chunk closings, and no new message
    os.killpg(recorder.pid, signal.SIGKILL)
    recorder.wait(10)
    recovered = tmp_path / 'recovered.mcap'
    recover(node_processes, output, recovered)
    node_processes.stop_all()
    remove_orphaned_shm(segments_before)
    _, by_topic, _, _ = read_back(recovered)
    for topic in ('/chatter', '/odom', '/rl_env/step_info'):
        assert len(by_topic[topic]) == burst, topic


def test_a_batch_period_out_of_range_is_one_line_naming_it(node_processes, tmp_path):
    output = tmp_path / 'never.mcap'
    result = subprocess.run(
        [RECORDER, '--ros-args', '-p', f'output:={output}', '-p', 'batch_period:=-0.5'],
        env=node_processes.env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith('recorder: parameter batch_period: ') and 'out of range' in line
    assert 'Min: 0.0, Max: 1.0' in line
    assert not output.exists()


def _replay_bag(path):
    """10 chatter messages 0.2 s apart, 5 on another topic, a latched description first."""
    from std_msgs.msg import String
    from stealth_interfaces.msg import RLEnvDescription

    start = 1_700_000_000 * 10**9
    writer = BagWriter(path)
    latched = QosDescription(history='unknown', depth=0, durability='transient_local')
    for topic, type_name, offer in (
        ('/replay/latched', 'stealth_interfaces/msg/RLEnvDescription', latched),
        ('/replay/chatter', 'std_msgs/msg/String', QosDescription(history='unknown', depth=0)),
        ('/replay/other', 'std_msgs/msg/String', QosDescription(history='unknown', depth=0)),
    ):
        writer.add_topic(topic, type_name, definition_text(type_name), [offer])
    writer.write('/replay/latched', serialize_message(RLEnvDescription(title='x')), start, start)
    for i in range(10):
        stamp = start + 100_000_000 + i * 200_000_000
        writer.write('/replay/chatter', serialize_message(String(data=str(i))), stamp, stamp)
        if i % 2:
            writer.write('/replay/other', serialize_message(String(data='no')), stamp, stamp)
    writer.close()
    return start


def test_play_back_keeps_timing_qos_and_the_topic_filter(node_processes, ros_context, tmp_path):
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String
    from stealth_interfaces.msg import RLEnvDescription

    bag = tmp_path / 'replay.mcap'
    start = _replay_bag(bag)
    node = rclpy.create_node('replay_listener', context=ros_context)
    chatter, other, latched, clock = [], [], [], []
    reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(
        String, '/replay/chatter', lambda m: chatter.append((time.monotonic(), m.data)), reliable
    )
    node.create_subscription(String, '/replay/other', other.append, reliable)
    node.create_subscription(
        RLEnvDescription,
        '/replay/latched',
        latched.append,
        QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL),
    )
    node.create_subscription(
        Clock,
        '/clock',
        lambda m: clock.append(m.clock.sec * 10**9 + m.clock.nanosec),
        QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT),
    )
    player = node_processes.start(
        [STEALTH, 'bag', 'play', str(bag), '--rate', '2', '--clock', '20', '-d', '3',
         '--topics', '/replay/chatter', '/replay/latched'],
        'player',
    )  # fmt: skip
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    deadline = time.monotonic() + 30
    while len(chatter) < 10 and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    assert player.wait(20) == 0, player.log_path.read_text()
    executor.spin_once(timeout_sec=0.2)
    executor.shutdown()
    node.destroy_node()

    assert [data for _, data in chatter] == [str(i) for i in range(10)]
    gaps = sorted(b - a for (a, _), (b, _) in zip(chatter, chatter[1:], strict=False))
    assert gaps[len(gaps) // 2] == pytest.approx(0.1, abs=0.02)  # 0.2 s recorded, rate 2
    assert chatter[-1][0] - chatter[0][0] == pytest.approx(0.9, abs=0.1)
    assert [m.title for m in latched] == ['x'] and other == []
    assert clock and clock == sorted(clock)
    assert start <= clock[0] and clock[-1] <= start + 2_000_000_000
