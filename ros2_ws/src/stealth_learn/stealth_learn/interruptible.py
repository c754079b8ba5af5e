"""Ctrl-C during the network's JAX work: ``interruptible(work)`` runs it where the main thread
can still react, and an interrupted process exits without waiting for it.

Python runs a signal's handler in the main thread, between bytecodes. An XLA compile or run is
one call into C++: on the main thread, SIGINT and SIGTERM wait until it returns (a plan of 1e8
Bellman backups never did, issue 40). So on the main thread the work runs in a daemon thread
while the main thread waits for it in short timed waits, returning to Python each time: the
handler runs within ``POLL`` s of the signal, whichever thread the kernel delivered it to, and
its exception (KeyboardInterrupt, ``sweep_stop.Interrupted``) comes out of here. Off the main
thread (a multi-threaded ROS executor's, say) the work simply runs: signals are not its.

The abandoned work goes on until it ends (the header's iteration bound,
``policy_file.MAX_ITERATIONS``, keeps one plan of a generated building under a second or so; a
250 x 250 m floor plan, 500 x 500 nodes, takes about 9 s). A process that exits meanwhile cannot
end normally: the interpreter's and JAX's teardown wait for the running computation, and Python
3.11 aborts the process ("FATAL: exception not rethrown") when the daemon thread comes back from
C++ while the interpreter finalises. So at exit (``_exit_now``, the first exit handler to run),
if the work has not ended within ``GRACE`` s, stdout, stderr and logging are flushed and the
process ends with ``os._exit`` and the status of the signal that interrupted it (130 SIGINT, 143
SIGTERM: what the project's commands return then), skipping the exit handlers registered before.
"""

from __future__ import annotations

import atexit
from collections.abc import Callable
import contextlib
import logging
import os
import sys
import threading
import time
from typing import TypeVar

POLL = 0.05  # s between the main thread's looks at pending signals while the work runs
GRACE = 0.5  # s the exiting process gives abandoned work to end before it exits at once
T = TypeVar('T')
_abandoned: list[threading.Thread] = []  # work whose waiting main thread was interrupted
_status = {'code': 130}  # the exit status of the last interruption


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
    except BaseException as stop:
        _abandon(thread, stop)
        raise
    if 'error' in outcome:
        raise outcome['error']
    return outcome['value']


def _abandon(thread: threading.Thread, stop: BaseException) -> None:
    if isinstance(stop, SystemExit):
        code = stop.code if isinstance(stop.code, int) else 1
    else:  # sweep_stop.Interrupted: 128 + its signal; a bare KeyboardInterrupt: SIGINT's
        code = getattr(stop, 'exit_code', 130 if isinstance(stop, KeyboardInterrupt) else 1)
    _status['code'] = code
    if not _abandoned:  # registered after JAX's exit handlers (JAX ran): runs before them
        atexit.register(_exit_now)
    _abandoned.append(thread)


def _exit_now() -> None:
    """At exit: ``os._exit`` unless the abandoned work ends within GRACE (module docstring)."""
    deadline = time.monotonic() + GRACE
    try:
        while any(t.is_alive() for t in _abandoned) and time.monotonic() < deadline:
            time.sleep(POLL)
        if not any(t.is_alive() for t in _abandoned):
            return
    except KeyboardInterrupt:  # Ctrl-C again: no more waiting
        pass
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # closed, a broken pipe: nothing to say
            stream.flush()
    os._exit(_status['code'])
