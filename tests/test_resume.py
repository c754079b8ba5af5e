"""What a killed `stealth train` leaves, and `stealth train --resume` going on from there.

SIGKILL of the orchestrator mid-run: its nodes stop on their own (PR_SET_PDEATHSIG), episodes.csv
holds every episode it counted and summary.json the run as of its last greedy evaluation;
`stealth doctor` removes the Fast DDS files the dead run left in /dev/shm, naming them. Then
`--resume` continues the run: the episode numbers, episodes.csv, the summary and a second
recording file, read with the first as one bag. Bad input is one line before anything starts.
"""

import csv
import json
import os
import signal
import time
import warnings

from ros_support import leaked_shm_segments, shm_segments
from test_system import (
    described,
    one_line_error,
    processes_naming,
    read_bag,
    short_scenario,
    wait_for_text,
)
from test_system import system as system  # noqa: F401, PLC0414 - the fixture, used by name

KILLED_AFTER = 7  # episodes counted before the orchestrator is killed (two greedy ones)
MORE = 5  # episodes the continued run adds


def episodes_in(path) -> list[int]:
    if not path.exists():
        return []
    return [int(row['episode']) for row in csv.DictReader(path.open())]


def wait_for_episodes(process, path, count: int, timeout: float = 240.0) -> None:
    deadline = time.monotonic() + timeout
    while len(episodes_in(path)) < count:
        assert process.poll() is None, process.stderr_path.read_text()
        assert time.monotonic() < deadline, process.stderr_path.read_text()
        time.sleep(0.2)


def test_a_killed_orchestrator_leaves_its_outputs_and_the_run_goes_on(system, tmp_path):
    shm_before = shm_segments()
    scenario = short_scenario(tmp_path)
    train = system.start(
        'train', '--scenario', str(scenario), '--goal', 'easy', '--episodes', '200',
        '--eval-every', '3', '--success-streak', '0', '--seed', '5', '--name', 'r',
        '--runs-dir', str(system.runs),
    )  # fmt: skip
    run = system.runs / 'r'
    wait_for_text(train, 'all nodes up')
    wait_for_episodes(train, run / 'episodes.csv', KILLED_AFTER)
    os.kill(train.pid, signal.SIGKILL)  # the orchestrator alone: no chance to stop its nodes
    train.wait(10)
    killed_at = time.monotonic()
    while processes_naming(run) and time.monotonic() - killed_at < 60:
        time.sleep(0.2)
    stopped_after = time.monotonic() - killed_at
    outlived = described(processes_naming(run))
    logs = {log.name: log.read_text(errors='replace') for log in (run / 'logs').glob('*.log')}
    assert not outlived, f'nodes outlived their orchestrator by a minute: {outlived}\n' + ''.join(
        f'--- the end of {name}:\n{text[-1500:]}\n' for name, text in sorted(logs.items())
    )
    for name, text in sorted(logs.items()):
        # a stop watchdog's dump (running.STOP_LIMIT, the recorder's) or the orphan watch's
        if 'Timeout (' in text or 'most recent call first' in text:
            warnings.warn(f'{name}: a stop hung, then ended:\n{text[-3000:]}', stacklevel=1)

    # What the killed run left: every episode it counted, the summary of its last evaluation.
    counted = episodes_in(run / 'episodes.csv')
    assert counted == list(range(len(counted))) and len(counted) >= KILLED_AFTER
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'running' and summary['mode'] == 'train'
    greedy = [e for e in counted if (e + 1) % 3 == 0]
    assert summary['final_greedy']['episode'] == greedy[-1]
    assert summary['episodes'] >= greedy[-1] + 1
    assert len(summary['scenario']['sha256']) == 64
    assert (run / 'policy.npz').is_file()  # the agent saved it as it stopped (SIGTERM)

    # The nodes stopped on SIGTERM: what they left in /dev/shm, stealth doctor removes.
    left = sorted(leaked_shm_segments(shm_before))
    doctor = system.run('doctor')
    assert 'Traceback' not in doctor.stderr + doctor.stdout
    if left:  # named with any other dead process's files (ros_domain's tests check the names)
        assert 'Fast DDS files of dead processes: fastrtps_' in doctor.stdout, doctor.stdout
    assert not leaked_shm_segments(shm_before), doctor.stdout
    shown = ', '.join(left) or 'none'
    print(f'\nSIGKILL of stealth train: its nodes gone after {stopped_after:.1f} s; '
          f'{len(left)} Fast DDS files left in /dev/shm ({shown})')  # fmt: skip

    # --resume: the same run goes on where episodes.csv stopped.
    total = len(counted) + MORE
    result = system.run('train', '--resume', str(run), '--episodes', str(total), timeout=300)
    assert result.returncode == 0, result.stderr + result.stdout
    assert 'Traceback' not in result.stderr
    assert f'continued from episode {len(counted)} ({len(counted)} done)' in result.stderr
    assert episodes_in(run / 'episodes.csv') == list(range(total))
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'budget' and summary['episodes'] == total
    assert [part['status'] for part in summary['parts']] == ['running', 'budget']
    assert summary['parts'][1]['episodes'] == [len(counted), total - 1]
    assert summary['seeds'] == {'simulator': 5, 'environment': 5, 'agent': 5}
    assert summary['policy']['saved'] and summary['policy']['episodes'] > 0
    assert summary['files']['recording_files'] == ['runs/r/recording.mcap',
                                                   'runs/r/recording_1.mcap']  # fmt: skip
    for png in ('learning_curve.png', 'path.png'):
        assert (run / png).read_bytes()[:4] == b'\x89PNG'
    agent = (run / 'params' / 'agent.yaml').read_text()
    assert 'load_policy: true' in agent and f'first_episode: {len(counted)}' in agent

    # The second file of the recording holds the continued episodes, numbered on.
    _, messages, _ = read_bag(run / 'recording_1.mcap')
    numbers = sorted({m.episode for m in messages['/rl_env/episode_summary']})
    assert numbers[0] == len(counted) and set(range(len(counted), total)) <= set(numbers)
    greedy = {m.episode for m in messages['/rl_agent/episode_info'] if m.greedy}
    assert greedy >= {e for e in range(len(counted), total) if (e + 1) % 3 == 0}
    info = system.run('bag', 'info', str(run))
    assert info.returncode == 0, info.stderr
    assert 'runs/r/recording.mcap' in info.stdout and 'runs/r/recording_1.mcap' in info.stdout

    # A changed scenario file: the run is not continued.
    scenario.write_text(scenario.read_text() + '\n# edited after the run\n')
    result = system.run('train', '--resume', str(run), '--episodes', str(total + 5))
    one_line_error(result, f'--resume {run}: its scenario file {scenario} changed since the run')


