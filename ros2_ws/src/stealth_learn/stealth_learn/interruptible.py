"""Ctrl-C during the network's JAX work: ``interruptible(work)`` runs it where the main thread
can still react.

Python runs a signal's handler in the main thread, between bytecodes. An XLA compile or run is
one call into C++: on the main thread, SIGINT and SIGTERM wait until it returns (a plan of 1e8
Bellman backups never did, issue 40). So on the main thread the work runs in a daemon thread
while the main thread waits for it in short timed waits, returning to Python each time: the
handler runs within ``POLL`` s of the signal, whichever thread the kernel delivered it to, and
its exception (KeyboardInterrupt, ``sweep_stop.Interrupted``) comes out of here. The abandoned
work goes on in its daemon thread until it ends (the header's iteration bound,
``policy_file.MAX_ITERATIONS``, keeps one call short: under a second on the largest generated
building, a compile 1-2 s). At exit the process waits for it (``_finish_abandoned``): Python
3.11 aborts the process ("FATAL: exception not rethrown") when a daemon thread comes back from
C++ while the interpreter finalises; a second Ctrl-C then exits at once (130). Off the main
thread (a ROS executor's, a worker's) the work simply runs: signals are not that thread's.
"""

from __future__ import annotations

import atexit
from collections.abc import Callable
import os
import sys
import threading
from typing import TypeVar

POLL = 0.05  # s between the main thread's looks at pending signals while the work runs
SAY_AFTER = 1.0  # s of waiting at exit before saying what the process waits for
T = TypeVar('T')
_abandoned: list[threading.Thread] = []  # work whose waiting main thread was interrupted


def interruptible(work: Callable[[], T]) -> T:
    """``work()``'s result (or its exception); on the main thread a signal's handler runs
    while it is under way (module docstring)."""
    if threading.current_thread() is not threading.main_thread():
        return work()
    outcome: dict = {}
    done = threading.Event()

    def run() -> None:
        try:
            outcome['value'] = work()
        except BaseException as error:  # handed to the waiting thread, raised there
            outcome['error'] = error
        finally:
            done.set()

    thread = threading.Thread(target=run, name='stealth-learn-jax', daemon=True)
    thread.start()
    try:
        while not done.wait(POLL):
            pass
    except BaseException:
        if not _abandoned:  # registered after JAX's own exit handlers: runs before them
            atexit.register(_finish_abandoned)
        _abandoned.append(thread)
        raise
    if 'error' in outcome:
        raise outcome['error']
    return outcome['value']


def _finish_abandoned() -> None:
    """At exit: wait for interrupted work to end (module docstring); Ctrl-C again exits now."""
    waited = 0.0
    try:
        for thread in _abandoned:
            while thread.is_alive():
                thread.join(POLL)
                waited += POLL
                if waited >= SAY_AFTER > waited - POLL:
                    print(
                        "waiting for the network's running computation to end (Ctrl-C again "
                        'to exit at once)',
                        file=sys.stderr,
                        flush=True,
                    )
    except KeyboardInterrupt:
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        os._exit(130)
