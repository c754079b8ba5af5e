"""Ctrl-C during the network's JAX work: ``interruptible(work)`` runs it where the main thread
can still react.

Python runs a signal's handler in the main thread, between bytecodes. An XLA compile or run is
one call into C++: on the main thread, SIGINT and SIGTERM wait until it returns (a plan of 1e8
Bellman backups never did, issue 40). So on the main thread the work runs in a daemon thread
while the main thread waits for it in short timed waits, returning to Python each time: the
handler runs within ``POLL`` s of the signal, whichever thread the kernel delivered it to, and
its exception (KeyboardInterrupt, ``sweep_stop.Interrupted``) comes out of here. The abandoned
work goes on in its daemon thread until it ends or the process exits (the header's iteration
bound, ``policy_file.MAX_ITERATIONS``, keeps it short). Off the main thread (a ROS executor's,
a worker's) the work simply runs: signals are not that thread's.
"""

from __future__ import annotations

from collections.abc import Callable
import threading
from typing import TypeVar

POLL = 0.05  # s between the main thread's looks at pending signals while the work runs
T = TypeVar('T')


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

    threading.Thread(target=run, name='stealth-learn-jax', daemon=True).start()
    while not done.wait(POLL):
        pass
    if 'error' in outcome:
        raise outcome['error']
    return outcome['value']
