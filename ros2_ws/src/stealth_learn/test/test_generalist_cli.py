"""`python -m stealth_learn.generalist` as a user runs it: a bad weights file or an argument out
of range stops it in one line (exit 2), and Ctrl-C stops it, or a long plan of the network, at
once (exit 130), compile or run alike (issue 40)."""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from stealth_learn import policy_file

PROMPT = 3.0  # s from Ctrl-C to the process gone ("within a couple of seconds", 2 loaded cores)
COMMAND = [sys.executable, '-m', 'stealth_learn.generalist']


def _run(args, timeout=120.0) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*COMMAND, *args], capture_output=True, text=True, timeout=timeout, check=False
    )


def _with_header(path: Path, **changes) -> Path:
    """The shipped weights with the architecture's fields changed (not checked: a bad file)."""
    with np.load(policy_file.SHIPPED) as stored:
        arrays = {name: np.array(stored[name]) for name in stored.files}
    header = json.loads(str(arrays[policy_file.HEADER]))
    header['architecture'].update(changes)
    arrays[policy_file.HEADER] = np.array(json.dumps(header))
    np.savez_compressed(path, **arrays)
    return path


def _longest(path: Path) -> Path:
    """A valid file: the shipped weights at the most Bellman backups the header allows."""
    params, header = policy_file.load(policy_file.SHIPPED, policy_file.policy_layout('full'))
    architecture = {**header['architecture'], 'iterations': policy_file.MAX_ITERATIONS}
    return policy_file.save(path, params, 'full', architecture, header['training'])


def test_a_bad_weights_file_stops_it_in_one_line(tmp_path):
    empty = tmp_path / 'empty.npz'
    empty.write_bytes(b'')
    nan = tmp_path / 'nan.npz'
    with np.load(policy_file.SHIPPED) as stored:
        arrays = {name: np.array(stored[name]) for name in stored.files}
    arrays['params/scale'] = np.array(np.nan, np.float32)
    np.savez_compressed(nan, **arrays)
    hidden = _with_header(tmp_path / 'hidden.npz', hidden=16)
    long = _with_header(tmp_path / 'long.npz', iterations=100_000_000)
    lines = {
        empty: f'{empty}: empty file (0 bytes), expected a generalist policy file (.npz with '
        '__header__ and the parameters)',
        nan: f"{nan}: parameter 'scale': 1 of 1 values not finite (NaN or infinite in "
        'float32): the file is corrupt',
        hidden: f"{hidden}: parameter 'reward_hidden/bias': expected shape (16,) for the "
        "header's architecture (hidden 16, features 8), found (32,)",
        long: f"{long} header: field 'architecture.iterations': expected an integer 1..10000, "
        'got 100000000',
        tmp_path: f'{tmp_path}: is a directory, expected a generalist policy file (.npz)',
    }
    for path, line in lines.items():
        done = _run(['--policy', str(path), '--test', '1'])
        assert done.returncode == 2, done.stderr
        assert done.stderr.splitlines() == [f'generalist: {line}']


@pytest.mark.parametrize('count', ['0', '-1'])
def test_a_test_count_below_one_is_an_argument_error(count):
    done = _run(['--test', count])
    assert done.returncode == 2, done.stderr
    assert 'Traceback' not in done.stderr
    assert done.stderr.splitlines()[-1] == (
        f'python -m stealth_learn.generalist: error: --test: expected a whole number >= 1, '
        f'got {count}'
    )


def _interrupt(command, ready, after: float, env=None) -> tuple[int, float, str]:
    """(exit code, s from SIGINT to exit, stderr) of ``command``, sent SIGINT ``after`` s after
    ``ready()`` said its output shows the JAX work under way."""
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True, env=env,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not ready(process) and time.monotonic() < deadline:
            assert process.poll() is None, process.communicate()
        time.sleep(after)
        assert process.poll() is None, 'it ended before Ctrl-C'
        sent = time.monotonic()
        os.killpg(process.pid, signal.SIGINT)  # Ctrl-C: the terminal signals the group
        try:
            _, err = process.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            _, err = process.communicate()
        return process.returncode, time.monotonic() - sent, err
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


# One plan of a 500 x 500 lattice at the most backups the header allows: 6-15 s of XLA (a
# building of 250 x 250 m at 0.5 m); Ctrl-C 0.5 s into the run (JAX logs the compile's end).
_LONG_PLAN = """
import sys
import numpy as np
from stealth_learn.generalist import GeneralistPolicy
from stealth_learn.vin import FREE, GOAL, MOVE_RIGHT, MOVE_UP
grid = np.zeros((500, 500, 7), np.float32)
grid[..., FREE] = 1.0
grid[0, 0, GOAL] = 1.0
grid[-1, :, MOVE_UP] = -2.0
grid[:, -1, MOVE_RIGHT] = -2.0
policy = GeneralistPolicy.load(sys.argv[1], 'stealth-grid-v1/full')
print('planning', flush=True)
try:
    policy.cell_logits(grid)
except KeyboardInterrupt:
    sys.exit(130)
print('planned', flush=True)
"""


def _compiled(process) -> bool:
    """Whether the plan is under way: it said so, and JAX logged the network's compile."""
    assert process.stdout.readline().strip() == 'planning'
    compiled = 'Finished XLA compilation of jit(<lambda>)'
    return any(compiled in line for line in iter(process.stderr.readline, ''))


def test_ctrl_c_stops_a_long_plan_of_the_network_at_once(tmp_path):
    weights = _longest(tmp_path / 'longest.npz')
    command = [sys.executable, '-c', _LONG_PLAN, str(weights)]
    env = {**os.environ, 'JAX_LOG_COMPILES': '1'}
    code, latency, err = _interrupt(command, _compiled, after=0.5, env=env)
    print(f'SIGINT to exit during a plan: {latency:.2f} s')
    assert code == 130, err
    assert latency < PROMPT, f'{latency:.1f} s'
    assert 'FATAL' not in err and 'Traceback' not in err, err


def test_ctrl_c_stops_the_evaluation_at_once(tmp_path):
    """The command on the largest generated buildings at the most backups: interrupted while
    it plans and rolls out, one line and 130."""
    weights = _longest(tmp_path / 'longest.npz')
    command = [*COMMAND, '--policy', str(weights), '--test', '20', '--width', '60',
               '--height', '40', '--lights', '8']  # fmt: skip
    code, latency, err = _interrupt(command, lambda process: True, after=12.0)
    print(f'SIGINT to exit during the evaluation: {latency:.2f} s')
    assert code == 130, err
    assert err.strip().splitlines()[-1] == 'generalist: interrupted', err
    assert 'Traceback' not in err and 'FATAL' not in err, err
    assert latency < PROMPT, f'{latency:.1f} s'
