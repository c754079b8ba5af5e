"""`stealth doctor`: what an earlier run may have left on this machine, checked and tidied.

- /dev/shm: Fast DDS files of dead processes (a run whose orchestrator or nodes were killed)
  are removed and named (ros_domain.remove_dead_shm; --dry-run only names them);
- ROS domains: which ids runs and tests hold (/tmp/stealth_nav_domains), by which process;
- run processes: nodes of a run whose orchestrator is gone, with the command that stops them;
- the build: whether `make setup` has something to rebuild in the source tree of this install.

One line per check; exit status 1 when something is left for the user to do. No rclpy.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import time

from stealth_bringup.ros_domain import (
    DOMAIN_LOCK_DIR,
    SHM_DIR,
    dead_shm_files,
    remove_dead_shm,
    shm_segments,
)
from stealth_bringup.run_config import NODES

PROG = 'stealth doctor'
SHOWN = 8  # names listed before '... and N more'
_PARAMS_FILE = re.compile(r'--params-file (?P<file>\S+/params/(?P<node>\w+)\.yaml)')


def parser() -> argparse.ArgumentParser:
    result = argparse.ArgumentParser(
        prog=PROG,
        description='Check what earlier runs left on this machine and tidy it: Fast DDS files '
        'of dead processes in /dev/shm (removed, named), the ROS domain ids held by runs and '
        'tests, nodes whose run is gone, and whether the workspace build is current.',
    )
    result.add_argument(
        '--dry-run', action='store_true', help='name what would be removed, remove nothing'
    )
    return result


def _listed(names: Sequence[str]) -> str:
    more = f' ... and {len(names) - SHOWN} more' if len(names) > SHOWN else ''
    return ', '.join(names[:SHOWN]) + more


def check_shm(dry_run: bool) -> tuple[str, bool]:
    """(line, fine) on the Fast DDS files in /dev/shm."""
    if dry_run:
        dead = dead_shm_files()
        if dead:
            return (
                f'/dev/shm: {len(dead)} Fast DDS files of dead processes: {_listed(dead)}',
                False,
            )
    else:
        removed = remove_dead_shm()
        if removed:
            line = f'/dev/shm: removed {len(removed)} Fast DDS files of dead processes: '
            return line + _listed(removed), True
    in_use = len(shm_segments(SHM_DIR))
    return f'/dev/shm: nothing left by dead processes ({in_use} Fast DDS files in use)', True


def _command_line(pid: int) -> str:
    try:
        raw = Path(f'/proc/{pid}/cmdline').read_bytes()
    except OSError:
        return ''
    return raw.replace(b'\0', b' ').decode(errors='replace').strip()


def _age(pid: int) -> float | None:
    """Seconds the process has run."""
    try:
        start_ticks = int(Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[19])
        uptime = float(Path('/proc/uptime').read_text().split()[0])
    except (OSError, IndexError, ValueError):
        return None
    return uptime - start_ticks / os.sysconf('SC_CLK_TCK')


def _short(seconds: float | None) -> str:
    if seconds is None:
        return '?'
    return f'{seconds:.0f} s' if seconds < 120 else f'{seconds / 60:.0f} min'


def lock_holders(lock_dir: Path = DOMAIN_LOCK_DIR) -> dict[int, int]:
    """{domain id: pid} of the domain lock files some process holds (/proc/locks)."""
    inodes = {}
    for path in lock_dir.glob('*.lock'):
        if path.stem.isdigit():
            try:
                inodes[path.stat().st_ino] = int(path.stem)
            except OSError:
                continue
    holders = {}
    try:
        lines = Path('/proc/locks').read_text().splitlines()
    except OSError:
        return holders
    for line in lines:
        fields = line.split()
        if len(fields) < 6 or fields[1] != 'FLOCK':
            continue
        try:
            pid, inode = int(fields[4]), int(fields[5].rsplit(':', 1)[1])
        except (ValueError, IndexError):
            continue
        if inode in inodes:
            holders[inodes[inode]] = pid
    return holders


def check_domains() -> tuple[str, bool]:
    """(line, fine) on the ROS domain ids held by runs and tests."""
    holders = lock_holders()
    if not holders:
        return 'ROS domains: none held by a run or test', True
    held = [
        f'{domain} (pid {pid}, {_short(_age(pid))}: {_command_line(pid)[:60] or "?"})'
        for domain, pid in sorted(holders.items())
    ]
    return f'ROS domains held by runs and tests: {"; ".join(held)}', True


def run_node_of(command_line: str) -> tuple[str, str] | None:
    """(node, run directory) of a process started with a run's params/<node>.yaml, else None;
    a --compose process names two files, and both nodes ('simulator and environment')."""
    matches = [m for m in _PARAMS_FILE.finditer(command_line) if m['node'] in NODES]
    if not matches:
        return None
    run = str(Path(matches[0]['file']).parent.parent)
    return ' and '.join(m['node'] for m in matches), run


def leftover_nodes() -> list[tuple[int, str, str]]:
    """(pid, node, run directory) of run nodes whose orchestrator is gone: started with a run's
    params/<node>.yaml and adopted by init (a run's nodes are its children until it ends)."""
    found = []
    for entry in Path('/proc').glob('[0-9]*'):
        pid = int(entry.name)
        node = run_node_of(_command_line(pid))
        if node is None:
            continue
        try:
            parent = int(Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        if parent == 1:
            found.append((pid, *node))
    return sorted(found)


def check_processes() -> tuple[str, bool]:
    """(line, fine) on nodes left running by a run whose orchestrator is gone."""
    left = leftover_nodes()
    if not left:
        return 'run processes: no node outlived its run', True
    named = [f'{node} (pid {pid}, {run})' for pid, node, run in left]
    pids = ' '.join(str(pid) for pid, _, _ in left)
    return (
        f'run processes: nodes whose run is gone: {_listed(named)}; stop them: kill {pids}',
        False,
    )


def source_tree() -> Path | None:
    """The repository this install was built from (symlink install), if it has a Makefile."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / 'Makefile').is_file() and (parent / 'ros2_ws').is_dir():
            return parent
    return None


def check_build() -> tuple[str, bool]:
    """(line, fine): whether `make setup` would rebuild anything (make -q)."""
    root = source_tree()
    make = shutil.which('make')
    if root is None or make is None:
        return 'build: not checked (no source tree with a Makefile, or no make)', True
    try:
        result = subprocess.run(
            [make, '-q', '-C', str(root), 'setup'],
            capture_output=True,
            timeout=120,
            check=False,
        )
    except (OSError, subprocess.SubprocessError) as error:
        return f'build: not checked ({error})', True
    if result.returncode == 0:
        return f'build: current ({root}/ros2_ws/install)', True
    return f'build: sources changed since the last build; run `make setup` in {root}', False


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    started = time.monotonic()
    fine = True
    for check in (lambda: check_shm(args.dry_run), check_domains, check_processes, check_build):
        line, ok = check()
        fine = fine and ok
        print(f'{PROG}: {line}', flush=True)
    print(f'{PROG}: {"all well" if fine else "see above"} ({time.monotonic() - started:.1f} s)')
    return 0 if fine else 1


if __name__ == '__main__':
    sys.exit(main())