def test_bad_resume_and_unknown_parameters_are_one_line_before_anything_starts(system, tmp_path):
    result = system.run('train', '--resume', str(tmp_path))
    one_line_error(result, f'--resume {tmp_path}: not a run directory', 'summary.json')
    result = system.run('train', '--resume', str(tmp_path / 'none'))
    one_line_error(result, f'--resume {tmp_path / "none"}: no such directory')

    started = time.monotonic()
    result = system.run('train', '--set', 'agent.epsilonn=0.2', '--runs-dir', str(system.runs))
    one_line_error(result, "--set agent.epsilonn: agent has no parameter 'epsilonn'",
                   "did you mean 'epsilon'")  # fmt: skip
    assert time.monotonic() - started < 30  # no node was started (it took 8.8 s after them)
    assert not system.runs.exists()


def test_a_run_from_the_floor_plan_starts_its_agent_at_each_lattice_state(system, tmp_path):
    """`stealth train --prior floor_plan`: the agent node loads the table the run wrote (no
    episodes yet, a row per lattice state) and learns on from it; its saved policy keeps them."""
    from stealth_agent.policy_store import load_policy

    scenario = short_scenario(tmp_path)
    result = system.run(
        'train', '--scenario', str(scenario), '--goal', 'easy', '--episodes', '4',
        '--eval-every', '2', '--seed', '5', '--name', 'p', '--prior', 'floor_plan',
        '--runs-dir', str(system.runs),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "the agent's table starts from the floor plan (603 states)" in result.stderr
    agent_log = (system.runs / 'p' / 'logs' / 'agent.log').read_text()
    assert 'policy.npz (0 episodes, 603 states); learning' in agent_log
    policy = load_policy(system.runs / 'p' / 'policy.npz')
    assert policy.learner.episodes > 0 and len(policy.index) == 603  # learned on from it
