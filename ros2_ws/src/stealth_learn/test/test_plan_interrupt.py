"""Ctrl-C stops a long plan of the network at once (exit 130), compile or run alike (issue 40):
every user of ``GeneralistPolicy.cell_logits`` (the evaluation's is `stealth generalist`, the
benchmark's: tests/test_benchmark.py interrupts it)."""

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from stealth_learn import policy_file

PROMPT = 3.0  # s from Ctrl-C to the process gone ("within a couple of seconds", 2 loaded cores)


def _longest(path: Path) -> Path:
    """A valid file: the shipped weights at the most Bellman backups the header allows."""
    params, header = policy_file.load(policy_file.SHIPPED, policy_file.policy_layout('full'))
    architecture = {**header['architecture'], 'iterations': policy_file.MAX_ITERATIONS}
    return policy_file.save(path, params, 'full', architecture, header['training'])


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
import signal
import sys
import numpy as np
signal.signal(signal.SIGINT, signal.default_int_handler)  # as at a terminal, even in a job
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
    compiled = 'Finished XLA compilation of jit(decide)'
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
