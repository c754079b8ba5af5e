"""The whole system as a user runs it: `stealth train` / `stealth rollout` start the simulator, the
environment, the agent and the recorder as separate processes in a private ROS domain (the
orchestrator picks it), run episodes over DDS and leave runs/<name>/ behind.

Every test checks that no process of its run outlives it (every node's command line names the
run directory) and that no Fast DDS segment is left in /dev/shm.
"""

import csv
import json
import os
from pathlib import Path
import signal
import subprocess
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
from ros_support import REPO_ROOT, leaked_shm_segments, ros_environment, shm_segments
import yaml

BIN = REPO_ROOT / 'ros2_ws' / 'install' / 'stealth_tools' / 'lib' / 'stealth_tools'
STEALTH = str(BIN / 'stealth')
NODES = ('recorder', 'simulator', 'environment', 'agent')
# Every topic of a run, and the type recorded for it (/parameter_events carries nothing here).
TOPICS = {
    '/rl_env/rl_env_description': 'stealth_interfaces/msg/RLEnvDescription',
    '/rl_env/rl_state_reward': 'stealth_interfaces/msg/RLStateReward',
    '/rl_env/step_info': 'stealth_interfaces/msg/StepInfo',
    '/rl_env/episode_summary': 'stealth_interfaces/msg/EpisodeSummary',
    '/rl_agent/rl_action': 'stealth_interfaces/msg/RLAction',
    '/rl_agent/rl_experiment_info': 'stealth_interfaces/msg/RLExperimentInfo',
    '/rl_agent/episode_info': 'stealth_interfaces/msg/AgentEpisodeInfo',
    '/searchlights': 'stealth_interfaces/msg/SearchlightArray',
    '/searchlight_markers': 'visualization_msgs/msg/MarkerArray',
    '/map': 'nav_msgs/msg/OccupancyGrid',
    '/amcl_pose': 'geometry_msgs/msg/PoseWithCovarianceStamped',
    '/odom': 'nav_msgs/msg/Odometry',
    '/ground_truth': 'nav_msgs/msg/Odometry',
    '/scan': 'sensor_msgs/msg/LaserScan',
    '/clock': 'rosgraph_msgs/msg/Clock',
    '/tf': 'tf2_msgs/msg/TFMessage',
    '/rosout': 'rcl_interfaces/msg/Log',
}
OUTCOMES = ('SUCCESS', 'DETECTED', 'TIMEOUT', 'ABORTED')
STEP_LIMIT = 60  # the test scenario's: short episodes, so a few take seconds


@pytest.fixture
def system(tmp_path):
    """Runs `stealth` commands; afterwards nothing of them runs and no shm segment leaked."""
    before = shm_segments()
    env = ros_environment(0)
    env.pop('ROS_DOMAIN_ID')  # the orchestrator takes a private one itself
    env.pop('STEALTH_NAV_SCENARIOS', None)
    runner = Runner(env, tmp_path)
    yield runner
    for process in runner.started:
        if process.poll() is None:
            process.kill()
            process.wait(10)
    leftovers = processes_naming(tmp_path)
    still = described(leftovers)
    for pid in leftovers:
        os.kill(pid, signal.SIGKILL)
    assert not leftovers, f'processes of the run still running: {still}'
    leaked = leaked_shm_segments(before)
    assert not leaked, f'Fast DDS shared memory left in /dev/shm: {sorted(leaked)}'


class Runner:
    def __init__(self, env, tmp_path: Path):
        self.env = env
        self.tmp_path = tmp_path
        self.runs = tmp_path / 'runs'
        self.started: list[subprocess.Popen] = []

    def run(self, *args, timeout=150):
        """`stealth args...` to completion, in the test's directory."""
        return subprocess.run(
            [STEALTH, *args],
            env=self.env,
            cwd=self.tmp_path,
            capture_output=True,
            text=True,
            timeout=timeout,
        )

    def start(self, *args, log: str = 'stderr.txt') -> subprocess.Popen:
        """`stealth args...` in the background (its own session, as a shell job would be), its
        stderr to the file `log` in the test's directory."""
        stderr = open(self.tmp_path / log, 'w')  # noqa: SIM115 - closed with the process
        process = subprocess.Popen(
            [STEALTH, *args],
            env=self.env,
            cwd=self.tmp_path,
            stdout=subprocess.PIPE,
            stderr=stderr,
            text=True,
            start_new_session=True,
        )
        process.stderr_path = self.tmp_path / log
        self.started.append(process)
        return process


