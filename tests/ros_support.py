"""Isolation for tests that start ROS nodes: a private DDS domain and no leftovers.

Every test that starts nodes takes a domain id nobody else on the machine holds (an flock'd file
per id), talks only over localhost, and on the way out stops its processes and removes the Fast
DDS shared-memory segments a killed process leaves in /dev/shm.
"""

import contextlib
import fcntl
import functools
import os
import pathlib
import random
import signal
import subprocess
import sys
import time

REPO_ROOT = pathlib.Path(__file__).resolve().parent.parent
VENV = REPO_ROOT / '.venv'
DOMAIN_LOCK_DIR = pathlib.Path('/tmp/stealth_nav_domains')
SHM_DIR = pathlib.Path('/dev/shm')
# Linux keeps ids 0-101 clear of the ephemeral port range; 0 is everyone's default, so skip it.
DOMAIN_IDS = range(1, 102)


@contextlib.contextmanager
def reserved_domain_id():
    """Hold a ROS_DOMAIN_ID that no other test run on this machine holds at the same time."""
    DOMAIN_LOCK_DIR.mkdir(parents=True, exist_ok=True)
    candidates = list(DOMAIN_IDS)
    random.shuffle(candidates)
    for domain_id in candidates:
        lock_file = open(DOMAIN_LOCK_DIR / f'{domain_id}.lock', 'w')  # noqa: SIM115
        try:
            fcntl.flock(lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock_file.close()
            continue
        try:
            yield domain_id
        finally:
            fcntl.flock(lock_file, fcntl.LOCK_UN)
            lock_file.close()
        return
    raise RuntimeError(f'all ROS domain ids {DOMAIN_IDS} are held by other test runs')


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
    env = dict(_sourced_environment())
    env.pop('ROS_LOCALHOST_ONLY', None)  # it overrides the discovery range below
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['PYTHONUNBUFFERED'] = '1'
    return env


def shm_segments() -> set[str]:
    """Fast DDS shared-memory segment and semaphore names currently in /dev/shm."""
    return {p.name for p in SHM_DIR.glob('*fastrtps*')} | {
        p.name for p in SHM_DIR.glob('*fastdds*')
    }


def mapped_shm_names() -> set[str]:
    """Names of /dev/shm files some live process still has mapped (those are not leaks)."""
    names = set()
    for maps in pathlib.Path('/proc').glob('[0-9]*/maps'):
        with contextlib.suppress(OSError):
            for line in maps.read_text().splitlines():
                if '/dev/shm/' in line:
                    names.add(line.rsplit('/dev/shm/', 1)[1].split(' ')[0])
    return names


def clean_shm() -> None:
    """Remove zombie Fast DDS segments (what a SIGKILLed participant leaves behind)."""
    subprocess.run(
        [str(VENV / 'bin' / 'fastdds'), 'shm', 'clean'],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        check=False,
        timeout=60,
    )


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


def leaked_shm_segments(before: set[str]) -> set[str]:
    """Segments created since `before` that no live process maps, after a `fastdds shm clean`."""
    new = shm_segments() - before
    if not new:
        return set()
    clean_shm()
    mapped = mapped_shm_names()
    return {name for name in shm_segments() - before if segment_base(name) not in mapped}


def segment_base(name: str) -> str:
    """The data segment a Fast DDS file belongs to: its lock (`_el`) and mutex (`sem.*_mutex`)
    files are never mapped themselves, but live as long as the segment's owner does."""
    name = name.removeprefix('sem.')
    for suffix in ('_el', '_mutex'):
        name = name.removesuffix(suffix)
    return name


def remove_orphaned_shm(before: set[str]) -> None:
    """Unlink the segments a SIGKILLed participant left: new since `before`, mapped by nobody.

    `fastdds shm clean` removes zombie segments it knows, but not the `fastrtps_port*` segments
    of a killed process, so those that no live process maps are unlinked here.
    """
    for name in leaked_shm_segments(before):
        (SHM_DIR / name).unlink(missing_ok=True)
