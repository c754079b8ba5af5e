"""Fault tolerance of `stealth train` (respawn): every node SIGKILLed in turn during one training,
and a node that keeps crashing.

The chaos run kills the agent, the environment, the simulator and the recorder, one at each of
KILL_AT's episodes; the run must still reach its stop criterion with contiguous episode numbers
(none counted twice), a recording that holds every step of every episode (the killed recorder's
file recovered, the respawned recorder's file beside it; the episode the killed environment cut
short may end early there, as the last step it sent may reach only the monitor), and nothing
left running or in /dev/shm (the `system` fixture checks those two).
"""

import csv
import json
import os
from pathlib import Path
import re
import signal
import stat
import time

from test_system import processes_naming, read_bag, wait_for_text
from test_system import system as system  # noqa: F401, PLC0414 - the fixture, used by name

KILL_ORDER = ('agent', 'environment', 'simulator', 'recorder')
# The episodes the kills come at, in KILL_ORDER. Paced by episodes, not seconds: the stop
# criterion (STREAK greedy successes in a row, one every 5 episodes) cannot be met before
# episode 4 + 5 * (STREAK - 1) = 149, however fast the machine learns, so every kill lands
# during the run (paced by 20 s, a faster loop met the criterion before the third kill).
KILL_AT = (10, 40, 70, 100)
STREAK = 30
RESPAWN_TIMEOUT = 120.0  # s for a killed node to be back (a loaded 2-core machine)
EPISODE_LINE = re.compile(r'^episode (\d+) ', re.MULTILINE)


def kill_node_pid(run: Path, name: str) -> int:
    """The live process of node `name` of the run (its params file names it)."""
    pids = processes_naming(run / 'params' / f'{name}.yaml')
    assert len(pids) == 1, f'{name}: expected one live process, found {pids}'
    return pids[0]


def kill_node(run: Path, name: str) -> int:
    """SIGKILL the live process of node `name` of the run; its pid."""
    pid = kill_node_pid(run, name)
    os.kill(pid, signal.SIGKILL)
    return pid


def wait_for_episode(train, episode: int, timeout: float = 300.0) -> None:
    """Wait until the run's progress lines have reached `episode` (the run still going)."""
    deadline = time.monotonic() + timeout
    while True:
        stderr = train.stderr_path.read_text()
        if max(map(int, EPISODE_LINE.findall(stderr)), default=-1) >= episode:
            return
        assert train.poll() is None, f'the run ended before episode {episode}:\n{stderr}'
        assert time.monotonic() < deadline, f'no episode {episode} in {timeout:g} s:\n{stderr}'
        time.sleep(0.1)


def recorded_steps(run: Path) -> dict[tuple[int, int], int]:
    """{(episode, step): times recorded} over every file of the run's recording."""
    files = sorted(run.glob('recording*.mcap'))
    assert [f.name for f in files] == ['recording.mcap', 'recording_1.mcap'], files
    seen: dict[tuple[int, int], int] = {}
    for path in files:
        _, messages, _ = read_bag(path)  # every file opens: the killed one was recovered
        for step in messages['/rl_env/step_info']:
            key = (step.episode, step.step)
            seen[key] = seen.get(key, 0) + 1
    return seen


def missing_steps(rows: list[dict], seen) -> list[tuple[int, int]]:
    """(episode, step) of every step episodes.csv's `rows` count that is not in `seen`."""
    return [
        (int(r['episode']), step)
        for r in rows
        for step in range(1, int(r['steps']) + 1)
        if (int(r['episode']), step) not in seen
    ]


def test_every_node_killed_in_turn_and_the_run_still_reaches_its_goal(system, tmp_path):
    train = system.start(
        'train', '--success-streak', str(STREAK), '--eval-every', '5', '--episodes', '400',
        '--name', 'chaos', '--runs-dir', str(system.runs),
    )  # fmt: skip
    run = system.runs / 'chaos'
    wait_for_text(train, 'all nodes up', timeout=180)
    for name, episode in zip(KILL_ORDER, KILL_AT, strict=True):
        wait_for_episode(train, episode)
        kill_node(run, name)
        wait_for_text(train, f'{name} is back after', timeout=RESPAWN_TIMEOUT)
    assert train.wait(900) == 0, train.stderr_path.read_text()
    stderr = train.stderr_path.read_text()
    assert 'Traceback' not in stderr

    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'success', summary['message']
    restarts = summary['restarts']
    assert [r['node'] for r in restarts] == list(KILL_ORDER), restarts
    for restart in restarts:
        assert 'was killed by SIGKILL' in restart['cause'] and restart['back_after'] > 0
    with open(run / 'episodes.csv', newline='') as stream:
        rows = list(csv.DictReader(stream))
    episodes = [int(r['episode']) for r in rows]
    assert episodes == list(range(len(episodes))), 'episode numbers not contiguous or repeated'
    assert summary['episodes'] == len(episodes)
    # Each episode a restart cut short is counted ABORTED (a node killed between two episodes
    # cuts none short).
    for restart in restarts:
        if restart['aborted_episode'] is not None:
            assert rows[restart['aborted_episode']]['outcome'] == 'ABORTED', restart

    seen = recorded_steps(run)
    # A step the environment sent just before its SIGKILL may reach the monitor and not the
    # recorder (nothing resends for a killed writer): the episode it cut short may end early
    # in the recording, never with a gap.
    killed_in = [
        r['aborted_episode']
        for r in restarts
        if r['node'] == 'environment' and r['aborted_episode'] is not None
    ]
    for episode in killed_in:
        recorded = sorted(step for e, step in seen if e == episode)
        assert recorded == list(range(1, len(recorded) + 1)), (episode, recorded)
    missing = [m for m in missing_steps(rows, seen) if m[0] not in killed_in]
    assert not missing, f'{len(missing)} steps not in the recording, first {missing[:5]}'
    # Beyond those, only episodes after the last counted one: the run goes on while its stop
    # (after the end criterion) reaches the agent, and they are not counted (a CI rehearsal at
    # load 4 recorded two, the second cut short).
    extra = sorted({episode for episode, _ in seen} - set(episodes))
    after = list(range(len(episodes), len(episodes) + len(extra)))
    assert extra == after, f'steps of uncounted episodes {extra}'


