"""Nodes on several hosts: `stealth train --remote NODE` prints the command for the other host,
waits for the node to join and supervises it through the ROS graph.

The two-host test puts the "hosts" in two network namespaces joined by a veth pair, with Fast DDS
on UDP only (shared memory would work across namespaces, /dev/shm being one), cuts the link for
5 s mid-run and counts every action and state at both ends and in the recording. It needs root
and `ip netns`; the other tests join the "remote" agent from this host (--discovery localhost).
"""

import contextlib
import dataclasses
import itertools
import json
import os
from pathlib import Path
import re
import shlex
import shutil
import signal
import subprocess
import time

from mcap.reader import make_reader
import pytest
from test_env_node import totals
from test_resume import wait_for_episodes
import test_system
from test_system import (
    STEALTH,
    assert_nodes_exited_cleanly,
    one_line_error,
    read_bag,
    short_scenario,
    wait_for_text,
)

system = test_system.system  # the fixture of `stealth` runs, with its checks afterwards
ACTION, STATE = '/rl_agent/rl_action', '/rl_env/rl_state_reward'
JOIN_PREFIX = '  env -u ROS_LOCALHOST_ONLY ROS_DOMAIN_ID='
PARTITION = 5.0  # s the link is down
EPISODES = 20  # of the two-host run (and of the one-host run it is compared with)
EPISODES_BEFORE_PARTITION = 3  # finished before the link goes down
# Fast simulation (the namespaces' test is about the link, not the filter).
FAST = ('--set', 'simulator.particles=100', '--set', 'simulator.laser_beams=60')
# Only inside the namespaces the test creates.
ADDRESSES = {'a': '10.231.0.1/24', 'b': '10.231.0.2/24'}


def join_command(train) -> str:
    """The command `stealth train` printed for the other host (waits for it)."""
    wait_for_text(train, JOIN_PREFIX, timeout=60.0)
    lines = train.stderr_path.read_text().splitlines()
    return next(line.strip() for line in lines if line.startswith(JOIN_PREFIX))


