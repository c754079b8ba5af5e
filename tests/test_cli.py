"""`stealth` against a real graph: the topic verbs, run, bag record/info, and one-line errors."""

import os
import pathlib
import re
import signal
import subprocess
import time

from mcap.reader import make_reader
import pytest
from ros_support import REPO_ROOT, wait_for_output

BIN = REPO_ROOT / 'ros2_ws' / 'install' / 'stealth_tools' / 'lib' / 'stealth_tools'
STEALTH = str(BIN / 'stealth')

# A chatter at 20 Hz (reliable) and a latched description (transient local).
TALKER = """
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from stealth_interfaces.msg import RLEnvDescription

rclpy.init()
node = rclpy.create_node('talker')
latched = node.create_publisher(
    RLEnvDescription, 'rl_env/rl_env_description',
    QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
               durability=DurabilityPolicy.TRANSIENT_LOCAL))
latched.publish(RLEnvDescription(num_actions=4.0, title='lgfloor'))
chatter = node.create_publisher(String, 'chatter', 100)
count = [0]

def talk():
    chatter.publish(String(data=f'hello {count[0]}'))
    count[0] += 1

node.create_timer(0.05, talk)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    node.destroy_node()
    rclpy.try_shutdown()
"""


def stealth(processes, *args, timeout=60):
    """Run `stealth args...` in the test's private domain; the completed process."""
    return subprocess.run(
        [STEALTH, *args], env=processes.env, capture_output=True, text=True, timeout=timeout
    )


def one_error_line(result, starts_with: str) -> str:
    """The single stderr line of a failed command (no traceback), checked."""
    assert result.returncode == 1, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert lines[-1].startswith(starts_with), result.stderr
    assert 'Traceback' not in result.stderr
    return lines[-1]


def test_topic_verbs_on_a_running_talker(node_processes):
    node_processes.start_python(TALKER, 'talker')

    echo = stealth(node_processes, 'topic', 'echo', '/chatter', '--once', '--spin-time', '20')
    assert echo.returncode == 0, echo.stderr
    assert re.fullmatch(r'data: hello \d+\n---\n', echo.stdout)
    # Transient local: the description was published long before this subscriber existed.
    echo = stealth(node_processes, 'topic', 'echo', 'rl_env/rl_env_description', '--once')
    assert echo.returncode == 0, echo.stderr
    assert 'num_actions: 4.0\n' in echo.stdout and 'title: lgfloor\n' in echo.stdout

    listing = stealth(node_processes, 'topic', 'list', '-t', '--spin-time', '10')
    assert '/chatter [std_msgs/msg/String]\n' in listing.stdout
    assert '/rl_env/rl_env_description [stealth_interfaces/msg/RLEnvDescription]\n' in (
        listing.stdout
    )

    info = stealth(node_processes, 'topic', 'info', '/chatter', '-v')
    assert info.returncode == 0, info.stderr
    assert info.stdout.startswith('Type: std_msgs/msg/String\n\nPublisher count: 1\n\n')
    assert 'Node name: talker\n' in info.stdout and '  Reliability: RELIABLE\n' in info.stdout

    hz = node_processes.start([STEALTH, 'topic', 'hz', '/chatter', '--window', '20'], 'hz')
    output = wait_for_output(hz, 'window: 20')
    os.killpg(hz.pid, signal.SIGINT)
    assert hz.wait(10) == 0
    rates = [float(r) for r in re.findall(r'average rate: ([\d.]+)', output)]
    assert rates[-1] == pytest.approx(20.0, rel=0.15)

    # --timeout bounds the command while messages keep arriving (it was N s without one), and
    # it closes with the rate of what came since its last line (discovery may take most of it).
    started = time.monotonic()
    hz = stealth(node_processes, 'topic', 'hz', '/chatter', '--timeout', '3', timeout=30)
    assert hz.returncode == 0 and time.monotonic() - started >= 3.0, hz.stderr
    rates = [float(r) for r in re.findall(r'average rate: ([\d.]+)', hz.stdout)]
    assert rates and rates[-1] == pytest.approx(20.0, rel=0.15)


