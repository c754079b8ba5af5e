"""One sweep trial, run where the engine placed it, and its runs as plain records. No Ray, no
rclpy (a ROS trial starts `stealth train` as a process).

A trial (``sweep_plan.make_trial``) trains its configuration on each of its seeds: mode ``gym``
with ``harness.run`` in this process, mode ``ros`` with `stealth train` (its own private ROS
domain, ``ros_domain``, so trials side by side never hear each other), read back from its
summary.json and episodes.csv. Each run becomes a record: JSON-able data (the settings, the
learning curve, the final greedy episode, the policy file's bytes in base64 so that it reaches
the driver from any host), which ``record_result`` turns back into a ``harness.RunResult`` for
the report. A run that raises is a record with status ``failed`` and its error.

The objective (what optuna maximises and "best" means): the greedy return relative to the
optimum, ``1 - (optimum - greedy) / |optimum|`` (1 at the optimum), minus 0.01 x the fraction
of the budget spent before it stayed on the success criterion (1 when it never did), mean over
the seeds.
"""

from __future__ import annotations

import base64
import csv
import ctypes
import dataclasses
import json
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np
from stealth_core.reward import EpisodeOutcome

from stealth_experiments.harness import RunResult, RunSpec, run, settled, settled_within
from stealth_experiments.sweep_stop import MARK, TRIAL_MARK, scratch_prefix

SPEED_WEIGHT = 0.01
ROS_TIMEOUT = 3600.0  # s: a `stealth train` trial that takes longer is failed


def run_trial(trial: dict, where: dict | None = None) -> list[dict]:
    """Every seed of the trial: one record each (failed ones included)."""
    where = where or {}
    return [_run_seed(trial, seed, where) for seed in trial['seeds']]


def _run_seed(trial: dict, seed: int, where: dict) -> dict:
    started = time.time()
    base = {
        'trial': trial['id'],
        'settings': {k: v for k, v in trial.items() if k not in ('id', 'seeds')},
        'seed': seed,
        'host': socket.gethostname(),
        'pid': os.getpid(),
        **where,
    }
    try:
        with tempfile.TemporaryDirectory(prefix=scratch_prefix()) as scratch:
            runner = _run_ros if trial['mode'] == 'ros' else _run_gym
            result, policy = runner(trial, seed, Path(scratch))
            encoded = base64.b64encode(policy.read_bytes()).decode() if policy else None
    except Exception as error:  # a trial that crashes is recorded, the sweep goes on
        message = f'{type(error).__name__}: {error}'.strip().splitlines()[0][:500]
        return {
            **base,
            'status': 'failed',
            'error': message,
            'wall_seconds': time.time() - started,
        }
    return {**base, 'status': 'ok', 'error': '', **result_fields(result), 'policy': encoded}


def _spec(trial: dict, seed: int, policy_dir: str | None = None) -> RunSpec:
    return RunSpec(
        trial['scenario'], trial['learner'], seed, trial['episodes'], trial['eval_every'],
        trial['slip'], trial['goal'], policy_dir, tuple(sorted(trial['params'].items())),
    )  # fmt: skip


def _run_gym(trial: dict, seed: int, scratch: Path):
    result = run(_spec(trial, seed, str(scratch)))
    policy = next(scratch.glob('*.npz'), None)
    return result, policy


# The agent node's parameter for each harness parameter (config/agent.yaml).
ROS_PARAMETERS = {
    'alpha': 'alpha',
    'gamma': 'gamma',
    'initial_value': 'initialvalue',
    'n_planning': 'n',
    'theta': 'theta',
    'epsilon': 'epsilon',
    'epsilon_decay': 'epsilon_decay_episodes',
}


