"""`stealth sweep` on a two-node Ray cluster on this machine: a head and a second node, one CPU
each, on loopback. A small sweep (2 learners x 2 seeds in-process, and one ROS-in-the-loop trial
on the default scenario) runs on it; while it runs, the worker process of a trial is killed.
Checked: trials ran on both nodes, every run is recorded with its results and policy, the killed
trial was retried and the sweep completed; then, one trial's results removed as if the sweep had
stopped before it, `--resume` runs that trial alone. Both nodes are stopped at the end (by their
process ids, never `ray stop`, which would stop every Ray on the machine), also when the test
fails.

On a local Ray of one CPU: Ctrl-C (SIGINT to the sweep's process group, as a terminal sends it)
and SIGTERM end a sweep with 130 and 143, its results marked interrupted with the trials done,
and --resume runs the stopped trial; a ROS trial interrupted leaves no process and no Fast DDS
file behind; a sweep whose every run failed exits 1.
"""

import contextlib
import csv
import json
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import tempfile
import time

import pytest
from ros_support import _sourced_environment
from stealth_bringup.ros_domain import dead_shm_files, shm_segments
from stealth_experiments.sweep_engine import RAY_ENVIRONMENT
from stealth_experiments.sweep_stop import RUNS_DIR_PREFIX, TRIAL_MARK

RAY = str(Path(sys.executable).parent / 'ray')
START_TIMEOUT = 240.0  # s: a Ray node on two loaded cores
SWEEP_TIMEOUT = 420.0

SWEEP = """
name: two-nodes
scenarios: [{scenario: simple-maze, goal: easy}]
learners: [qlearning, dyna]
seeds: [0, 1]
episodes: {qlearning: 60, dyna: 20}
eval_every: 5
mode: gym
extra:
  - {mode: ros, scenario: simple-maze, goal: easy, learner: dyna, seed: 0, episodes: 10}
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def _children() -> dict[int, list[int]]:
    tree: dict[int, list[int]] = {}
    for stat in Path('/proc').glob('[0-9]*/stat'):
        with contextlib.suppress(OSError, ValueError, IndexError):
            fields = stat.read_text().rsplit(')', 1)[1].split()
            tree.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    return tree


def _cmdline(pid: int) -> str:
    try:
        return Path(f'/proc/{pid}/cmdline').read_bytes().replace(b'\0', b' ').decode()
    except OSError:
        return ''


def _cluster_processes(temp_dirs) -> list[int]:
    """The processes of our Ray nodes (their command lines name our temp dirs) and every
    descendant (workers, `stealth train` and its nodes)."""
    roots = [
        int(p.name)
        for p in Path('/proc').glob('[0-9]*')
        if any(d in _cmdline(int(p.name)) for d in temp_dirs)
    ]
    tree, found, stack = _children(), [], list(roots)
    while stack:
        pid = stack.pop()
        if pid != os.getpid() and pid not in found:
            found.append(pid)
            stack += tree.get(pid, [])
    return found


def _stop_cluster(temp_dirs) -> None:
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid in _cluster_processes(temp_dirs):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, sig)
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and _cluster_processes(temp_dirs):
            time.sleep(0.5)


def _trial_workers(temp_dirs) -> list[int]:
    """Ray worker processes running a trial (sweep_pool's actor, while it runs one)."""
    return [
        pid
        for pid in _cluster_processes(temp_dirs)
        if _cmdline(pid).startswith('ray::TrialWorker.run')
    ]


def _sweep(args: list[str], env: dict, log) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, '-m', 'stealth_experiments.sweep', *args],
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )


def _finish(process: subprocess.Popen, log, watch=lambda: None) -> tuple[int | None, str]:
    """(exit code, output) of a sweep, calling ``watch`` while it runs; killed at the timeout."""
    try:
        deadline = time.monotonic() + SWEEP_TIMEOUT
        while process.poll() is None and time.monotonic() < deadline:
            watch()
            time.sleep(0.5)
        code = process.poll()
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
        log.seek(0)
        output = log.read()
    return code, output


ALIVE_NODES = """
import sys, ray
ray.init(address=sys.argv[1], log_to_driver=False, logging_level='ERROR')
print(sum(1 for node in ray.nodes() if node['Alive'] and node['Resources'].get('CPU')))
ray.shutdown()
"""