def processes_naming(path: Path) -> list[int]:
    """PIDs of live processes whose command line mentions `path` (every node of a run does)."""
    found = []
    for cmdline in Path('/proc').glob('[0-9]*/cmdline'):
        try:
            text = cmdline.read_bytes().replace(b'\0', b' ').decode(errors='replace')
        except OSError:
            continue
        if str(path) in text and int(cmdline.parent.name) != os.getpid():
            found.append(int(cmdline.parent.name))
    return found


def described(pids: list[int]) -> str:
    """Which processes: each PID with its state and program (`python` stripped), for a failure
    that names what outlived a run."""
    lines = []
    for pid in pids:
        try:
            words = Path(f'/proc/{pid}/cmdline').read_bytes().split(b'\0')
            state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
        except OSError:
            lines.append(f'{pid} (gone)')
            continue
        program = next((w for w in words[1:] if b'/' in w), words[0]).decode(errors='replace')
        lines.append(f'{pid} (state {state}, {Path(program).name})')
    return ', '.join(lines)


def short_scenario(tmp_path: Path) -> Path:
    """simple-maze with a step limit of STEP_LIMIT, as a scenario file of its own."""
    data = yaml.safe_load((REPO_ROOT / 'scenarios' / 'simple-maze.yaml').read_text())
    data.update(
        name='short-maze',
        map=str(REPO_ROOT / 'maps' / 'simple-maze.yaml'),
        step_limit=STEP_LIMIT,
    )
    path = tmp_path / 'short-maze.yaml'
    path.write_text(yaml.safe_dump(data))
    return path


