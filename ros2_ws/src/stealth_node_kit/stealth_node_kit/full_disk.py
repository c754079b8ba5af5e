"""A full disk, said in one line, by every writer of a run (the nodes and the orchestrator):
which file could not be written and how much space is left on which file system. No rclpy.

A node that cannot write its file because the disk is full stops with EXIT_DISK_FULL after
one fatal line (disk_full_message); the orchestrator does not restart it (the disk would be
as full for the new process) but stops the run with that line, and exits with the same code.
"""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path
import shutil

EXIT_DISK_FULL = 4  # a node or a run that stopped because its disk is full
FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)
PREFIX = 'the disk is full: '  # how every disk-full line begins (the orchestrator finds it)


class DiskFullError(OSError):
    """A write that failed because the disk (or the user's quota) is full; str() is the one
    line to show (disk_full_message)."""

    def __init__(self, path: str | os.PathLike, shown: str | None = None):
        self.path = Path(path)
        self.line = disk_full_message(path, shown)
        super().__init__(errno.ENOSPC, self.line)

    def __str__(self) -> str:
        return self.line


def is_disk_full(error: BaseException) -> bool:
    """Whether `error` is a write refused for want of space (ENOSPC, EDQUOT)."""
    return isinstance(error, DiskFullError) or (
        isinstance(error, OSError) and error.errno in FULL_ERRNOS
    )


def mount_point(path: str | os.PathLike) -> Path:
    """The mount point of the file system holding `path` (or its nearest existing parent)."""
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    while not os.path.ismount(path) and path != path.parent:
        path = path.parent
    return path


def size_text(size: float) -> str:
    """A byte count as people read it: '512 bytes', '12 KiB', '3.4 MiB', '1.2 GiB'."""
    if size < 1024:
        return f'{int(size)} bytes'
    for unit in ('KiB', 'MiB', 'GiB', 'TiB'):
        size /= 1024
        if size < 1024 or unit == 'TiB':
            return f'{size:.0f} {unit}' if size >= 10 else f'{size:.1f} {unit}'
    raise AssertionError('unreachable')


def free_space(path: str | os.PathLike) -> str:
    """'12 KiB free on /tmp/full': what is left on the file system of `path`."""
    where = mount_point(path)
    try:
        free = shutil.disk_usage(where).free
    except OSError:
        return f'free space on {where} unknown'
    return f'{size_text(free)} free on {where}'


def disk_full_message(path: str | os.PathLike, shown: str | None = None) -> str:
    """'the disk is full: could not write runs/x/episodes.csv (12 KiB free on /tmp/full)';
    `shown` is how to name the file (default: as given)."""
    return f'{PREFIX}could not write {shown or path} ({free_space(path)})'


@contextlib.contextmanager
def checked_write(path: str | os.PathLike, shown: str | None = None):
    """An OSError of a full disk inside the block becomes DiskFullError naming `path`; any
    other error passes unchanged."""
    try:
        yield
    except DiskFullError:
        raise
    except OSError as error:
        if is_disk_full(error):
            raise DiskFullError(path, shown) from error
        raise


def remove_quietly(path: str | os.PathLike) -> None:
    """Remove a temporary file that a failed write left (no error if it is not there)."""
    with contextlib.suppress(OSError):
        os.unlink(path)
