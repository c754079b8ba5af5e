"""Fixtures for system tests: private DDS domains, node processes that never outlive a test."""

import pathlib
import sys
import time

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from ros_support import (  # noqa: E402
    NodeProcesses,
    leaked_shm_segments,
    remove_orphaned_shm,
    reserved_domain_id,
    ros_environment,
    shm_segments,
)


@pytest.fixture
def ros_domain(monkeypatch):
    """A ROS_DOMAIN_ID of this test's own, also set in this process's environment."""
    with reserved_domain_id() as domain_id:
        for key, value in ros_environment(domain_id).items():
            if key.startswith('ROS_'):
                monkeypatch.setenv(key, value)
        monkeypatch.delenv('ROS_LOCALHOST_ONLY', raising=False)
        yield domain_id


@pytest.fixture
def ros_context(ros_domain, node_processes):
    """An initialised rclpy context on the test's private domain, shut down afterwards.

    It depends on `node_processes` so that it is torn down first: the leak check there must not
    see this process's own live DDS participant.
    """
    import rclpy

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=ros_domain)
    yield context
    context.try_shutdown()


@pytest.fixture
def node_processes(ros_domain, tmp_path):
    """Start node processes; afterwards none is left running and no shm segment leaked."""
    before = shm_segments()
    processes = NodeProcesses(ros_domain, tmp_path)
    yield processes
    processes.stop_all()
    alive = [p.args for p in processes.processes if p.poll() is None]
    assert not alive, f'processes still running after the test: {alive}'
    if processes.any_killed:
        leaked = _orphans_removed(before)  # a SIGKILLed node cannot clean up; the test does
    else:
        leaked = leaked_shm_segments(before)
    assert not leaked, f'Fast DDS shared memory left in /dev/shm: {sorted(leaked)}'


def _orphans_removed(before: set[str], settle: float = 5.0) -> set[str]:
    """Remove what a SIGKILLed node left, looking again for up to `settle` s; what is still
    left unmapped then.

    One removal is not enough: a segment the killed node shared with a peer is still mapped
    while that peer exits, and unmapped a moment later (seen once in CI: a port segment and
    its mutex left after a clean peer's exit).
    """
    deadline = time.monotonic() + settle
    while True:
        remove_orphaned_shm(before)
        leaked = leaked_shm_segments(before)
        if not leaked or time.monotonic() > deadline:
            return leaked
        time.sleep(0.5)
