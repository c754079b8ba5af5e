"""`stealth sweep --address` over a real link: a Ray head on "host" a and a worker node on "host"
b, two network namespaces joined by a veth pair (test_multihost's ``two_hosts``), one CPU each.
The sweep runs on a (beside the head) and joins the cluster by the head's address on the link;
while a trial runs on b, every process of host b is killed (the host dies). Checked: the sweep
finishes with every row, trials ran on both nodes before, the lost trial was retried on the
head (its record says attempt 2, its row the head's node) and the output names it. Everything
started lives in the two namespaces and goes with them; Ray's temp dirs are removed.
"""

import contextlib
import csv
import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import time

from ros_support import _sourced_environment
from stealth_experiments.sweep_engine import RAY_ENVIRONMENT
from test_multihost import two_hosts  # noqa: F401 - the fixture
from test_sweep import _cmdline, _finish, _free_port

RAY = str(Path(sys.executable).parent / 'ray')
START_TIMEOUT = 240.0  # s: a Ray node on two loaded cores
# Six trials of seconds each: the one running on b is killed 1 s into it.
SWEEP = """
name: two-hosts
scenarios: [{scenario: simple-maze, goal: easy}]
learners: [qlearning]
seeds: [0, 1, 2, 3, 4, 5]
episodes: 1000
eval_every: 10
mode: gym
"""
NODES = """
import json, sys, ray
ray.init(address=sys.argv[1], log_to_driver=False, logging_level='ERROR')
print(json.dumps({n['NodeManagerAddress']: n['NodeID'] for n in ray.nodes()
                  if n['Alive'] and n['Resources'].get('CPU')}))
ray.shutdown()
"""


def _netns_pids(netns: str) -> list[int]:
    found = subprocess.run(['ip', 'netns', 'pids', netns], capture_output=True, text=True)
    return [int(pid) for pid in found.stdout.split()]


def _nodes_done(out: Path) -> set[str]:
    """The Ray nodes of the trials recorded so far."""
    found = set()
    for path in (out / 'trials').glob('*.json'):
        with contextlib.suppress(OSError, ValueError):  # being written
            found |= {r['node'] for r in json.loads(path.read_text())['records']}
    return found


def _ray_start(host, env: dict, *args: str) -> None:
    """`ray start ARGS` on the host; AssertionError with what it said when it fails."""
    result = subprocess.run(
        [*host.exec, RAY, 'start', *args],
        env=env, capture_output=True, text=True, timeout=START_TIMEOUT,
    )  # fmt: skip
    assert result.returncode == 0, f'ray start {" ".join(args)}:\n{result.stderr[-3000:]}'


def _nodes(host, address: str, env: dict, count: int) -> dict[str, str]:
    """{node IP: node id} once the cluster has ``count`` live nodes with a CPU, asked from
    ``host`` (`ray start` returns before a node on a loaded host has registered)."""
    deadline = time.monotonic() + START_TIMEOUT
    found: dict | str = {}
    while time.monotonic() < deadline:
        result = subprocess.run(
            [*host.exec, sys.executable, '-c', NODES, address],
            env=env, capture_output=True, text=True, timeout=START_TIMEOUT,
        )  # fmt: skip
        lines = result.stdout.strip().splitlines()
        found = json.loads(lines[-1]) if lines else result.stderr[-500:]
        if isinstance(found, dict) and len(found) == count:
            return found
        time.sleep(2.0)
    raise AssertionError(f'the cluster never had {count} live nodes (last: {found})')