def ros_command(trial: dict, seed: int, runs_dir: Path) -> list[str]:
    """`stealth train` for one seed of a ROS trial (agent parameters by --set)."""
    command = [
        sys.executable, '-m', 'stealth_bringup.orchestrate',
        '--scenario', trial['scenario'], '--episodes', str(trial['episodes']),
        '--eval-every', str(trial['eval_every']), '--seed', str(seed),
        '--runs-dir', str(runs_dir), '--name', 'run', '--no-record',
        '--set', f'agent.agent={trial["learner"]}',
    ]  # fmt: skip
    if trial['goal']:
        command += ['--goal', trial['goal']]
    params = trial['params']
    if 'epsilon' in params or 'epsilon_decay' in params:  # as in harness.configured
        command += [
            '--set',
            'agent.epsilon_schedule=exponential',
            '--set',
            'agent.epsilon_final=0.0',
        ]
    for name, value in sorted(params.items()):
        command += ['--set', f'agent.{ROS_PARAMETERS[name]}={value}']
    return command


def _stop_with_parent() -> None:
    """In the `stealth train` child, before it runs: the signals of a process of its own, and
    SIGTERM (its orderly stop) when the worker that started it dies, so that a killed worker
    leaves no ROS nodes behind (Linux prctl PR_SET_PDEATHSIG).

    A Ray worker runs a trial in a thread with SIGINT blocked; a child inherits the mask, and
    its nodes then ignored the SIGINT that stops them (the run ended "did not stop cleanly").
    The child runs in a session of its own (sweep_stop: one stop signal, not the terminal's
    Ctrl-C as well), marked as its sweep's."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.signal.argtypes = [ctypes.c_int, ctypes.c_void_p]
    for number in (signal.SIGINT, signal.SIGTERM):
        libc.signal(int(number), None)  # SIG_DFL
    signal.pthread_sigmask(signal.SIG_SETMASK, [])
    libc.prctl(1, int(signal.SIGTERM))


def _run_ros(trial: dict, seed: int, scratch: Path):
    from stealth_core.gym_env import lattice_model
    from stealth_core.planners import value_iteration

    if trial['slip']:
        raise ValueError('a ROS trial has no slip (the simulator moves as it moves)')
    started = time.perf_counter()
    log = scratch / 'stealth-train.log'
    env = dict(os.environ)
    mark = env.pop(MARK, None)
    if mark:
        env[TRIAL_MARK] = mark
    with open(log, 'w', encoding='utf-8') as stream:
        finished = subprocess.run(
            ros_command(trial, seed, scratch), stdout=stream, stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL, timeout=ROS_TIMEOUT, check=False, env=env,
            preexec_fn=_stop_with_parent, start_new_session=True,
        )  # fmt: skip
    run_dir = scratch / 'run'
    summary_file = run_dir / 'summary.json'
    summary = (
        json.loads(summary_file.read_text(encoding='utf-8')) if summary_file.is_file() else {}
    )
    if finished.returncode != 0 or not summary:
        raise RuntimeError(f'stealth train exited {finished.returncode}: {_why(summary, log)}')
    with open(run_dir / 'episodes.csv', encoding='utf-8') as stream:
        rows = list(csv.DictReader(stream))
    training = [r for r in rows if r['greedy'] != 'True']
    greedy = [r for r in rows if r['greedy'] == 'True']
    if not greedy:
        raise RuntimeError('stealth train ran no greedy evaluation (raise episodes)')
    optimum = value_iteration(lattice_model(trial['scenario'], trial['goal'])).optimal_return
    eval_at = [sum(1 for t in training if int(t['episode']) < int(g['episode'])) for g in greedy]
    eval_returns = [float(g['total_reward']) for g in greedy]
    last = greedy[-1]
    final = {
        'outcome': EpisodeOutcome[last['outcome']],
        'steps': int(last['steps']),
        'total_reward': float(last['total_reward']),
        'peak_visibility': float(last['peak_visibility']),
        'accumulated_visibility': float(last['accumulated_visibility']),
        'path_length': float(last['path_length']),
        'points': None,
    }
    result = RunResult(
        _spec(trial, seed),
        optimum,
        np.array([float(t['total_reward']) for t in training]),
        np.array([EpisodeOutcome[t['outcome']] for t in training], dtype=np.int8),
        np.array(eval_at),
        np.array(eval_returns),
        ros_settled(eval_at, greedy, optimum),
        final,
        time.perf_counter() - started,
        int(summary.get('steps') or 0),
    )
    policy = run_dir / 'policy.npz'
    return result, policy if policy.is_file() else None


def _why(summary: dict, log: Path) -> str:
    """What a failed `stealth train` said: its summary's message, else its own last line."""
    if summary.get('message'):
        return f'{summary.get("status")}: {summary["message"]}'
    lines = [line for line in log.read_text(errors='replace').splitlines() if line.strip()]
    own = [line for line in lines if line.startswith('stealth train:')]
    return (own or lines or ['no output'])[-1]