def test_a_node_that_keeps_crashing_is_given_up_after_its_retries(system, tmp_path):
    crashing = tmp_path / 'crashing_agent'
    crashing.write_text(
        '#!/bin/sh\necho "[ERROR] [0.0] [agent]: cannot open /nonexistent/policy.npz"\nexit 1\n'
    )
    crashing.chmod(crashing.stat().st_mode | stat.S_IXUSR)
    result = system.run(
        'train', '--episodes', '5', '--name', 'crashing', '--runs-dir', str(system.runs),
        '--executable', f'agent={crashing}', '--respawn', '2',
    )  # fmt: skip
    assert result.returncode == 1, result.stderr
    assert 'Traceback' not in result.stderr
    line = result.stderr.strip().splitlines()[-1]
    assert line.startswith('stealth train: agent exited with code 1'), result.stderr
    assert 'cannot open /nonexistent/policy.npz' in line  # its last log line
    assert 'not restarted again: it already was 2 times (--respawn 2)' in line
    run = system.runs / 'crashing'
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'failed'
    assert [r['node'] for r in summary['restarts']] == ['agent', 'agent']
    assert [r['delay'] for r in summary['restarts']] == [0.5, 1.0]
    assert (run / 'logs' / 'agent.log').read_text().count('cannot open') == 3


def test_a_killed_composed_process_comes_back_with_both_nodes(system):
    """--compose: the simulator and the environment die together and come back together as
    the environment's process; the run goes on with contiguous episodes, every step recorded."""
    train = system.start(
        'train', '--compose', '--success-streak', '0', '--episodes', '30', '--seed', '2',
        '--name', 'composed', '--runs-dir', str(system.runs),
    )  # fmt: skip
    run = system.runs / 'composed'
    wait_for_text(train, 'all nodes up', timeout=180)
    wait_for_episode(train, 10)
    composed = kill_node_pid(run, 'environment')
    assert kill_node(run, 'simulator') == composed  # one process
    wait_for_text(train, 'environment is back after', timeout=RESPAWN_TIMEOUT)
    assert train.wait(300) == 0, train.stderr_path.read_text()
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['composed'] and [r['node'] for r in summary['restarts']] == ['environment']
    with open(run / 'episodes.csv', newline='') as stream:
        rows = list(csv.DictReader(stream))
    assert [int(r['episode']) for r in rows] == list(range(30))
    _, messages, _ = read_bag(run / 'recording.mcap')
    seen = {(step.episode, step.step) for step in messages['/rl_env/step_info']}
    missing = missing_steps(rows, seen)
    assert not missing, f'{len(missing)} steps not in the recording, first {missing[:5]}'


def test_a_recorder_stalled_until_the_run_stops_still_records_every_step(system):
    """A recorder that falls behind (here stopped outright, SIGSTOP, from the first episode's
    end until the run stops its nodes) misses what DDS could not deliver meanwhile. A reliable
    writer resends it on its next heartbeat (3 s apart), so only while it lives: the agent and
    the environment wait for every subscriber's acknowledgement before they exit."""
    train = system.start(
        'train', '--success-streak', '0', '--episodes', '20', '--seed', '3',
        '--name', 'stalled', '--runs-dir', str(system.runs),
    )  # fmt: skip
    run = system.runs / 'stalled'
    wait_for_text(train, 'all nodes up', timeout=180)
    deadline = time.monotonic() + 120.0
    episodes = run / 'episodes.csv'
    while not episodes.exists() or len(episodes.read_text().splitlines()) < 2:  # episode 0 ended
        assert train.poll() is None and time.monotonic() < deadline, train.stderr_path.read_text()
        time.sleep(0.05)
    recorder = kill_node_pid(run, 'recorder')
    os.kill(recorder, signal.SIGSTOP)
    try:
        wait_for_text(train, 'stopping agent', timeout=300)
    finally:
        os.kill(recorder, signal.SIGCONT)
    assert train.wait(120) == 0, train.stderr_path.read_text()
    with open(episodes, newline='') as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 20 and sum(int(r['steps']) for r in rows[1:]) > 100, rows
    _, messages, _ = read_bag(run / 'recording.mcap')
    seen = {(step.episode, step.step) for step in messages['/rl_env/step_info']}
    missing = missing_steps(rows, seen)
    assert not missing, f'{len(missing)} steps not in the recording, first {missing[:5]}'
