"""Watching a run live: `stealth train --watch` starts the Foxglove bridge, and a real Foxglove
WebSocket client (tools/foxglove-ws-check: the protocol spec on `ws`, subprotocol
foxglove.sdk.v1, messages decoded with Foxglove's own @foxglove/rosmsg2-serialization from the
schema the bridge advertised) sees the robot learn; one that connects mid-run still gets the
map; clients sending garbage or vanishing mid-message change nothing. `stealth bridge` on its
own: a port in use is one line, a topic whose type cannot be resolved is skipped by name.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import time

from ros_support import REPO_ROOT, node_tool, reserved_domain_id, ros_environment
from stealth_tools.interfaces import definition_text
from test_system import STEALTH, short_scenario, system, wait_for_text  # noqa: F401 - fixture

CLIENT_DIR = REPO_ROOT / 'tools' / 'foxglove-ws-check'
# topic: (type, messages to wait for)
WATCHED = {
    '/map': ('nav_msgs/msg/OccupancyGrid', 1),
    '/amcl_pose': ('geometry_msgs/msg/PoseWithCovarianceStamped', 3),
    '/searchlight_markers': ('visualization_msgs/msg/MarkerArray', 1),
    '/rl_env/step_info': ('stealth_interfaces/msg/StepInfo', 2),
    '/visibility_grid': ('nav_msgs/msg/OccupancyGrid', 1),
    '/planned_path': ('nav_msgs/msg/Path', 1),
}
LATE = ('/map', '/visibility_grid', '/searchlight_markers')
WALL_CLOCK_NS = 10**18  # log times above this are wall-clock times, below simulated ones


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def wait_for_port(port: int, process, timeout: float = 120.0) -> None:
    """Until something listens on `port` (a server started with its process, which must live);
    a client that connects first is refused and does not try again."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            socket.create_connection(('127.0.0.1', port), timeout=1.0).close()
            return
        except OSError:
            assert process.poll() is None, f'it exited with {process.returncode} before listening'
            assert time.monotonic() < deadline, f'nothing listens on {port} after {timeout:g} s'
            time.sleep(0.2)


def foxglove_client(port: int, topics: dict[str, int], tmp_path, name: str, timeout=240.0):
    """(exit status, report, last decoded message per topic) of a client session."""
    node = node_tool(CLIENT_DIR, 'ws')
    samples = tmp_path / f'{name}-samples.json'
    wanted = ','.join(f'{topic}={count}' for topic, count in topics.items())
    result = subprocess.run(
        [node, str(CLIENT_DIR / 'client.mjs'), f'ws://localhost:{port}', '--topics', wanted,
         '--timeout', str(timeout), '--samples', str(samples)],
        capture_output=True, text=True, timeout=timeout + 30,
    )  # fmt: skip
    assert result.stdout, f'client.mjs printed nothing: {result.stderr}'
    report = json.loads(result.stdout)
    (tmp_path / f'{name}-report.json').write_text(result.stdout)
    return result.returncode, report, json.loads(samples.read_text()) if samples.exists() else {}


def misbehave(port: int) -> None:
    """A client that sends garbage, one that hangs up mid-frame, one that is no WebSocket."""
    handshake = (
        b'GET / HTTP/1.1\r\nHost: localhost\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n'
        b'Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n'
        b'Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n'
    )
    for _ in range(3):
        with socket.create_connection(('127.0.0.1', port)) as garbage:
            garbage.sendall(handshake)
            garbage.recv(4096)
            garbage.sendall(b'\x81\x85\x00\x00\x00\x00hello')  # a text frame that is no JSON
            time.sleep(0.2)
        with socket.create_connection(('127.0.0.1', port)) as cut:
            cut.sendall(handshake)
            cut.recv(4096)
            cut.sendall(b'\x82\xfe\x10\x00\x00\x00\x00\x00' + b'\x01' * 100)  # 4 KiB promised
        with socket.create_connection(('127.0.0.1', port)) as stranger:
            stranger.sendall(b'\x00\xffnot http at all\r\n\r\n')
            time.sleep(0.2)