def _wait_for_nodes(address: str, env: dict, count: int) -> None:
    """Until the cluster has ``count`` live nodes with a CPU: `ray start` returns before a
    node on a loaded host has registered, and a sweep started then runs on the head alone."""
    deadline = time.monotonic() + START_TIMEOUT
    alive = ''
    while time.monotonic() < deadline:
        result = subprocess.run(
            [sys.executable, '-c', ALIVE_NODES, address],
            env=env, capture_output=True, text=True, timeout=START_TIMEOUT,
        )  # fmt: skip
        alive = result.stdout.strip().splitlines()[-1:] or [result.stderr[-500:]]
        if alive == [str(count)]:
            return
        time.sleep(2.0)
    raise AssertionError(f'the cluster never had {count} live nodes (last: {alive})')


def _rows(out: Path) -> list[dict]:
    with open(out / 'results.csv', encoding='utf-8') as stream:
        return list(csv.DictReader(stream))


@pytest.fixture
def cluster():
    """(address, environment, temp dirs): a Ray head and a second node, one CPU each."""
    env = dict(_sourced_environment())
    env.update(RAY_ENVIRONMENT)
    env['RAY_AUTH_MODE'] = 'disabled'  # loopback only, a cluster of this test's own
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    # Short paths: Ray's sockets live under the temp dir (108-byte socket path limit).
    temp_dirs = [
        tempfile.mkdtemp(prefix='swh', dir='/tmp'),
        tempfile.mkdtemp(prefix='sww', dir='/tmp'),
    ]
    port = _free_port()
    address = f'127.0.0.1:{port}'
    common = ['--num-cpus', '1', '--node-ip-address', '127.0.0.1', '--disable-usage-stats']
    try:
        subprocess.run(
            [RAY, 'start', '--head', '--port', str(port), '--include-dashboard', 'false',
             '--temp-dir', temp_dirs[0], *common],
            env=env, check=True, timeout=START_TIMEOUT, capture_output=True,
        )  # fmt: skip
        subprocess.run(
            [RAY, 'start', '--address', address, '--temp-dir', temp_dirs[1], *common],
            env=env, check=True, timeout=START_TIMEOUT, capture_output=True,
        )  # fmt: skip
        _wait_for_nodes(address, env, 2)
        yield address, env, temp_dirs
    finally:
        _stop_cluster(temp_dirs)
        leftover = _cluster_processes(temp_dirs)
        for d in temp_dirs:
            subprocess.run(['rm', '-rf', d], check=False)
        assert not leftover, f'Ray processes still running: {leftover}'


def test_a_sweep_on_two_nodes_survives_a_killed_worker(cluster, tmp_path):
    address, env, temp_dirs = cluster
    sweep_file = tmp_path / 'sweep.yaml'
    sweep_file.write_text(SWEEP)
    out = tmp_path / 'out'
    killed = []

    def kill_a_trial_worker() -> None:
        workers = _trial_workers(temp_dirs)
        if not killed and workers:
            time.sleep(3)  # well into the trial
            if workers[0] in _trial_workers(temp_dirs):
                killed.append(workers[0])
                os.kill(workers[0], signal.SIGKILL)

    with open(tmp_path / 'sweep.log', 'w+') as log:
        process = _sweep([str(sweep_file), '--address', address, '--out', str(out)], env, log)
        code, output = _finish(process, log, kill_a_trial_worker)
    assert code == 0, f'the sweep did not complete (exit {code}):\n{output[-3000:]}'
    assert killed, 'no trial worker was seen to kill'
    assert '1 retried' in output, output[-3000:]
    rows = _rows(out)
    assert len(rows) == 5, rows  # 2 learners x 2 seeds in-process, and the ROS trial
    assert all(row['status'] == 'ok' for row in rows), [row['error'] for row in rows]
    assert sorted(row['mode'] for row in rows) == ['gym'] * 4 + ['ros']
    assert len({row['node'] for row in rows}) == 2, 'the trials did not run on both nodes'
    for row in rows:
        assert float(row['greedy_return']) != 0.0 and row['wall_seconds']
        assert (out / 'policies' / f'{row["trial"]}-seed{row["seed"]}.npz').stat().st_size > 0
    results = (out / 'results.md').read_text()
    assert '## Best configuration per scenario' in results and '| ros |' in results

    # As if the sweep had stopped before this trial ended: --resume runs it alone.
    gone = rows[0]['trial']
    (out / 'trials' / f'{gone}.json').unlink()
    with open(tmp_path / 'resume.log', 'w+') as log:
        resumed = _sweep(['--resume', str(out), '--address', address], env, log)
        code, output = _finish(resumed, log)
    assert code == 0, output[-3000:]
    assert '4 trial(s) already finished' in output and '1 to run' in output, output[-3000:]
    again = _rows(out)
    assert sorted(r['trial'] for r in again) == sorted(r['trial'] for r in rows)
    assert all(r['status'] == 'ok' for r in again)