def start_shell(command: str, env, log: Path, prefix=()) -> subprocess.Popen:
    """`command` through the shell, as a user pastes it (its own process group)."""
    stream = open(log, 'w')  # noqa: SIM115 - closed by stop()
    process = subprocess.Popen(
        [*prefix, 'bash', '-c', command],
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=stream,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    process.log, process.stream = log, stream
    return process


def stop(process: subprocess.Popen, timeout: float = 20.0) -> str:
    """SIGINT its group, wait (SIGKILL after `timeout`); its output."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGINT)
    try:
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(5)
    process.stream.close()
    return process.log.read_text()


@pytest.fixture
def remote(system):
    """Starts commands "on the other host" (through the shell, in the runs' environment); none
    survives the test."""
    started: list[subprocess.Popen] = []

    def start(command: str, name: str, prefix=(), **extra_env) -> subprocess.Popen:
        env = {**system.env, **extra_env}
        process = start_shell(command, env, system.tmp_path / f'{name}.log', prefix)
        started.append(process)
        return process

    yield start
    for process in started:
        if process.poll() is None:
            stop(process)


def in_background(system, args, prefix=(), **extra_env) -> subprocess.Popen:
    """`stealth args...` in the background like system.start, after `prefix` (ip netns exec)."""
    stderr = open(system.tmp_path / 'stderr.txt', 'w')  # noqa: SIM115 - closed with the process
    process = subprocess.Popen(
        [*prefix, STEALTH, *args],
        env={**system.env, **extra_env},
        cwd=system.tmp_path,
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        start_new_session=True,
    )
    process.stderr_path = system.tmp_path / 'stderr.txt'
    system.started.append(process)
    return process


def run_args(tmp_path, name: str, episodes: int, *more: str) -> list[str]:
    return [
        'train', '--scenario', str(short_scenario(tmp_path)), '--goal', 'easy',
        '--episodes', str(episodes), '--eval-every', '0', '--success-streak', '0',
        '--seed', '3', *FAST, '--name', name, '--runs-dir', str(tmp_path / 'runs'), *more,
    ]  # fmt: skip


# --- bad input and supervision, on one host ---------------------------------------------------


def test_a_remote_node_that_never_joins_is_a_timeout_naming_it_and_its_command(system, tmp_path):
    result = system.run(
        *run_args(tmp_path, 'lonely', 2, '--remote', 'agent', '--join-timeout', '3')
    )
    line = one_line_error(result, 'stealth train: agent did not join ROS domain ', 'within 3 s')
    command = line.split('start it on its host with: ', 1)[1]
    assert command.startswith('env -u ROS_LOCALHOST_ONLY ROS_DOMAIN_ID=')
    assert ' stealth run stealth_agent agent_node --ros-args -p ' in command
    run = system.runs / 'lonely'
    assert f'policy_file:={json.dumps(str((run / "policy.npz").resolve()))}' in shlex.split(
        command
    )
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'failed' and summary['remote_nodes']['agent']['state'] == (
        'never joined'
    )
    assert set(summary['nodes']) == {'recorder', 'simulator', 'environment'}
    assert_nodes_exited_cleanly(run, summary)
    assert read_bag(run / 'recording.mcap')[0] is not None  # closed and indexed


def test_an_agent_joins_with_the_printed_command_and_leaving_ends_the_run(
    system, remote, tmp_path
):
    train = system.start(*run_args(tmp_path, 'joined', 1000, '--remote', 'agent'))
    agent = remote(join_command(train), 'agent')
    wait_for_text(train, 'all nodes up')
    assert 'agent (remote) joined the run after ' in train.stderr_path.read_text()
    time.sleep(2.0)
    stop(agent)  # as Ctrl-C on its host: it leaves the graph
    assert train.wait(60) == 1
    stderr = train.stderr_path.read_text()
    line = stderr.strip().splitlines()[-1]
    assert line.startswith('stealth train: agent (remote) left the ROS graph during the run'), (
        stderr
    )
    assert 'Traceback' not in stderr
    run = system.runs / 'joined'
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'failed' and summary['remote_nodes']['agent']['state'] == 'left'
    assert_nodes_exited_cleanly(run, summary)
    bag_summary, messages, _ = read_bag(run / 'recording.mcap')
    assert bag_summary is not None and messages[ACTION]
    assert len(messages['/rl_env/episode_summary']) >= summary['episodes']


def test_a_second_agent_joining_stops_the_run_naming_the_topic(system, remote, tmp_path):
    train = system.start(*run_args(tmp_path, 'crowded', 1000, '--remote', 'agent'))
    command = join_command(train)
    remote(command, 'agent')
    wait_for_text(train, 'all nodes up')
    time.sleep(2.0)
    remote(command, 'second-agent')
    assert train.wait(60) == 1
    stderr = train.stderr_path.read_text()
    line = stderr.strip().splitlines()[-1]
    assert line.startswith(f'stealth train: a second agent joined the run: {ACTION} has 2 '), (
        stderr
    )
    assert '(nodes /agent, /agent)' in line and 'Traceback' not in stderr
    assert 'stealth train: agent runs on another host: stop it there (Ctrl-C)' in stderr
    run = system.runs / 'crowded'
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'failed'
    assert_nodes_exited_cleanly(run, summary)
    bag_summary, messages, _ = read_bag(run / 'recording.mcap')
    assert bag_summary is not None
    assert len(messages['/rl_env/episode_summary']) >= summary['episodes']


# --- two hosts: two network namespaces --------------------------------------------------------


@dataclasses.dataclass
class Host:
    """A network namespace standing for a host, with its end of the veth pair."""

    netns: str
    veth: str
    address: str

    @property
    def exec(self) -> list[str]:
        return ['ip', 'netns', 'exec', self.netns]

    def ip(self, *args: str) -> None:
        _ip('-n', self.netns, *args)

    def link(self, state: str) -> None:
        """The link up or down; up again, with the multicast route discovery needs (a link
        going down takes its routes with it)."""
        self.ip('link', 'set', self.veth, state)
        if state == 'up':
            self.ip('route', 'replace', '224.0.0.0/4', 'dev', self.veth)


def _ip(*args: str) -> None:
    subprocess.run(['ip', *args], check=True, capture_output=True, text=True, timeout=20)


@pytest.fixture
def two_hosts():
    """Namespaces a and b joined by a veth pair (10.231.0.1 and .2), multicast routed over it;
    removed afterwards, with anything still running in them."""
    if os.geteuid() != 0 or shutil.which('ip') is None:
        pytest.skip('needs root and iproute2 to make two network namespaces')
    tag = os.getpid() % 100_000
    hosts = {
        side: Host(f'stealth-{side}-{tag}', f'st{side}{tag}', ADDRESSES[side]) for side in 'ab'
    }
    try:
        for host in hosts.values():
            _ip('netns', 'add', host.netns)
        _ip('link', 'add', hosts['a'].veth, 'type', 'veth', 'peer', 'name', hosts['b'].veth)
        for host in hosts.values():
            _ip('link', 'set', host.veth, 'netns', host.netns)
            host.ip('addr', 'add', host.address, 'dev', host.veth)
            host.ip('link', 'set', 'lo', 'up')
            host.link('up')
    except subprocess.CalledProcessError as error:
        _remove(hosts.values())
        pytest.skip(f'no network namespaces here: {error.stderr.strip()}')
    try:
        yield hosts
    finally:
        _remove(hosts.values())


def _remove(hosts) -> None:
    for host in hosts:
        pids = subprocess.run(
            ['ip', 'netns', 'pids', host.netns], capture_output=True, text=True, check=False
        ).stdout.split()
        for pid in pids:
            with contextlib.suppress(ProcessLookupError):
                os.kill(int(pid), signal.SIGKILL)
        subprocess.run(['ip', 'netns', 'del', host.netns], capture_output=True, check=False)


def recorded_times(path: Path, topics) -> dict[str, list[int]]:
    """Log times (ns) of every message of `topics` in the recording."""
    times = {topic: [] for topic in topics}
    with open(path, 'rb') as stream:
        for _, channel, message in make_reader(stream).iter_messages(topics=list(topics)):
            times[channel.topic].append(message.log_time)
    return times


def test_an_agent_on_another_host_loses_nothing_over_a_partition(
    system, two_hosts, remote, tmp_path
):
    """Simulator, environment and recorder on host a, the agent on host b, UDP between them;
    the link goes down for 5 s mid-run: every action and state still arrives exactly once."""
    a, b = two_hosts['a'], two_hosts['b']
    udp = {'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'}  # no shared memory between the "hosts"
    args = run_args(tmp_path, 'two-hosts', EPISODES, '--discovery', 'subnet', '--remote', 'agent')
    train = in_background(system, [*args, '--join-timeout', '60'], a.exec, **udp)
    command = join_command(train)
    assert ' ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET stealth run stealth_agent agent_node ' in command
    agent = remote(command, 'agent', b.exec, **udp)
    wait_for_text(train, 'all nodes up', timeout=90)
    # Paced by the run's own progress, not a sleep: a fast loop had ended all its episodes
    # before a link that went down 3 s after the start came back.
    wait_for_episodes(train, system.runs / 'two-hosts' / 'episodes.csv', EPISODES_BEFORE_PARTITION)
    down = time.time_ns()
    b.link('down')
    time.sleep(PARTITION)
    b.link('up')
    up = time.time_ns()
    assert train.wait(150) == 0, train.stderr_path.read_text()
    stderr = train.stderr_path.read_text()
    assert 'agent (remote) joined the run after ' in stderr and 'Traceback' not in stderr
    assert 'stealth train: agent runs on another host: stop it there (Ctrl-C)' in stderr
    # On b: what reached the agent and what it sent, counted by the agent itself.
    agent_log = stop(agent)
    counted = re.search(r'totals: (\d+) states received, (\d+) actions sent', agent_log)
    assert counted, agent_log
    reached_b, sent_actions = map(int, counted.groups())

    run = system.runs / 'two-hosts'
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'budget' and summary['discovery'] == 'subnet'
    assert summary['remote_nodes']['agent']['state'] == 'on the graph'
    env = totals((run / 'logs' / 'environment.log').read_text())
    _, messages, _ = read_bag(run / 'recording.mcap')
    times = recorded_times(run / 'recording.mcap', (ACTION, STATE))
    # The partition fell inside the run: steps before the link went down and after it came up.
    assert min(times[ACTION]) < down and max(times[ACTION]) > up
    # Not one action or state lost or duplicated: the same counts at both ends and recorded, but
    # for the run's end: the environment exits right after its last state (which may then not
    # get out), and the agent may answer it when the environment is gone (the recorder, stopped
    # last, still records that action).
    counts = (env, sent_actions, reached_b, {topic: len(t) for topic, t in times.items()})
    assert env['states'] - reached_b in (0, 1), counts
    assert env['states'] - len(times[STATE]) in (0, 1), counts
    assert sent_actions == len(times[ACTION]), counts
    assert sent_actions - env['received'] in (0, 1) and env['dropped'] == 0, counts
    # Every state is an episode's first or a move's result (the stop may cut the last move).
    assert env['executed'] - (env['states'] - env['episodes']) in (0, 1)
    # Every step of every episode that ended recorded once, in order.
    steps = [(m.episode, m.step) for m in messages['/rl_env/step_info']]
    assert len(steps) == len(set(steps))
    ended = {m.episode: m.steps for m in messages['/rl_env/episode_summary']}
    assert summary['episodes'] == EPISODES <= len(ended)
    for episode, count in ended.items():
        assert [s for e, s in steps if e == episode] == list(range(1, count + 1)), episode
    # ... and the agent acted once on every state of them.
    acted = {m.episode: m.steps for m in messages['/rl_agent/episode_info']}
    assert {episode: acted.get(episode) for episode in ended} == ended

    all_times = sorted(times[ACTION] + times[STATE])
    stall = max(later - earlier for earlier, later in itertools.pairwise(all_times)) / 1e9
    across = summary['steps_per_s']
    without_stall = summary['steps'] / max(1e-9, summary['run_s'] - stall)
    one_host = system.run(*run_args(tmp_path, 'one-host', EPISODES))
    assert one_host.returncode == 0, one_host.stderr
    local = json.loads((system.runs / 'one-host' / 'summary.json').read_text())['steps_per_s']
    print(
        f'\ntwo hosts (network namespaces, UDP): {summary["steps"]} steps at {across} steps/s '
        f'({without_stall:.1f} without the partition); one host: {local} steps/s; the '
        f'{PARTITION:g} s partition stalled the run {stall:.1f} s'
    )