def test_bag_record_writes_a_rosbag2_directory_that_bag_info_reads(node_processes, tmp_path):
    node_processes.start_python(TALKER, 'talker')
    bag = tmp_path / 'run1'
    record = node_processes.start([STEALTH, 'bag', 'record', '/chatter', '-o', str(bag)], 'record')
    wait_for_output(record, "Subscribed to topic '/chatter'")
    time.sleep(1.0)
    os.killpg(record.pid, signal.SIGTERM)
    assert record.wait(20) == 0, record.log_path.read_text()
    assert sorted(p.name for p in bag.iterdir()) == ['metadata.yaml', 'run1_0.mcap']

    info = stealth(node_processes, 'bag', 'info', str(bag))
    assert info.returncode == 0, info.stderr
    count = int(re.search(r'Messages:\s+(\d+)', info.stdout).group(1))
    assert count >= 10
    assert (
        f'Topic: /chatter | Type: std_msgs/msg/String | Count: {count} | '
        'Serialization Format: cdr' in info.stdout
    )
    assert 'Storage id:        mcap\n' in info.stdout


def test_run_passes_sigterm_on_and_leaves_nothing_running(node_processes, tmp_path):
    output = tmp_path / 'quiet.mcap'
    run = node_processes.start(
        [STEALTH, 'run', 'stealth_tools', 'recorder', '--ros-args', '-p', f'output:={output}'],
        'run',
    )
    wait_for_output(run, 'Recording to')
    os.kill(run.pid, signal.SIGTERM)  # to `stealth` only: it must pass it on
    assert run.wait(20) == 0, run.log_path.read_text()
    with open(output, 'rb') as stream:
        assert make_reader(stream).get_summary() is not None  # closed properly
    assert not [
        cmdline
        for cmdline in pathlib.Path('/proc').glob('[0-9]*/cmdline')
        if str(output) in _read(cmdline)
    ]


def _read(path: pathlib.Path) -> str:
    try:
        return path.read_bytes().decode(errors='replace')
    except OSError:
        return ''


def test_run_errors_are_one_line(node_processes, tmp_path):
    line = one_error_line(stealth(node_processes, 'run', 'no_such_pkg', 'node'), 'stealth run: ')
    assert "package 'no_such_pkg' not found" in line and 'stealth_tools' in line
    line = one_error_line(
        stealth(node_processes, 'run', 'stealth_tools', 'no_such_node'), 'stealth run: '
    )
    assert line.endswith("has no executable 'no_such_node' (it has: bridge, recorder, stealth)")
    # A node that fails on start: its reason, then which executable and how it ended.
    crash = stealth(
        node_processes,
        'run',
        'stealth_tools',
        'recorder',
        '--ros-args',
        '-p',
        f'output:={tmp_path}/missing_dir/x.mcap',
    )
    line = one_error_line(crash, 'stealth run: stealth_tools recorder exited with code 1 after')
    assert line.endswith('No such file or directory')


def test_bag_and_topic_errors_are_one_line(node_processes, tmp_path):
    one_error_line(
        stealth(node_processes, 'bag', 'play', str(tmp_path / 'nope.mcap')),
        f'stealth bag play: {tmp_path}/nope.mcap: no such file or directory',
    )
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(b'\x89MCAP0\r\n' + b'\x01' * 20)
    for verb in ('play', 'info', 'recover'):  # one answer: no recover to suggest, none to make
        one_error_line(
            stealth(node_processes, 'bag', verb, str(cut)),
            f'stealth bag {verb}: {cut}: an MCAP file that ends before its header is complete (28 '
            'bytes): it holds no messages; nothing to play or recover',
        )
    one_error_line(stealth(node_processes, 'bag', 'record'), 'stealth bag record: name the topics')
    one_error_line(
        stealth(node_processes, 'topic', 'info', '/nope', '--spin-time', '0.3'),
        "stealth topic info: Unknown topic '/nope'",
    )
    one_error_line(
        stealth(node_processes, 'topic', 'echo', '/nope', '--spin-time', '0.3'),
        "stealth topic echo: could not determine the type of '/nope'",
    )
    one_error_line(
        stealth(node_processes, 'train', '--scenario', 'nope'), "stealth train: scenario 'nope'"
    )
    for verb in ('echo', 'hz', 'info'):
        one_error_line(
            stealth(node_processes, 'topic', verb, 'bad topic!!'),
            f"stealth topic {verb}: invalid topic name 'bad topic!!': topic name must not",
        )
    string = 'std_msgs/msg/String'
    one_error_line(
        stealth(node_processes, 'topic', 'echo', '/silent', string, '--timeout', '1'),
        'stealth topic echo: no message on /silent within 1 s',
    )
    one_error_line(
        stealth(node_processes, 'topic', 'hz', '/silent', '--spin-time', '0.3', '--timeout', '1'),
        'stealth topic hz: nothing published /silent within 1 s',
    )