# --- stopping a sweep, on a local Ray ----------------------------------------------------------

# qlearning's trial ends in seconds; dyna's would take hours: it is the one running when stopped.
STOPPED = """
name: stopped
scenarios: [{scenario: simple-maze, goal: easy}]
learners: [qlearning, dyna]
seeds: [0]
episodes: {qlearning: 20, dyna: 100000}
eval_every: 10
"""


@pytest.fixture
def local_env() -> dict:
    env = dict(_sourced_environment())
    env.update(RAY_ENVIRONMENT)
    env['RAY_AUTH_MODE'] = 'disabled'
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return env


def _output_until(process: subprocess.Popen, log, *expected: str) -> str:
    """The sweep's output once every ``expected`` text is in it (AssertionError if it ended
    or timed out before)."""
    deadline = time.monotonic() + SWEEP_TIMEOUT
    output = ''
    while time.monotonic() < deadline and process.poll() is None:
        log.seek(0)
        output = log.read()
        if all(text in output for text in expected):
            return output
        time.sleep(0.5)
    raise AssertionError(f'the sweep never said {expected} (exit {process.poll()}):\n{output}')


def _status(out: Path) -> dict:
    return json.loads((out / 'status.json').read_text())


def test_ctrl_c_and_sigterm_end_a_sweep_marked_interrupted_and_resume_reruns_the_rest(
    tmp_path, local_env
):
    sweep_file = tmp_path / 'stopped.yaml'
    sweep_file.write_text(STOPPED)
    out = tmp_path / 'out'
    with open(tmp_path / 'sweep.log', 'w+') as log:
        process = _sweep([str(sweep_file), '--out', str(out), '--cpus', '1'], local_env, log)
        try:
            _output_until(process, log, 'trial started: 1/2 done, 1 running')
        finally:
            os.killpg(process.pid, signal.SIGINT)  # Ctrl-C: the terminal signals the group
        code, output = _finish(process, log)
    assert code == 130, output[-3000:]
    line = (
        f'stealth sweep: interrupted by SIGINT: 1 of 2 trials done; `stealth sweep --resume {out}`'
    )
    assert line in output, output[-3000:]
    assert _status(out) == {'status': 'interrupted', 'signal': 'SIGINT', 'trials': 2,
                            'trials_done': 1, 'trials_failed': 0}  # fmt: skip
    assert '**Sweep interrupted by SIGINT: 1 of 2 trials done;' in (out / 'results.md').read_text()
    assert [row['learner'] for row in _rows(out)] == ['qlearning']
    assert not _scratch(process.pid), 'the stopped trial left its scratch directory'

    # --resume runs the stopped trial again; SIGTERM to the sweep alone stops it too.
    with open(tmp_path / 'resume.log', 'w+') as log:
        resumed = _sweep(['--resume', str(out), '--cpus', '1'], local_env, log)
        try:
            _output_until(resumed, log, '1 trial(s) already finished', '1 to run',
                          'trial started: 0/1 done, 1 running')  # fmt: skip
        finally:
            os.kill(resumed.pid, signal.SIGTERM)
        code, output = _finish(resumed, log)
    assert code == 143, output[-3000:]
    assert 'stealth sweep: interrupted by SIGTERM: 1 of 2 trials done' in output, output[-3000:]
    assert _status(out)['signal'] == 'SIGTERM'


def _scratch(sweep_pid: int) -> list[Path]:
    """The scratch directories of a sweep's trials (sweep_stop.scratch_prefix)."""
    return list(Path(tempfile.gettempdir()).glob(f'{RUNS_DIR_PREFIX}{sweep_pid}-*'))


def _marked(sweep_pid: int) -> list[int]:
    """Processes of the sweep's ROS trials (sweep_stop's mark begins with the driver's pid)."""
    prefix = f'{TRIAL_MARK}={sweep_pid}-'.encode()
    found = []
    for entry in Path('/proc').glob('[0-9]*'):
        with contextlib.suppress(OSError):
            if any(v.startswith(prefix) for v in (entry / 'environ').read_bytes().split(b'\0')):
                found.append(int(entry.name))
    return found