# --- records ------------------------------------------------------------------------------------


def ros_settled(eval_at, greedy_rows, optimum: float) -> int | None:
    """Episodes until a ROS run's greedy evaluations stayed on the success criterion, read from
    episodes.csv's ``meets_criterion`` column; a run whose file predates the scores falls back
    on the old return criterion."""
    if greedy_rows and 'meets_criterion' in greedy_rows[0]:
        return settled(eval_at, [row['meets_criterion'] == 'True' for row in greedy_rows])
    returns = [float(row['total_reward']) for row in greedy_rows]
    return settled_within(eval_at, returns, optimum)


def score(greedy: float, optimum: float, episodes_to_within, budget: int) -> float:
    """The objective of one run (module docstring)."""
    relative = 1.0 - (optimum - greedy) / abs(optimum) if optimum else float(greedy >= optimum)
    spent = 1.0 if episodes_to_within is None else episodes_to_within / budget
    return relative - SPEED_WEIGHT * spent


def objective(records: list[dict]) -> float:
    """The mean score of a trial's runs; a failed run counts as -1 (worse than any return)."""
    return float(np.mean([r['score'] if r['status'] == 'ok' else -1.0 for r in records]))


def result_fields(result: RunResult) -> dict:
    final = {k: v for k, v in result.final.items() if k != 'points'}
    final['outcome'] = None if final.get('outcome') is None else int(final['outcome'])
    points = result.final.get('points')
    greedy = float(result.eval_returns[-1])
    return {
        'optimum': float(result.optimum),
        'greedy_return': greedy,
        'episodes_to_within': result.episodes_to_within,
        'score': score(greedy, result.optimum, result.episodes_to_within, result.spec.episodes),
        'wall_seconds': float(result.seconds),
        'env_steps': int(result.env_steps),
        'train_returns': [float(v) for v in result.train_returns],
        'train_outcomes': [int(v) for v in result.train_outcomes],
        'eval_at': [int(v) for v in result.eval_at],
        'eval_returns': [float(v) for v in result.eval_returns],
        'final': {k: (float(v) if isinstance(v, np.floating) else v) for k, v in final.items()},
        'points': None if points is None else np.asarray(points, dtype=float).tolist(),
    }


def record_result(record: dict) -> RunResult:
    """A successful run's record as the harness's RunResult (for harness_report)."""
    settings = record['settings']
    spec = _spec({**settings, 'seeds': [record['seed']]}, record['seed'])
    final = dict(record['final'])
    final['outcome'] = None if final.get('outcome') is None else EpisodeOutcome(final['outcome'])
    final['points'] = None if record['points'] is None else np.array(record['points'])
    return RunResult(
        spec,
        record['optimum'],
        np.array(record['train_returns']),
        np.array(record['train_outcomes'], dtype=np.int8),
        np.array(record['eval_at']),
        np.array(record['eval_returns']),
        record['episodes_to_within'],
        final,
        record['wall_seconds'],
        record['env_steps'],
    )


def replace_spec(result: RunResult, **changes) -> RunResult:
    return dataclasses.replace(result, spec=dataclasses.replace(result.spec, **changes))
