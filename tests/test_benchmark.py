"""`stealth benchmark` end to end, as a user runs it: two small shipped scenarios and an
unreadable file one after another (--jobs 1), then on a local Ray of two CPUs; and Ctrl-C in
the middle, which writes the trials done, marks the rest interrupted and exits 130, the
generalist's JAX work included; a bad generalist weights file refused in one line."""

import csv
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from ros_support import _sourced_environment
from stealth_agent.learners import LEARNER_NAMES
from stealth_experiments.benchmark_methods import TWINS, learning_extra
from stealth_experiments.sweep_engine import RAY_ENVIRONMENT

TIMEOUT = 420.0  # s, on two loaded cores (a local Ray's start included)
REQUIRED = (
    'scenario', 'goal', 'track', 'method', 'success', 'detected', 'return', 'vi_return',
    'path_length', 'vi_path_length', 'exposure', 'seconds',
)  # fmt: skip


def _env() -> dict:
    env = dict(_sourced_environment())
    env.update(RAY_ENVIRONMENT)
    env['RAY_AUTH_MODE'] = 'disabled'
    return env


def _wait_for_log(process, log, text: str) -> None:
    """Until the running benchmark's log holds text (or it ended, or TIMEOUT passed)."""
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline and process.poll() is None:
        log.seek(0)
        if text in log.read():
            return
        time.sleep(0.2)


def _benchmark(args, log) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, '-m', 'stealth_tools.cli', 'benchmark', *args],
        env=_env(), stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
    )  # fmt: skip


