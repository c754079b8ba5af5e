"""Isolation for tests that start ROS nodes: a private DDS domain and no leftovers.

Every test that starts nodes takes a domain id nobody else on the machine holds (an flock'd file
per id), talks only over localhost, and on the way out stops its processes and removes the Fast
DDS shared-memory segments a killed process leaves in /dev/shm.
"""

import contextlib
import functools
import os
import pathlib
import signal
import subprocess
import sys
import time

from stealth_bringup.ros_domain import (  # the runs' implementation: one lock space for both
    SHM_DIR,  # noqa: F401 - re-exported for the tests
    clean_shm,
    mapped_shm_names,
    private_environment,
    remove_orphaned_shm,  # noqa: F401 - re-exported for the tests
    reserved_domain_id,  # noqa: F401 - re-exported for the tests
    segment_base,
    shm_segments,
)

REPO_ROOT = pathlib.Path(__file__).resolve().parent.parent
VENV = REPO_ROOT / '.venv'
NODE_MAJOR_MIN = 18


def node_tool(tool: pathlib.Path, module: str) -> str:
    """The node executable for a pinned JS tool of tools/ (with `module` installed); fails,
    never skips, with what to install."""
    import shutil

    import pytest

    hint = (
        'install Node.js 18 or newer with npm (Debian: sudo apt-get install nodejs npm), then '
        f'`npm ci --prefix {tool.relative_to(REPO_ROOT)}` (make test-system does)'
    )
    node = shutil.which('node')
    if node is None or shutil.which('npm') is None:
        pytest.fail(f'{tool.name} needs node and npm: {hint}')
    version = subprocess.run([node, '--version'], capture_output=True, text=True).stdout
    if int(version.strip().lstrip('v').split('.')[0]) < NODE_MAJOR_MIN:
        pytest.fail(f'node {version.strip()} is too old for {tool.name}: {hint}')
    if not (tool / 'node_modules' / module).is_dir():
        pytest.fail(f'{tool}/node_modules is missing: {hint}')
    return node


@functools.cache
def _sourced_environment() -> tuple[tuple[str, str], ...]:
    """The environment a user's shell has after `source scripts/ros_env.sh` (venv + install)."""
    output = subprocess.run(
        ['bash', '-c', f'source {REPO_ROOT}/scripts/ros_env.sh && env -0'],
        capture_output=True,
        check=True,
        env={key: value for key, value in os.environ.items() if not key.startswith('ROS_')},
    ).stdout
    pairs = (entry.split('=', 1) for entry in output.decode().split('\0') if '=' in entry)
    return tuple((key, value) for key, value in pairs)


def ros_environment(domain_id: int) -> dict[str, str]:
    """The environment of a node process: the venv and install space, a private domain."""
    return private_environment(domain_id, base=dict(_sourced_environment()))


class NodeProcesses:
    """Starts node processes in one private domain and guarantees they are gone afterwards."""

    def __init__(self, domain_id: int, log_dir: pathlib.Path):
        self.domain_id = domain_id
        self.env = ros_environment(domain_id)
        self.log_dir = log_dir
        self.processes: list[subprocess.Popen] = []

    @property
    def any_killed(self) -> bool:
        """True when some process ended by SIGKILL (it cannot have cleaned up its segments)."""
        return any(p.returncode == -signal.SIGKILL for p in self.processes)

    def start(self, args: list[str], name: str, **popen_kwargs) -> subprocess.Popen:
        """Start one process (its own process group) with output captured to a log file."""
        log = open(self.log_dir / f'{name}.log', 'w')  # noqa: SIM115 - closed in stop_all
        process = subprocess.Popen(
            args,
            env={**self.env, **popen_kwargs.pop('extra_env', {})},
            stdout=popen_kwargs.pop('stdout', log),
            stderr=popen_kwargs.pop('stderr', subprocess.STDOUT),
            start_new_session=True,
            **popen_kwargs,
        )
        process.log_file = log
        process.log_path = self.log_dir / f'{name}.log'
        self.processes.append(process)
        return process

    def start_python(self, script: str, name: str, *args: str, **popen_kwargs):
        """Start `python -c script` in the ROS environment."""
        return self.start([sys.executable, '-c', script, *args], name, **popen_kwargs)

    def stop_all(self, timeout: float = 10.0) -> None:
        """SIGINT every process group, then SIGKILL what is still alive after the timeout."""
        for process in self.processes:
            if process.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(process.pid, signal.SIGINT)
        deadline = time.monotonic() + timeout
        for process in self.processes:
            remaining = max(0.1, deadline - time.monotonic())
            try:
                process.wait(remaining)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(process.pid, signal.SIGKILL)
                process.wait(5)
            # A clean exit of the leader is not enough: children in the group must go too.
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(process.pid, signal.SIGKILL)
            process.log_file.close()


def wait_for_output(process, text: str, timeout: float = 30.0) -> str:
    """What a process NodeProcesses started has printed, once that holds `text`;
    AssertionError, with its output, if it exits first or takes longer than `timeout` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        output = process.log_path.read_text()
        if text in output:
            return output
        if process.poll() is not None:
            raise AssertionError(f'{process.args} exited early:\n{output}')
        time.sleep(0.05)
    raise AssertionError(f'no {text!r} within {timeout} s:\n{process.log_path.read_text()}')


def leaked_shm_segments(before: set[str]) -> set[str]:
    """Segments created since `before` that no live process maps, after a `fastdds shm clean`."""
    if not shm_segments() - before:
        return set()
    clean_shm()
    mapped = mapped_shm_names()
    return {name for name in shm_segments() - before if segment_base(name) not in mapped}


class SpinningNode:
    """A test's own node with its own executor, spun only when the test waits for something."""

    def __init__(self, name: str, context):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.node = rclpy.create_node(name, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)

    def close(self) -> None:
        self.executor.remove_node(self.node)
        self.executor.shutdown()
        self.node.destroy_node()

    def spin_until(self, predicate, timeout: float) -> bool:
        """Spin until ``predicate()`` holds or ``timeout`` s pass; the predicate's last value."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not predicate():
            self.executor.spin_once(timeout_sec=0.02)
        return predicate()

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def handshake(self, calls: dict, timeout: float, resend: float = 1.0, alive=lambda: True):
        """{name: answer} of `calls` ({name: (client, request)}, each request one that changes
        nothing), all sent at once and each again every `resend` s until answered; a name with
        no answer within `timeout` s, or once ``alive()`` is false, is left out.
        ``service_is_ready`` only says this side has matched the server: Fast DDS's server
        waits 100 ms for its side to match this client's answer reader and otherwise drops the
        answer ('failed to send response (timeout)' in its log). An answer proves both sides
        matched, and matches last."""
        futures, sent = {}, {}
        deadline = time.monotonic() + timeout

        def answered(name) -> bool:
            return name in futures and futures[name].done()

        while time.monotonic() < deadline and alive():
            if all(answered(name) for name in calls):
                break
            for name, (client, request) in calls.items():
                if answered(name) or not client.service_is_ready():
                    continue
                if time.monotonic() - sent.get(name, -resend) < resend:
                    continue
                if name in futures:
                    client.remove_pending_request(futures[name])
                futures[name], sent[name] = client.call_async(request), time.monotonic()
            self.executor.spin_once(timeout_sec=0.02)
        for name, future in futures.items():
            if not future.done():
                calls[name][0].remove_pending_request(future)
        return {name: f.result() for name, f in futures.items() if f.done()}
