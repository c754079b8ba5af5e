"""`run <package> <executable>`: find a node's executable the ament way and supervise it.

Executables live in <prefix>/lib/<package>/ of the package's ament prefix (what setup.cfg's
script_dir gives ament_python packages), exactly where `ros2 run` looks. The child runs in this
process group, so Ctrl-C reaches it directly as with `ros2 run`; SIGTERM sent to this process
is passed on, and the child is told to die (PR_SET_PDEATHSIG) if this process is killed, so
nothing outlives the command. A failing child gets one line saying which and why: its exit
status and the last line it wrote to stderr.
"""

from __future__ import annotations

from collections.abc import Sequence
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from ament_index_python.packages import (
    PackageNotFoundError,
    get_package_prefix,
    get_packages_with_prefixes,
)
from stealth_node_kit.orphan_watch import die_with_parent


class ExecutableNotFoundError(LookupError):
    """An unknown package or executable; the message lists what exists."""


def executables_of(package: str) -> list[Path]:
    """The executable files in the package's lib/<package>/ directory, sorted by name."""
    directory = Path(get_package_prefix(package)) / 'lib' / package
    if not directory.is_dir():
        return []
    return sorted(p for p in directory.iterdir() if p.is_file() and os.access(p, os.X_OK))


def packages_with_executables() -> list[str]:
    """Every package on AMENT_PREFIX_PATH that has at least one executable."""
    return sorted(name for name in get_packages_with_prefixes() if executables_of(name))


def find_executable(package: str, executable: str) -> Path:
    """The path of `executable` of `package`; ExecutableNotFoundError lists the alternatives."""
    try:
        candidates = executables_of(package)
    except PackageNotFoundError:
        known = ', '.join(packages_with_executables()) or 'none'
        raise ExecutableNotFoundError(
            f"package '{package}' not found (packages with executables: {known})"
        ) from None
    for path in candidates:
        if path.name == executable:
            return path
    names = ', '.join(p.name for p in candidates) or 'none'
    raise ExecutableNotFoundError(
        f"package '{package}' has no executable '{executable}' (it has: {names})"
    )


def _relay_stderr(source, sink, last_line: list[str]) -> None:
    """Copy the child's stderr through, remembering its last non-empty line."""
    for raw in iter(source.readline, b''):
        sink.write(raw)
        sink.flush()
        text = raw.decode(errors='replace').strip()
        if text:
            last_line[0] = text


def failure_line(label: str, returncode: int, seconds: float, last_stderr: str) -> str | None:
    """The one line telling why a child failed, None if it exited cleanly."""
    if returncode == 0:
        return None
    if returncode < 0:
        what = f'was killed by {signal.Signals(-returncode).name}'
    else:
        what = f'exited with code {returncode}'
    why = f': {last_stderr}' if last_stderr else ''
    return f'{label} {what} after {seconds:.1f} s{why}'


def run_supervised(command: Sequence[str], label: str) -> int:
    """Run a child to completion; on failure print one line; return its exit status."""
    started = time.monotonic()
    process = subprocess.Popen(list(command), stderr=subprocess.PIPE, preexec_fn=die_with_parent())
    last_line = ['']
    relay = threading.Thread(
        target=_relay_stderr, args=(process.stderr, sys.stderr.buffer, last_line), daemon=True
    )
    relay.start()

    def forward(signum, _frame):
        if process.poll() is None:
            process.send_signal(signum)

    previous = {
        signal.SIGTERM: signal.signal(signal.SIGTERM, forward),
        # Ctrl-C reaches the child through the shared process group; do not send it twice.
        signal.SIGINT: signal.signal(signal.SIGINT, lambda *_: None),
    }
    try:
        returncode = process.wait()
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    relay.join(timeout=2.0)
    line = failure_line(label, returncode, time.monotonic() - started, last_line[0])
    if line and returncode not in (-signal.SIGINT, -signal.SIGTERM):
        print(f'stealth run: {line}', file=sys.stderr)
    return returncode if returncode >= 0 else 128 - returncode