def test_a_sweep_over_a_link_finishes_when_its_worker_host_dies(two_hosts, tmp_path):  # noqa: F811
    a, b = two_hosts['a'], two_hosts['b']
    head_ip, worker_ip = a.address.split('/')[0], b.address.split('/')[0]
    env = dict(_sourced_environment())
    env.update(RAY_ENVIRONMENT)
    env['RAY_AUTH_MODE'] = 'disabled'  # a cluster of this test's own, inside its namespaces
    # Short paths: Ray's sockets live under the temp dir (108-byte socket path limit).
    temp_dirs = [tempfile.mkdtemp(prefix=p, dir='/tmp') for p in ('swa', 'swb')]
    port = _free_port()
    address = f'{head_ip}:{port}'
    common = ['--num-cpus', '1', '--disable-usage-stats']
    try:
        _ray_start(a, env, '--head', '--port', str(port), '--node-ip-address', head_ip,
                   '--include-dashboard', 'false', '--temp-dir', temp_dirs[0],
                   *common)  # fmt: skip
        _ray_start(b, env, '--address', address, '--node-ip-address', worker_ip,
                   '--temp-dir', temp_dirs[1], *common)  # fmt: skip
        nodes = _nodes(a, address, env, 2)
        assert set(nodes) == {head_ip, worker_ip}, nodes
        sweep_file = tmp_path / 'sweep.yaml'
        sweep_file.write_text(SWEEP)
        out = tmp_path / 'out'
        killed: list[int] = []
        running_on_b: list[int] = []  # the worker process of the trial killed

        def kill_host_b() -> None:
            """Once a trial has finished on b and the next has run there for 1 s, SIGKILL every
            process of host b."""
            if killed or nodes[worker_ip] not in _nodes_done(out):
                return
            running = [p for p in _netns_pids(b.netns) if _cmdline(p).startswith(
                'ray::TrialWorker.run')]  # fmt: skip
            if running:
                running_on_b.append(running[0])
                time.sleep(1.0)
                for pid in _netns_pids(b.netns):
                    with contextlib.suppress(ProcessLookupError):
                        os.kill(pid, signal.SIGKILL)
                        killed.append(pid)

        with open(tmp_path / 'sweep.log', 'w+') as log:
            process = subprocess.Popen(
                [*a.exec, sys.executable, '-m', 'stealth_experiments.sweep', str(sweep_file),
                 '--address', address, '--out', str(out), '--no-plots'],
                env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
            )  # fmt: skip
            code, output = _finish(process, log, kill_host_b)
        assert killed, f'no trial was seen running on host b:\n{output[-3000:]}'
        assert code == 0, f'the sweep did not complete (exit {code}):\n{output[-3000:]}'
        assert f'engine: the Ray cluster at {address} is up' in output, output[-3000:]
        lost = f' lost its worker (pid {running_on_b[0]} on node {nodes[worker_ip][:8]} at '
        assert f'{lost}{worker_ip}: ' in output, output[-3000:]
        assert '), retried from the start (attempt 2 of 3): ' in output, output[-3000:]
        retried_line = next(
            line for line in output.splitlines() if 'retried after a lost worker: ' in line
        )
        retried = retried_line.split('retried after a lost worker: ', 1)[1].split(' (')[0]
        assert f'sweep: trial {retried}{lost}' in output, output[-3000:]

        with open(out / 'results.csv', encoding='utf-8') as stream:
            rows = list(csv.DictReader(stream))
        assert len(rows) == 6 and all(r['status'] == 'ok' for r in rows), rows
        assert {r['node'] for r in rows} == {nodes[head_ip][:12], nodes[worker_ip][:12]}, (
            'the trials did not run on both hosts'
        )
        row = next(r for r in rows if r['trial'] == retried)
        assert row['node'] == nodes[head_ip][:12], 'the retried trial did not run on the head'
        record = json.loads((out / 'trials' / f'{retried}.json').read_text())['records'][0]
        assert record['attempt'] == 2 and record['status'] == 'ok'
        assert json.loads((out / 'status.json').read_text())['status'] == 'complete'
    finally:
        for host in (a, b):  # the namespaces go with the fixture; their processes first
            for pid in _netns_pids(host.netns):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        for directory in temp_dirs:
            shutil.rmtree(directory, ignore_errors=True)
