"""Same seed, same episodes, whatever the load (issue 15).

Two `stealth train` runs of the default scenario with the same seed, started side by side while
busy processes hog the CPU, must hand the agent the same states and rewards, get the same
actions and report the same episodes: every message of the RL topics of their recordings is
compared (stamps aside, stealth_tools.rl_compare), and a difference fails the test naming the
first message that differs. Before the fix (ending a move within the controller's stopped speed
let the simulator's idle timer step the physics by however much wall time had passed before the
next move) two such runs parted within the first few episodes.

And `stealth train --compose` (the simulator in the environment's process, called directly)
must give the very episodes of separate processes: the same messages on every RL topic.
"""

import contextlib
import json
import subprocess
import sys

import pytest
from stealth_tools.rl_compare import RL_TOPICS, first_difference, read_rl_topics
import test_system

system = test_system.system  # the fixture of `stealth` runs, with its checks afterwards
EPISODES = 12  # of simple-maze's easy goal: ~1,500 steps, long explorations and short successes
SEED = 3
HOGS = 2  # busy processes: as many as CI's cores, so the runs' nodes wait for the CPU
RUN_TIMEOUT = 600.0  # s for both runs together (about 2 min on 2 loaded cores)
HOG = 'import time\nend = time.monotonic() + {limit}\nwhile time.monotonic() < end:\n    pass\n'


@contextlib.contextmanager
def cpu_hog(count: int, limit: float):
    """`count` processes spinning on the CPU until the block ends (and after `limit` s on their
    own, should this process die first)."""
    hogs = [
        subprocess.Popen([sys.executable, '-c', HOG.format(limit=limit)]) for _ in range(count)
    ]
    try:
        yield hogs
    finally:
        for hog in hogs:
            hog.kill()
        for hog in hogs:
            hog.wait(10)


TRAIN = ('train', '--episodes', str(EPISODES), '--seed', str(SEED), '--success-streak', '0')


def _same_episodes(system, runs: dict, what: str) -> None:
    """Wait for the runs ({name: process}); their recordings' RL topics must be equal."""
    for run in runs.values():
        try:
            run.wait(RUN_TIMEOUT)
        except subprocess.TimeoutExpired:
            pytest.fail(f'no end within {RUN_TIMEOUT:g} s:\n{run.stderr_path.read_text()}')
    for run in runs.values():
        assert run.returncode == 0, run.stderr_path.read_text()
    first, second = (read_rl_topics(system.runs / name / 'recording.mcap') for name in runs)
    difference = first_difference(first, second, EPISODES)
    counts = ', '.join(f'{topic} {len(first[topic])}' for topic in RL_TOPICS)
    assert difference is None, (
        f'{what} with seed {SEED} differ in their first {EPISODES} episodes: {difference}'
    )
    print(f'\n{EPISODES} episodes the same message for message ({counts})')


def test_the_same_seed_gives_the_same_episodes_under_load(system):
    names = ('first', 'second')
    with cpu_hog(HOGS, limit=RUN_TIMEOUT) as hogs:
        runs = {name: system.start(*TRAIN, '--name', name, log=f'{name}.txt') for name in names}
        _same_episodes(system, runs, 'two runs')
        assert all(hog.poll() is None for hog in hogs), 'the CPU hog ended before the runs'


def test_a_composed_run_gives_the_episodes_of_separate_processes(system):
    runs = {
        'separate': system.start(*TRAIN, '--name', 'separate', log='separate.txt'),
        'composed': system.start(*TRAIN, '--compose', '--name', 'composed', log='composed.txt'),
    }
    _same_episodes(system, runs, 'a composed and a separate run')
    summary = json.loads((system.runs / 'composed' / 'summary.json').read_text())
    assert summary['composed'] and set(summary['nodes']) == {'recorder', 'environment', 'agent'}
    assert summary['nodes']['environment']['command'][0].endswith('sim_env')
    log = (system.runs / 'composed' / 'logs' / 'environment.log').read_text()
    assert 'robot over the simulator in this process (called directly' in log