def test_an_interrupted_ros_trial_leaves_no_process_and_no_shared_memory(tmp_path, local_env):
    sweep_file = tmp_path / 'ros.yaml'
    sweep_file.write_text(
        'scenarios: [{scenario: simple-maze, goal: easy}]\nlearners: [dyna]\nseeds: [0]\n'
        'episodes: 400\neval_every: 10\nmode: ros\n'
    )
    out = tmp_path / 'out'
    before = shm_segments()
    with open(tmp_path / 'sweep.log', 'w+') as log:
        process = _sweep([str(sweep_file), '--out', str(out), '--cpus', '1'], local_env, log)
        try:
            deadline = time.monotonic() + SWEEP_TIMEOUT
            while len(_marked(process.pid)) < 4 and time.monotonic() < deadline:  # `stealth
                time.sleep(0.5)  # train` and its three nodes
            assert len(_marked(process.pid)) >= 4, 'the ROS trial never started its nodes'
        finally:
            os.killpg(process.pid, signal.SIGINT)
        code, output = _finish(process, log)
    assert code == 130, output[-3000:]
    assert 'interrupted by SIGINT: 0 of 1 trials done' in output, output[-3000:]
    assert _marked(process.pid) == [], 'processes of the ROS trial are still running'
    assert not _scratch(process.pid), 'the stopped trial left its scratch directory'
    left = set(dead_shm_files()) & (shm_segments() - before)
    assert not left, f'Fast DDS files of the stopped trial left in /dev/shm: {sorted(left)}'
    assert _status(out)['status'] == 'interrupted'


def test_a_sweep_whose_every_run_failed_exits_1(tmp_path, local_env):
    sweep_file = tmp_path / 'failing.yaml'
    sweep_file.write_text(  # a ROS trial has no slip: the trial fails at once
        'scenarios: [{scenario: simple-maze, goal: easy}]\nlearners: [dyna]\nseeds: [0]\n'
        'episodes: 10\nmode: ros\nslip: 0.1\n'
    )
    out = tmp_path / 'out'
    with open(tmp_path / 'sweep.log', 'w+') as log:
        process = _sweep([str(sweep_file), '--out', str(out), '--cpus', '1'], local_env, log)
        code, output = _finish(process, log)
    assert code == 1, output[-3000:]
    assert 'stealth sweep: failed: every run failed (1 of 1 trials done);' in output, output
    assert _status(out)['status'] == 'failed'
    assert _rows(out)[0]['error'].startswith('ValueError: a ROS trial has no slip')


def test_a_configuration_whose_runs_fail_is_marked_failed_and_the_rest_finish_exit_3(
    tmp_path, local_env
):
    sweep_file = tmp_path / 'partly.yaml'
    sweep_file.write_text(  # the in-process trials learn with slip; a ROS trial has none: it fails
        'scenarios: [{scenario: simple-maze, goal: easy}]\nlearners: [qlearning]\nseeds: [0, 1]\n'
        'episodes: 20\neval_every: 10\nmode: gym\nslip: 0.1\n'
        'extra:\n  - {mode: ros, scenario: simple-maze, goal: easy, learner: dyna, seed: 0, '
        'episodes: 10}\n'
    )
    out = tmp_path / 'out'
    with open(tmp_path / 'sweep.log', 'w+') as log:
        process = _sweep([str(sweep_file), '--out', str(out), '--cpus', '2'], local_env, log)
        code, output = _finish(process, log)
    assert code == 3, output[-3000:]
    rows = _rows(out)
    failed = [r for r in rows if r['status'] != 'ok']
    assert len(rows) == 3 and [r['mode'] for r in failed] == ['ros'], rows
    reason = 'ValueError: a ROS trial has no slip (the simulator moves as it moves)'
    assert failed[0]['error'] == reason
    assert all(float(r['greedy_return']) != 0.0 for r in rows if r['status'] == 'ok')
    assert (
        f'stealth sweep: 1 of 3 runs failed, the rest finished (exit 3); `stealth sweep --resume '
        f'{out}` runs the failed ones again:\n  {failed[0]["trial"]} seed 0: {reason}\n'
    ) in output, output[-3000:]
    assert f'failed: {reason}' in (out / 'results.md').read_text()
    status = _status(out)
    assert status['status'] == 'complete' and status['trials_failed'] == 1