def _finish(process, log) -> tuple[int | None, str]:
    try:
        process.wait(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    log.seek(0)
    return process.returncode, log.read()


def _rows(out: Path) -> list[dict]:
    with open(out / 'results.csv', encoding='utf-8') as stream:
        reader = csv.DictReader(stream)
        assert set(REQUIRED) <= set(reader.fieldnames)
        return list(reader)


def test_a_benchmark_one_after_another_names_an_unreadable_scenario_and_runs_the_rest(tmp_path):
    broken = tmp_path / 'broken.yaml'
    broken.write_text('not: [yaml\n')
    out = tmp_path / 'out'
    with open(tmp_path / 'log', 'w+') as log:
        process = _benchmark(
            [str(broken), 'map1', '--jobs', '1', '--episodes', '20', '--out', str(out)], log,
        )  # fmt: skip
        code, output = _finish(process, log)
    assert code == 0, output[-3000:]
    assert f'stealth benchmark: {broken}: YAML syntax error' in output, output[-3000:]
    assert 'its rows are marked failed' in output
    rows = _rows(out)
    # per scenario: value iteration and A* on both tracks, Dark Path and every learner on the
    # full one (not on the learning track: asked for by name), the 2 replanners on the sensed
    # one; the generalist and its three twins on both where the learning extra is installed
    # (default methods only there; not the cycle rule, `stealth generalist`'s)
    twins = ('generalist', *(twin for twin in TWINS if twin != 'generalist (cycle rule)'))
    generalist = {(m, t) for m in twins for t in ('full', 'sensed')} if learning_extra() else set()
    learners = {(name, 'full') for name in LEARNER_NAMES}
    per = 7 + len(learners) + len(generalist)
    assert len(rows) == 2 * per
    ran = [r for r in rows if r['scenario'] == 'map1']
    assert {r['status'] for r in ran} == {'ok'}
    assert {(r['method'], r['track']) for r in ran} == {
        ('value iteration', 'full'), ('value iteration', 'sensed'), ('A*', 'full'),
        ('A*', 'sensed'), ('Dark Path', 'full'), ('replan (unknown dark)', 'sensed'),
        ('replan (unknown lit)', 'sensed'), *learners, *generalist,
    }  # fmt: skip
    oracle = [r for r in ran if r['method'] == 'value iteration']
    assert all(r['success'] == 'True' and r['return'] == r['vi_return'] for r in oracle)
    failed = [r for r in rows if r['scenario'] == 'broken']
    assert len(failed) == per and {r['status'] for r in failed} == {'failed'}
    summary = (out / 'summary.md').read_text()
    assert '## Track: full' in summary and '## Track: sensed' in summary
    assert '## Track: learning' not in summary and not (out / 'learning.csv').exists()
    assert 'Learners trained 20 episodes per scenario goal' in summary
    assert (out / 'benchmark.png').stat().st_size > 10_000
    assert f'stealth benchmark: {per} of {2 * per} rows failed' in output


def test_a_benchmark_on_a_local_ray(tmp_path):
    out = tmp_path / 'out'
    with open(tmp_path / 'log', 'w+') as log:
        process = _benchmark(
            ['simple-maze', 'map1', '--jobs', '2', '--methods', 'vi', 'replan-dark',
             '--no-plots', '--out', str(out)], log,
        )  # fmt: skip
        code, output = _finish(process, log)
    assert code == 0, output[-3000:]
    assert 'engine: a local Ray is up' in output
    assert 'benchmark: trial finished: 4/4 done, 0 running, 0 failed' in output, output[-3000:]
    rows = _rows(out)
    assert sorted((r['scenario'], r['method'], r['track']) for r in rows) == [
        ('map1', 'replan (unknown dark)', 'sensed'), ('map1', 'value iteration', 'full'),
        ('map1', 'value iteration', 'sensed'), ('simple-maze', 'replan (unknown dark)', 'sensed'),
        ('simple-maze', 'value iteration', 'full'), ('simple-maze', 'value iteration', 'sensed'),
    ]  # fmt: skip
    assert {r['status'] for r in rows} == {'ok'}
    assert not (out / 'benchmark.png').exists()


def test_ctrl_c_writes_the_trials_done_and_marks_the_rest_interrupted(tmp_path):
    out = tmp_path / 'out'
    with open(tmp_path / 'log', 'w+') as log:
        # a learner with a budget it will not finish: Ctrl-C comes while it trains
        process = _benchmark(
            ['simple-maze', '--jobs', '1', '--methods', 'vi', 'qlearning',
             '--episodes', '10000000', '--out', str(out)], log,
        )  # fmt: skip
        try:
            _wait_for_log(process, log, 'benchmark: trial finished: 1/2 done')
        finally:
            os.killpg(process.pid, signal.SIGINT)  # Ctrl-C: the terminal signals the group
        code, output = _finish(process, log)
    assert code == 130, output[-3000:]
    line = 'stealth benchmark: Interrupted by SIGINT: 1 of 2 trials done; the rest marked'
    assert line in output, output[-3000:]
    rows = _rows(out)
    assert [(r['method'], r['track'], r['status']) for r in rows] == [
        ('value iteration', 'full', 'ok'),
        ('value iteration', 'sensed', 'ok'),
        ('qlearning', 'full', 'interrupted'),
    ]
    assert '**Interrupted by SIGINT: 1 of 2 trials done' in (out / 'summary.md').read_text()


needs_learning = pytest.mark.skipif(not learning_extra(), reason='needs the learning extra')


def _weights(tmp_path: Path, name: str, change) -> Path:
    """The shipped generalist weights, ``change(arrays, header)`` applied, unchecked."""
    from stealth_learn import policy_file

    with np.load(policy_file.SHIPPED) as stored:
        arrays = {key: np.array(stored[key]) for key in stored.files}
    header = json.loads(str(arrays.pop(policy_file.HEADER)))
    change(arrays, header)
    path = tmp_path / name
    np.savez_compressed(path, **arrays, **{policy_file.HEADER: np.array(json.dumps(header))})
    return path


@needs_learning
def test_a_bad_generalist_weights_file_stops_the_benchmark_in_one_line(tmp_path):
    """Refused before any trial (issue 40: a wrong shape ran every generalist row into Flax's
    error and exited 0; an empty file was a traceback)."""
    empty = tmp_path / 'empty.npz'
    empty.write_bytes(b'')

    def shape(arrays, header):
        arrays['params/reward_hidden/kernel'] = arrays['params/reward_hidden/kernel'][:-1]

    def nan(arrays, header):
        arrays['params/goal_value'] = np.array(np.nan, np.float32)

    def iterations(arrays, header):
        header['architecture']['iterations'] = 100_000_000

    files = {
        empty: 'empty file (0 bytes)',
        _weights(tmp_path, 'shape.npz', shape): (
            "parameter 'reward_hidden/kernel': expected shape (13, 32)"
        ),
        _weights(tmp_path, 'nan.npz', nan): "parameter 'goal_value': 1 of 1 values not finite",
        _weights(tmp_path, 'long.npz', iterations): (
            "field 'architecture.iterations': expected an integer 1..10000, got 100000000"
        ),
    }
    for path, expected in files.items():
        done = subprocess.run(
            [sys.executable, '-m', 'stealth_tools.cli', 'benchmark', 'simple-maze', '--jobs',
             '1', '--methods', 'vi', 'generalist', '--policy-file', str(path), '--out',
             str(tmp_path / 'out')],
            env=_env(), capture_output=True, text=True, timeout=TIMEOUT, check=False,
        )  # fmt: skip
        assert done.returncode == 1, done.stdout[-2000:] + done.stderr
        lines = done.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith(f'stealth benchmark: {path}'), lines
        assert expected in lines[0], lines
        assert not (tmp_path / 'out' / 'results.csv').exists()


@needs_learning
def test_ctrl_c_during_the_generalist_exits_130_at_once(tmp_path):
    """The generalist at the most Bellman backups the header allows, on the largest generated
    building (60 x 40 m, 8 lights; the sensed track plans anew as it senses): Ctrl-C while it
    plans ends the benchmark within seconds, its rows interrupted (issue 40: a header of 1e8
    backups ignored SIGINT and SIGTERM until SIGKILL)."""
    from stealth_core.scenario_generator import Options, generate
    from stealth_learn import policy_file

    scenario = generate(1_000_000, Options(width=60, height=40, lights=8)).write(tmp_path)
    params, header = policy_file.load(policy_file.SHIPPED, policy_file.policy_layout('full'))
    architecture = {**header['architecture'], 'iterations': policy_file.MAX_ITERATIONS}
    weights = policy_file.save(tmp_path / 'longest.npz', params, 'full', architecture)
    out = tmp_path / 'out'
    with open(tmp_path / 'log', 'w+') as log:
        process = _benchmark(
            [str(scenario), '--jobs', '1', '--tracks', 'sensed', '--methods', 'vi', 'generalist',
             '--policy-file', str(weights), '--no-plots', '--out', str(out)], log,
        )  # fmt: skip
        try:
            _wait_for_log(process, log, 'benchmark: trial finished: 1/2 done')
            time.sleep(4.0)  # into the generalist's trial: JAX's compile, then its plans
            assert process.poll() is None, 'the generalist trial ended before Ctrl-C'
        finally:
            sent = time.monotonic()
            os.killpg(process.pid, signal.SIGINT)
        code, output = _finish(process, log)
    latency = time.monotonic() - sent
    print(f'SIGINT to exit during the generalist trial: {latency:.2f} s')
    assert code == 130, output[-3000:]
    assert latency < 5.0, f'{latency:.1f} s'
    assert 'Traceback' not in output and 'FATAL' not in output, output[-3000:]
    rows = _rows(out)
    assert [(r['method'], r['track'], r['status']) for r in rows] == [
        ('value iteration', 'sensed', 'ok'),
        ('generalist', 'sensed', 'interrupted'),
    ]
