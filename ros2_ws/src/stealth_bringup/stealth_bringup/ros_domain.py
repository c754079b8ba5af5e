"""A private DDS domain for a run, and the Fast DDS shared memory a killed node leaves behind.

A run takes a ROS_DOMAIN_ID nobody else on the machine holds: one flock'd file per id in
/tmp/stealth_nav_domains (the same lock files the system tests take, so runs and tests never hear
each other), held for the whole run. Its nodes talk over localhost only
(ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; ROS_LOCALHOST_ONLY, which overrides it, is unset), or
over the subnet when nodes on other hosts join it (`--discovery subnet`).

A node that exits normally removes its Fast DDS segments from /dev/shm; a SIGKILLed one cannot.
`remove_orphaned_shm` removes, after `fastdds shm clean`, the segments that appeared since a
snapshot and that no live process maps; `remove_dead_shm` (at the start of every run, and
`stealth doctor`) those of any dead process, from an earlier run whose orchestrator was killed
say. No rclpy here.
"""

from __future__ import annotations

from collections.abc import Iterator
import contextlib
import fcntl
import os
from pathlib import Path
import random
import shutil
import subprocess
import sys
import time

DOMAIN_LOCK_DIR = Path('/tmp/stealth_nav_domains')
# Linux keeps ids 0-101 clear of the ephemeral port range; 0 is everyone's default, so skip it.
DOMAIN_IDS = range(1, 102)
SHM_DIR = Path('/dev/shm')
SHM_CONFIRM = 1.0  # s between the two looks that find a Fast DDS file unmapped before removal
# --discovery: ROS_AUTOMATIC_DISCOVERY_RANGE of the run's participants.
DISCOVERY_RANGES = {'localhost': 'LOCALHOST', 'subnet': 'SUBNET'}


class DomainError(RuntimeError):
    """No free domain id."""


@contextlib.contextmanager
def reserved_domain_id(lock_dir: Path = DOMAIN_LOCK_DIR) -> Iterator[int]:
    """Hold a ROS_DOMAIN_ID that no other run or test on this machine holds meanwhile."""
    lock_dir.mkdir(parents=True, exist_ok=True)
    candidates = list(DOMAIN_IDS)
    random.shuffle(candidates)
    for domain_id in candidates:
        lock_file = open(lock_dir / f'{domain_id}.lock', 'w')  # noqa: SIM115 - held while yielded
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
    raise DomainError(f'every ROS domain id {DOMAIN_IDS.start}-{DOMAIN_IDS.stop - 1} is in use')


def private_environment(
    domain_id: int, base: dict[str, str] | None = None, discovery: str = 'localhost'
) -> dict[str, str]:
    """The environment of a node process in the private domain (localhost discovery unless
    `discovery` is 'subnet')."""
    env = dict(os.environ if base is None else base)
    env.pop('ROS_LOCALHOST_ONLY', None)  # it would override the discovery range
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = DISCOVERY_RANGES[discovery]
    env['PYTHONUNBUFFERED'] = '1'  # log lines reach the log file as they are written
    env['RCUTILS_LOGGING_BUFFERED_STREAM'] = '0'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    return env


def shm_segments(shm_dir: Path = SHM_DIR) -> set[str]:
    """Fast DDS shared-memory segment and semaphore names currently in /dev/shm."""
    return {p.name for p in shm_dir.glob('*fastrtps*')} | {
        p.name for p in shm_dir.glob('*fastdds*')
    }


def mapped_shm_names() -> set[str]:
    """Names of /dev/shm files some live process has mapped (those are in use, not leaks)."""
    names = set()
    for maps in Path('/proc').glob('[0-9]*/maps'):
        with contextlib.suppress(OSError):
            for line in maps.read_text().splitlines():
                if '/dev/shm/' in line:
                    names.add(line.rsplit('/dev/shm/', 1)[1].split(' ')[0])
    return names


def segment_base(name: str) -> str:
    """The data segment a Fast DDS file belongs to: its lock (`_el`) and mutex (`sem.*_mutex`)
    files are never mapped themselves, but belong to a live owner as long as the segment does."""
    name = name.removeprefix('sem.')
    for suffix in ('_el', '_mutex'):
        name = name.removesuffix(suffix)
    return name


def fastdds_tool() -> str | None:
    """The `fastdds` command of this installation (the venv's), if there is one."""
    beside_python = Path(sys.executable).parent / 'fastdds'
    if beside_python.exists():
        return str(beside_python)
    return shutil.which('fastdds')


def clean_shm() -> None:
    """`fastdds shm clean`: remove the zombie segments Fast DDS itself recognises."""
    tool = fastdds_tool()
    if tool is None:
        return
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        subprocess.run(
            [tool, 'shm', 'clean'],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            check=False,
            timeout=60,
        )


def _unmapped_shm(shm_dir: Path) -> set[str]:
    """Our Fast DDS files in /dev/shm that no live process maps (nor, for a lock or mutex file,
    the segment it belongs to)."""
    mapped = mapped_shm_names()
    unmapped = set()
    for name in shm_segments(shm_dir):
        if segment_base(name) in mapped:
            continue
        with contextlib.suppress(OSError):
            if (shm_dir / name).stat().st_uid == os.getuid():
                unmapped.add(name)
    return unmapped


def dead_shm_files(shm_dir: Path = SHM_DIR, confirm: float = SHM_CONFIRM) -> list[str]:
    """Fast DDS files in /dev/shm whose owners are all dead: no live process maps them, now and
    again `confirm` s later (a participant that is starting creates its segment a moment before
    it maps it)."""
    first = _unmapped_shm(shm_dir)
    if not first:
        return []
    time.sleep(confirm)
    return sorted(first & _unmapped_shm(shm_dir))


def remove_dead_shm(shm_dir: Path = SHM_DIR, confirm: float = SHM_CONFIRM) -> list[str]:
    """Remove what dead_shm_files finds (`fastdds shm clean` first, as Fast DDS itself would,
    then whatever is left of it); the names removed."""
    dead = dead_shm_files(shm_dir, confirm)
    if not dead:
        return []
    clean_shm()
    for name in sorted(set(dead) & _unmapped_shm(shm_dir)):
        with contextlib.suppress(OSError):
            (shm_dir / name).unlink()
    left = shm_segments(shm_dir)
    return [name for name in dead if name not in left]


def remove_orphaned_shm(before: set[str], shm_dir: Path = SHM_DIR) -> list[str]:
    """Remove the Fast DDS segments created since `before` that no live process maps.

    `fastdds shm clean` does not remove the `fastrtps_port*` segments of a killed process, so
    those nobody maps any more are unlinked here. Returns the names removed.
    """
    if not shm_segments(shm_dir) - before:
        return []
    clean_shm()
    mapped = mapped_shm_names()
    orphans = {n for n in shm_segments(shm_dir) - before if segment_base(n) not in mapped}
    for name in orphans:
        with contextlib.suppress(OSError):
            (shm_dir / name).unlink()
    return sorted(orphans)
