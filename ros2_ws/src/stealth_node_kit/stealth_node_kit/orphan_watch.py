"""The last resort against a node outliving its killed orchestrator.

A node started by the orchestrator is asked to die with it (PR_SET_PDEATHSIG: SIGTERM) and then
stops in order, with its own watchdog over a stop that hangs (``running.STOP_LIMIT``, the
recorder's). Neither covers a main thread stuck before the stop signal's Python handler runs
(it runs only between bytecodes), nor an exit that hangs after that watchdog is cancelled
(interpreter teardown, DDS's destructors): such a process lives on with no one left to kill it.
A CI run found a recorder so, a minute after the kill, its place never caught.

The watch is a daemon thread that looks at the parent every POLL s. Once the parent is gone it
sets a timer: ORPHAN_LIMIT s later SIGALRM writes every thread's stack to stderr (the node's log;
faulthandler, no Python code needed) and then ends the process (SIGALRM's default action, the
kernel's doing: it works with the main thread stuck or the interpreter torn down). A process
not asked to die with its parent (a user's ``nohup stealth bag record``) is never watched.

``die_with_parent`` is how a starter asks (the orchestrator's supervisor, ``stealth run``).
"""

from __future__ import annotations

from collections.abc import Callable
import contextlib
import ctypes
import faulthandler
import os
import signal
import sys
import threading
import time

ORPHAN_LIMIT = 40.0  # s from finding the parent gone to the end (after every stop watchdog)
POLL = 0.5  # s between looks at the parent
_PR_SET_PDEATHSIG, _PR_GET_PDEATHSIG = 1, 2


def _prctl():
    """libc's prctl, or None where there is none (not Linux)."""
    try:
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


def die_with_parent(first: Callable[[], None] | None = None) -> Callable[[], None]:
    """A preexec function for ``subprocess.Popen``: the child runs ``first`` (if given), then
    asks for SIGTERM when this process dies, and ends at once if it died already (between the
    fork and the request). Prepared here, in the parent, so that the child makes only system
    calls between fork and exec."""
    prctl = _prctl()
    parent = os.getpid()

    def child() -> None:
        if first is not None:
            first()
        if prctl is not None:
            prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
            if os.getppid() != parent:
                os._exit(1)

    return child


def parent_death_signal() -> int:
    """The signal this process gets when its parent dies (PR_GET_PDEATHSIG); 0 for none or
    where prctl is missing."""
    prctl = _prctl()
    if prctl is None:
        return 0
    value = ctypes.c_int(0)
    if prctl(_PR_GET_PDEATHSIG, ctypes.byref(value), 0, 0, 0) != 0:
        return 0
    return value.value


def watch_for_orphaning(
    limit: float = ORPHAN_LIMIT, poll: float = POLL
) -> threading.Thread | None:
    """Start the watch (see the module's docstring) if this process was asked to die with its
    parent; the thread, or None when not."""
    if not parent_death_signal():
        return None
    parent = os.getppid()
    thread = threading.Thread(
        target=_watch, args=(parent, limit, poll), name='orphan-watch', daemon=True
    )
    thread.start()
    return thread


def _watch(parent: int, limit: float, poll: float) -> None:
    while os.getppid() == parent:
        time.sleep(poll)
    with contextlib.suppress(ValueError, OSError, AttributeError, RuntimeError):
        # stderr gone or not a file: the end comes all the same, without the stacks
        faulthandler.register(signal.SIGALRM, file=sys.stderr, all_threads=True, chain=True)
    signal.setitimer(signal.ITIMER_REAL, limit)