def read_bag(path: Path):
    """(summary, {topic: [decoded messages]}, {topic: schema name}); every message decoded."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        messages: dict[str, list] = {}
        for _, channel, _, decoded in reader.iter_decoded_messages():
            messages.setdefault(channel.topic, []).append(decoded)
    types = {
        channel.topic: summary.schemas[channel.schema_id].name
        for channel in summary.channels.values()
    }
    return summary, messages, types


def assert_nodes_exited_cleanly(run: Path, summary: dict, but=()) -> None:
    """Every node of the run's summary (less those named in `but`) exited with code 0; if not,
    the failure shows how each other one ended and the end of its log."""
    shown = []
    for name, node in summary['nodes'].items():
        if name in but or node['exit'] == 'exited with code 0':
            continue
        log = run / 'logs' / f'{name}.log'
        tail = log.read_text(errors='replace').splitlines()[-15:] if log.exists() else []
        shown.append(f'{name} {node["exit"]}; end of {log}:\n' + '\n'.join(tail))
    assert not shown, '\n'.join(shown)


def wait_for_text(process, text: str, timeout: float = 90.0) -> None:
    """Wait until a background `stealth` has written `text` to stderr."""
    deadline = time.monotonic() + timeout
    while text not in process.stderr_path.read_text():
        assert process.poll() is None, process.stderr_path.read_text()
        assert time.monotonic() < deadline, process.stderr_path.read_text()
        time.sleep(0.1)


def one_line_error(result, *needles: str) -> str:
    """The failure line of a command that failed cleanly (last stderr line, no traceback)."""
    assert result.returncode == 1, (result.stdout, result.stderr)
    assert 'Traceback' not in result.stderr + result.stdout, result.stderr
    line = result.stderr.strip().splitlines()[-1]
    assert line.startswith('stealth train: '), result.stderr
    for needle in needles:
        assert needle in line, result.stderr
    return line


def test_train_runs_episodes_over_dds_and_leaves_a_complete_run(system, tmp_path):
    scenario = short_scenario(tmp_path)
    # epsilon 0.2 (the default is 0): a greedy episode must say 0 where training ones do not.
    result = system.run(
        'train', '--scenario', str(scenario), '--goal', 'easy', '--episodes', '8',
        '--eval-every', '4', '--success-streak', '0', '--seed', '3', '--name', 'sys',
        '--set', 'agent.epsilon=0.2', '--runs-dir', str(system.runs),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr + result.stdout
    assert 'Traceback' not in result.stderr
    run = system.runs / 'sys'
    assert 'Replay:    stealth bag play runs/sys/recording.mcap' in result.stdout
    assert 'Evaluate:  stealth rollout --run runs/sys' in result.stdout

    # The run directory is complete.
    for name in ('recording.mcap', 'policy.npz', 'summary.json', 'episodes.csv',
                 'learning_curve.png', 'path.png'):  # fmt: skip
        assert (run / name).is_file(), f'{name} missing: {sorted(os.listdir(run))}'
    for node in NODES:
        params = yaml.safe_load((run / 'params' / f'{node}.yaml').read_text())
        assert set(params) == {node} and 'ros__parameters' in params[node]
        assert (run / 'logs' / f'{node}.log').stat().st_size > 0
    environment = yaml.safe_load((run / 'params' / 'environment.yaml').read_text())
    assert environment['environment']['ros__parameters']['scenario'] == str(scenario)
    assert environment['environment']['ros__parameters']['seed'] == 3
    for png in ('learning_curve.png', 'path.png'):
        assert (run / png).read_bytes()[:4] == b'\x89PNG'

    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'budget' and summary['episodes'] == 8
    assert summary['greedy_episodes'] == 2 and summary['training_episodes'] == 6
    assert summary['scenario']['name'] == 'short-maze' and summary['goal'] == 'easy'
    assert summary['seeds'] == {'simulator': 3, 'environment': 3, 'agent': 3}
    assert_nodes_exited_cleanly(run, summary)
    # The agent learns until it is stopped: an episode may end between the budget and that.
    late = summary['not_counted']
    assert summary['policy']['saved']
    assert 6 <= summary['policy']['episodes'] <= 6 + len(late)

    # Every topic carried traffic, and every message of the recording decodes.
    bag_summary, messages, types = read_bag(run / 'recording.mcap')
    assert bag_summary is not None, 'the recording was not closed (no summary section)'
    assert bag_summary.statistics.message_count == sum(len(m) for m in messages.values())
    for topic, type_name in TOPICS.items():
        assert types.get(topic) == type_name, (topic, types.get(topic))
        assert messages.get(topic), f'no traffic on {topic}'

    # summary.json and episodes.csv tell what the recording shows.
    not_counted = {entry['episode'] for entry in late}
    summaries = {m.episode: m for m in messages['/rl_env/episode_summary']}
    counted = [summaries[e] for e in sorted(summaries) if e not in not_counted]
    assert [m.episode for m in counted] == list(range(8))
    assert summary['outcomes'] == {
        name: sum(OUTCOMES[m.outcome] == name for m in counted) for name in OUTCOMES
    }
    steps = [m for m in messages['/rl_env/step_info'] if m.episode in set(range(8))]
    assert summary['steps'] == sum(m.steps for m in counted) == len(steps)
    actions = len(messages['/rl_agent/rl_action'])
    assert len(messages['/rl_env/step_info']) <= actions <= len(messages['/rl_env/step_info']) + 1
    rows = list(csv.DictReader((run / 'episodes.csv').open()))
    for row, message in zip(rows, counted, strict=True):
        assert int(row['episode']) == message.episode
        assert row['outcome'] == OUTCOMES[message.outcome]
        assert int(row['steps']) == message.steps
        assert float(row['total_reward']) == pytest.approx(message.total_reward, rel=1e-5)
    # Each episode scored on the lattice nodes its actions sent the robot to (episode_scores),
    # against the optimum on the lattice; the true and estimated path lengths beside them.
    from stealth_core.gym_env import lattice_model
    from stealth_core.path_scores import replay_actions

    model = lattice_model(str(scenario), 'easy')
    optimum = summary['optimum_on_lattice']
    assert summary['criterion']['max_path_ratio'] == 1.1
    for row in rows:
        mine = sorted((m.step, m.action) for m in steps if m.episode == int(row['episode']))
        lattice = replay_actions(model, [action for _, action in mine])
        assert int(row['lattice_steps']) == lattice.steps
        assert float(row['lattice_path_length']) == pytest.approx(lattice.path_length, rel=1e-5)
        assert float(row['path_over_optimum']) == pytest.approx(
            lattice.path_length / optimum['path_length'], rel=1e-5
        )
        assert float(row['true_path_over_optimum']) == pytest.approx(
            float(row['path_length']) / optimum['path_length'], rel=1e-5
        )
        assert float(row['estimated_path_length']) > 0
        assert row['meets_criterion'] in ('True', 'False')
    greedy = {m.episode for m in messages['/rl_agent/episode_info'] if m.greedy and m.episode < 8}
    assert greedy == {3, 7} == {int(r['episode']) for r in rows if r['greedy'] == 'True'}
    for message in messages['/rl_agent/episode_info']:
        assert (message.epsilon == 0.0) == message.greedy
    # Nothing of the first episode is missing (the first one is held until the recorder listens).
    assert {m.episode for m in messages['/rl_agent/episode_info']} >= set(range(8))
    infos = messages['/rl_agent/rl_experiment_info']
    assert {m.episode_number for m in infos} >= set(range(8))
    first_states = [m for m in messages['/rl_env/step_info'] if (m.episode, m.step) == (0, 1)]
    assert len(first_states) == 1

    # The saved policy rolls out (greedy, no learning) on the same scenario.
    result = system.run('rollout', '--run', str(run), '--episodes', '2')
    assert result.returncode == 0, result.stderr + result.stdout
    (evaluation,) = sorted(run.glob('eval-*'))
    evaluated = json.loads((evaluation / 'summary.json').read_text())
    assert evaluated['mode'] == 'eval' and evaluated['episodes'] == 2
    assert evaluated['greedy_episodes'] == 2
    agent = yaml.safe_load((evaluation / 'params' / 'agent.yaml').read_text())
    assert agent['agent']['ros__parameters']['evaluate'] is True
    assert read_bag(evaluation / 'recording.mcap')[0] is not None


def test_sigint_mid_run_stops_every_process_and_closes_the_recording(system, tmp_path):
    train = system.start(
        'train', '--scenario', str(short_scenario(tmp_path)), '--episodes', '1000',
        '--name', 'interrupted', '--runs-dir', str(system.runs),
    )  # fmt: skip
    run = system.runs / 'interrupted'
    wait_for_text(train, 'all nodes up')
    time.sleep(4.0)  # a few episodes in
    nodes = [pid for pid in processes_naming(run) if pid != train.pid]
    assert len(nodes) >= len(NODES), nodes  # every node is running
    train.send_signal(signal.SIGINT)
    assert train.wait(60) == 130
    stderr = train.stderr_path.read_text()
    assert 'stealth train: interrupted by SIGINT after ' in stderr, stderr
    assert 'Traceback' not in stderr
    assert not processes_naming(run)

    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'interrupted'
    assert_nodes_exited_cleanly(run, summary)
    bag_summary, messages, _ = read_bag(run / 'recording.mcap')
    assert bag_summary is not None and bag_summary.chunk_indexes, 'the MCAP is not indexed'
    assert messages['/rl_env/step_info'] and messages['/rl_env/rl_env_description']
    assert len(messages['/rl_env/episode_summary']) >= summary['episodes']


def test_without_respawn_a_node_dying_stops_the_others_and_cleans_its_memory(system, tmp_path):
    train = system.start(
        'train', '--scenario', str(short_scenario(tmp_path)), '--episodes', '1000',
        '--name', 'killed', '--runs-dir', str(system.runs), '--respawn', '0',
    )  # fmt: skip
    run = system.runs / 'killed'
    wait_for_text(train, 'all nodes up')
    time.sleep(2.0)
    (environment,) = processes_naming(run / 'params' / 'environment.yaml')
    os.kill(environment, signal.SIGKILL)  # no chance to clean up after itself
    assert train.wait(60) == 1
    stderr = train.stderr_path.read_text()
    line = stderr.strip().splitlines()[-1]
    assert line.startswith('stealth train: environment was killed by SIGKILL during the run'), (
        stderr
    )
    assert '(log: runs/killed/logs/environment.log)' in line and 'Traceback' not in stderr
    assert not processes_naming(run)
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'failed'
    assert summary['nodes']['environment']['exit'] == 'was killed by SIGKILL'
    assert_nodes_exited_cleanly(run, summary, but=('environment',))
    assert read_bag(run / 'recording.mcap')[0] is not None  # closed and indexed all the same
    # The fixture checks that the killed node's /dev/shm segments are gone.


def test_bad_input_is_one_line_before_anything_starts(system, tmp_path):
    runs = str(system.runs)
    result = system.run('train', '--scenario', 'no-such-scenario', '--runs-dir', runs)
    line = one_line_error(result, "scenario 'no-such-scenario': not found", 'simple-maze')
    assert result.stderr.strip() == line and not system.runs.exists()

    result = system.run('train', '--goal', 'impossible', '--runs-dir', runs)
    one_line_error(result, "--goal 'impossible'", 'it has: easy, medium, hard')

    params = tmp_path / 'params'
    params.mkdir()
    (params / 'agent.yaml').write_text('agent:\n  ros__parameters:\n    epsilon: [0.1\n')
    result = system.run('train', '--params-dir', str(params), '--runs-dir', runs)
    one_line_error(result, f'parameter file {params / "agent.yaml"}: not valid YAML (line 4)')

    result = system.run('train', '--set', 'agent.epsilon', '--runs-dir', runs)
    one_line_error(result, "--set 'agent.epsilon': expected node.parameter=value")

    result = system.run(
        'train', '--executable', f'environment={tmp_path / "no_env_node"}', '--runs-dir', runs
    )
    one_line_error(result, f'environment: executable {tmp_path / "no_env_node"} does not exist')

    # With the default floor-plan prior: was a ValueError traceback and an empty run directory.
    result = system.run('train', '--set', 'agent.gamma=1.5', '--name', 'g', '--runs-dir', runs)
    line = one_line_error(result, '--set agent.gamma: expected a number from 0 to 1, got 1.5')
    assert result.stderr.strip() == line
    assert not system.runs.exists()  # nothing was created for any of them


@pytest.mark.parametrize(
    ('setting', 'node', 'reason'),
    [
        ('simulator.particles=5', 'simulator', 'particles'),
        ('agent.agent=texplore', 'agent', "unknown learner 'texplore'"),
    ],
)
def test_a_node_that_crashes_on_start_stops_the_run(system, setting, node, reason):
    """The node is the installed one given as --executable, whose parameters the run leaves to
    it (stealth train refuses these values itself for the nodes it knows)."""
    from stealth_bringup.run_config import NODES
    from stealth_tools.executables import find_executable

    spec = NODES[node]
    executable = find_executable(spec.package, spec.executable)
    result = system.run(
        'train', '--set', setting, '--executable', f'{node}={executable}', '--name', 'crash',
        '--runs-dir', str(system.runs), timeout=90,
    )  # fmt: skip
    line = one_line_error(
        result, f'stealth train: {node} exited with code 2 during startup after ', reason
    )
    assert f'(log: runs/crash/logs/{node}.log)' in line
    summary = json.loads((system.runs / 'crash' / 'summary.json').read_text())
    assert summary['status'] == 'failed' and summary['message'] in line
    assert summary['episodes'] == 0
    others = {name: state['exit'] for name, state in summary['nodes'].items() if name != node}
    # The others are stopped with SIGINT, some while still importing (before rclpy handles the
    # signal, Python itself dies of it): both are the clean stops of supervisor.CLEAN_EXITS.
    clean = ('exited with code 0', 'was killed by SIGINT')
    assert others and all(exit in clean for exit in others.values()), others