def test_watch_serves_the_run_to_foxglove_clients(system, tmp_path):  # noqa: F811
    port = free_port()
    train = system.start(
        'train', '--scenario', str(short_scenario(tmp_path)), '--goal', 'easy',
        '--episodes', '1000', '--watch', '--set', f'bridge.port={port}',
        '--runs-dir', str(system.runs),
    )  # fmt: skip
    wait_for_text(train, 'watch live:', timeout=180)
    stderr = train.stderr_path.read_text()
    assert f'ws://localhost:{port}' in stderr, stderr

    status, report, samples = foxglove_client(
        port, {t: n for t, (_, n) in WATCHED.items()}, tmp_path, 'first'
    )
    assert status == 0, report['problems']
    assert report['server']['subprotocol'] == 'foxglove.sdk.v1'
    assert 'time' in report['server']['capabilities']
    for topic, (type_name, count) in WATCHED.items():
        seen = report['topics'][topic]
        channel = seen['channel']
        assert (channel['encoding'], channel['schemaEncoding']) == ('cdr', 'ros2msg'), topic
        assert channel['schemaName'] == type_name
        assert channel['schema'] == definition_text(type_name), topic  # as the recorder writes
        assert seen['count'] >= count and seen['decode_errors'] == 0, (topic, seen)
    # /clock drives the timeline: server time and log times are simulated time
    assert report['times'] > 0 and 0 < int(report['last_time']) < WALL_CLOCK_NS
    step_times = report['topics']['/rl_env/step_info']
    assert 0 < int(step_times['first_log_time']) <= int(step_times['last_log_time'])
    assert int(step_times['last_log_time']) < WALL_CLOCK_NS

    grid, lit = samples['/map'], samples['/visibility_grid']
    assert (lit['info']['width'], lit['info']['height']) == (
        grid['info']['width'], grid['info']['height'],
    )  # fmt: skip
    assert lit['header']['frame_id'] == 'map' and max(lit['data']) == 100 and min(lit['data']) == 0
    pose = samples['/amcl_pose']
    assert pose['header']['frame_id'] == 'map' and len(pose['pose']['covariance']) == 36
    assert {m['ns'] for m in samples['/searchlight_markers']['markers']} >= {'cones', 'lamps'}
    assert samples['/rl_env/step_info']['step'] >= 1
    plan = samples['/planned_path']
    assert plan['header']['frame_id'] == 'map' and len(plan['poses']) > 2
    # What was served renders (the README's picture is made this way).
    picture = tmp_path / 'view.png'
    rendered = subprocess.run(
        [sys.executable, str(REPO_ROOT / 'scripts' / 'render_bridge_view.py'),
         str(tmp_path / 'first-samples.json'), str(picture)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert rendered.returncode == 0, rendered.stderr
    assert picture.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'

    misbehave(port)
    # A client that connects mid-run still gets the latched state: from DDS when it is the
    # only one (the bridge subscribes anew), from the bridge's copy when another one watches.
    status, late, samples = foxglove_client(port, dict.fromkeys(LATE, 1), tmp_path, 'late', 60)
    assert status == 0, late['problems']
    assert samples['/map']['info']['width'] == grid['info']['width']
    watcher = subprocess.Popen(
        [node_tool(CLIENT_DIR, 'ws'), str(CLIENT_DIR / 'client.mjs'), f'ws://localhost:{port}',
         '--topics', '/map=1000000,/rl_env/step_info=1000000', '--timeout', '600'],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        time.sleep(3.0)  # connected, subscribed, the map received
        status, later, samples = foxglove_client(port, {'/map': 1}, tmp_path, 'later', 60)
        assert status == 0, later['problems']
        assert samples['/map']['info']['width'] == grid['info']['width']
    finally:
        watcher.send_signal(signal.SIGTERM)
        watched = json.loads(watcher.communicate(timeout=60)[0])
    assert watched['topics']['/map']['count'] >= 1 and not watched['problems'], watched
    assert watched['topics']['/rl_env/step_info']['decode_errors'] == 0
    assert train.poll() is None, train.stderr_path.read_text()  # the run went on

    train.send_signal(signal.SIGINT)
    assert train.wait(120) == 130, train.stderr_path.read_text()
    (run,) = system.runs.iterdir()
    log = (run / 'logs' / 'bridge.log').read_text()
    assert 'Traceback' not in log and 'Callback failed' not in log, log
    trouble = [line for line in log.splitlines() if 'websocket:' in line and '[WARN]' in line]
    kinds = [line.split('websocket: ', 1)[1] for line in trouble]
    assert trouble and len(kinds) <= 6, trouble  # each kind once, not once per bad client
    assert any('Invalid message' in k for k in kinds), trouble
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['nodes']['bridge']['exit'] and summary['nodes']['bridge']['cpu_s'] > 0

    # The recording, replayed with --bridge (in a domain of its own), is served the same way.
    port = free_port()
    with reserved_domain_id() as domain_id:
        play = subprocess.Popen(
            [STEALTH, 'bag', 'play', str(run / 'recording.mcap'), '--bridge', '--bridge-port',
             str(port), '--delay', '3', '--loop'],
            env=ros_environment(domain_id), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            text=True, start_new_session=True,
        )  # fmt: skip
        system.started.append(play)
        try:
            wait_for_port(port, play)
            status, replayed, samples = foxglove_client(
                port, {'/map': 1, '/rl_env/step_info': 2}, tmp_path, 'replay', 90
            )
            assert status == 0, replayed['problems']
            assert samples['/map']['info']['width'] == grid['info']['width']
        finally:
            play.send_signal(signal.SIGINT)
            _, errors = play.communicate(timeout=60)
    assert play.returncode == 0 and 'Traceback' not in errors, errors


def test_bridge_command_bad_input(node_processes, tmp_path):
    # A port in use: one line naming it and the option.
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = subprocess.run(
            [STEALTH, 'bridge', '--port', str(port)],
            env=node_processes.env, capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    assert result.returncode == 1 and 'Traceback' not in result.stderr, result.stderr
    line = result.stderr.strip().splitlines()[-1]
    assert line.startswith(f'stealth bridge: port {port} is in use'), result.stderr
    assert line.endswith('--port N')

    # A type the bridge cannot resolve (its package not installed where it runs): skipped with
    # a warning naming the topic; the topics it can resolve are relayed.
    publisher = node_processes.start_python(
        'import rclpy, time\n'
        'from std_msgs.msg import String\n'
        'from stealth_interfaces.msg import RLAction\n'
        'rclpy.init()\n'
        "node = rclpy.create_node('publisher')\n"
        "actions = node.create_publisher(RLAction, 'unresolvable', 10)\n"
        "words = node.create_publisher(String, 'words', 10)\n"
        'while rclpy.ok():\n'
        '    actions.publish(RLAction(action=1)); words.publish(String(data="hi"))\n'
        '    rclpy.spin_once(node, timeout_sec=0.1)\n',
        'publisher',
    )
    prefixes = node_processes.env['AMENT_PREFIX_PATH'].split(os.pathsep)
    without = os.pathsep.join(p for p in prefixes if not p.endswith('stealth_interfaces'))
    port = free_port()
    bridge = node_processes.start(
        [STEALTH, 'bridge', '--port', str(port)],
        'bridge',
        extra_env={'AMENT_PREFIX_PATH': without},
    )
    deadline = time.monotonic() + 60
    while (
        time.monotonic() < deadline and "Advertising '/words'" not in bridge.log_path.read_text()
    ):
        assert bridge.poll() is None and publisher.poll() is None, bridge.log_path.read_text()
        time.sleep(0.2)
    time.sleep(1.0)
    log = bridge.log_path.read_text()
    assert "Advertising '/words' (std_msgs/msg/String" in log, log
    skipped = [line for line in log.splitlines() if "'/unresolvable'" in line]
    assert len(skipped) == 1 and "Not relaying '/unresolvable'" in skipped[0], log
    assert "package 'stealth_interfaces' not found" in skipped[0], log
    assert bridge.poll() is None


def test_the_foxglove_layout_is_whole_and_shows_the_topics_of_a_run():
    from test_system import TOPICS

    layout = json.loads((REPO_ROOT / 'docs' / 'foxglove' / 'stealth-nav.json').read_text())
    assert set(layout) >= {'configById', 'layout', 'globalVariables', 'userNodes'}

    def panels(node):
        if isinstance(node, str):
            return [node]
        assert node['direction'] in ('row', 'column') and 0 < node['splitPercentage'] < 100
        return panels(node['first']) + panels(node['second'])

    shown = panels(layout['layout'])
    assert sorted(shown) == sorted(layout['configById'])
    assert {name.split('!')[0] for name in shown} == {'3D', 'Plot', 'RosOut'}
    light_model = {'/agent/light_belief', '/agent/light_belief_uncertain'}  # its runs' belief
    run_topics = set(TOPICS) | {'/visibility_grid', '/planned_path'} | light_model
    (scene,) = (c for n, c in layout['configById'].items() if n.startswith('3D!'))
    assert set(scene['topics']) <= run_topics
    assert {'/map', '/scan', '/amcl_pose', '/searchlight_markers', '/visibility_grid',
            '/planned_path'} <= set(scene['topics'])  # fmt: skip
    assert scene['topics']['/amcl_pose']['showCovariance']
    plotted = {
        path['value'].split('.')[0]
        for name, config in layout['configById'].items()
        if name.startswith('Plot!')
        for path in config['paths']
    }
    assert plotted == {'/rl_env/episode_summary', '/rl_env/step_info'}
