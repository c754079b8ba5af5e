"""Stopping a sweep on SIGINT or SIGTERM honestly, and leaving no ROS trial behind. No rclpy.

Ray Tune takes SIGINT for itself: it ends the run and returns as if every trial had finished, and
ray.init makes SIGTERM a bare exit. So while a sweep runs (``signals_stop``), both signals are the
driver's: inside a Tune run (``tune_run``) the signal is remembered and Tune asked to end through
its own SIGUSR1 handler (it stops the running trials and returns), and the run then raises
Interrupted (Tune is left for optuna searches); anywhere else Interrupted is raised at once (out
of Ray's blocking calls too: ``ray_calls``), and so is a second signal. Interrupted is a
KeyboardInterrupt whose exit code is 128 + the signal's number (130 SIGINT, 143 SIGTERM).

A ROS trial's `stealth train` runs in a session of its own, so that the terminal's Ctrl-C does
not reach it as well as the stop of its worker (two signals make it kill its nodes at once), and
carries the driver's mark (TRIAL_MARK; MARK is set before Ray starts and a local Ray's workers
inherit it), as do the trials' scratch directories. When Tune stops a trial, Ray ends its worker
and kills the worker's children; after an interrupted sweep ``clean_up`` waits for what is left
of the marked processes (their nodes stopping; SIGKILL after STOP_GRACE), and removes the trials'
scratch directories and the Fast DDS files of dead processes (stealth_bringup's
ros_domain.remove_dead_shm, as `stealth doctor` does).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
import contextlib
import os
from pathlib import Path
import shutil
import signal
import tempfile
import threading
import time
import uuid

MARK = 'STEALTH_SWEEP_MARK'  # the driver's, in its environment: inherited by a local Ray
TRIAL_MARK = 'STEALTH_SWEEP_TRIAL'  # a ROS trial's processes: the mark of their sweep
STOP_GRACE = 60.0  # s a stopped `stealth train` has for its orderly stop before SIGKILL
SIGNALS = (signal.SIGINT, signal.SIGTERM)
RUNS_DIR_PREFIX = 'stealth-sweep-'  # sweep_trials' scratch directories


class Interrupted(KeyboardInterrupt):
    """The sweep was stopped by a signal; ``exit_code`` is the shell's 128 + its number.
    ``report`` and ``status``: the interrupted sweep's results.md and status, once written."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        self.report = self.status = None
        super().__init__(self.name)

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


_state = {'active': False, 'signum': None, 'tune': False}


def requested() -> int | None:
    """The signal that asked the sweep to stop, if one did."""
    return _state['signum']


def _on_signal(signum, frame) -> None:
    first = _state['signum'] is None
    if first:
        _state['signum'] = signum
    tune_handler = signal.getsignal(signal.SIGUSR1)
    if first and _state['tune'] and callable(tune_handler):
        tune_handler(signal.SIGUSR1, frame)  # Tune ends the run; tune_run raises after it
        return
    raise Interrupted(signum)


def claim_signals() -> None:
    """SIGINT and SIGTERM to the sweep again (ray.init takes SIGTERM), while signals_stop."""
    if _state['active']:
        for number in SIGNALS:
            signal.signal(number, _on_signal)


@contextlib.contextmanager
def signals_stop() -> Iterator[str]:
    """SIGINT and SIGTERM stop the sweep (module docstring); yields the mark of its ROS trials.
    Outside the main thread (no signals there) only the mark."""
    mark = f'{os.getpid()}-{uuid.uuid4().hex[:12]}'
    saved_environment = {k: os.environ.get(k) for k in (MARK, 'TUNE_DISABLE_SIGINT_HANDLER')}
    os.environ[MARK] = mark
    os.environ['TUNE_DISABLE_SIGINT_HANDLER'] = '1'
    main = threading.current_thread() is threading.main_thread()
    previous = {number: signal.getsignal(number) for number in SIGNALS} if main else {}
    _state.update(active=main, signum=None, tune=False)
    claim_signals()
    try:
        yield mark
    finally:
        _state.update(active=False, tune=False, signum=None)  # the stop went out as Interrupted
        for number, handler in previous.items():
            signal.signal(number, handler)
        for key, value in saved_environment.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


@contextlib.contextmanager
def tune_run() -> Iterator[None]:
    """Around Tuner.fit: a signal ends the run through Tune, then raises Interrupted here."""
    if not _state['active']:
        yield
        return
    claim_signals()
    # A handler an earlier run left would set that run's event: Tune installs its own.
    signal.signal(signal.SIGUSR1, signal.SIG_DFL)
    _state['tune'] = True
    try:
        yield
    finally:
        _state['tune'] = False
    if _state['signum'] is not None:
        raise Interrupted(_state['signum'])


@contextlib.contextmanager
def ray_calls() -> Iterator[None]:
    """Around Ray's blocking calls (ray.wait, ray.get): a signal handled inside one comes out of
    it as a bare KeyboardInterrupt (Ray drops the exception the handler raised); the sweep's
    stop comes out of here as Interrupted, with its signal."""
    try:
        yield
    except KeyboardInterrupt as stop:
        if _state['signum'] is not None and not isinstance(stop, Interrupted):
            raise Interrupted(_state['signum']) from None
        raise


# --- the ROS trials of an interrupted sweep ------------------------------------------------------


def marked(mark: str, proc: Path = Path('/proc')) -> list[int]:
    """This user's processes that carry the mark (a ROS trial's `stealth train` and nodes)."""
    wanted = f'{TRIAL_MARK}={mark}'.encode()
    found = []
    for entry in proc.glob('[0-9]*'):
        with contextlib.suppress(OSError):
            if wanted in (entry / 'environ').read_bytes().split(b'\0'):
                found.append(int(entry.name))
    return found


def scratch_prefix() -> str:
    """The prefix of a trial's scratch directory: with its sweep's mark, when it has one."""
    mark = os.environ.get(MARK)
    return f'{RUNS_DIR_PREFIX}{mark}-' if mark else RUNS_DIR_PREFIX


def clean_up(mark: str, say: Callable[[str], None], ros: bool, grace: float = STOP_GRACE):
    """After an interrupted sweep: the stopped trials' scratch directories go; with ``ros``,
    their processes are waited for (SIGKILL after ``grace``) and dead Fast DDS files removed."""
    if ros:
        found = marked(mark)
        if found:
            say(f'sweep: waiting for {len(found)} process(es) of ROS trials to stop')
        deadline = time.monotonic() + grace
        while found and time.monotonic() < deadline:
            time.sleep(0.5)
            found = marked(mark)
        for pid in found:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        if found:
            say(f'sweep: killed {len(found)} ROS trial process(es) left after {grace:g} s')
            time.sleep(1.0)
    for scratch in Path(tempfile.gettempdir()).glob(f'{RUNS_DIR_PREFIX}{mark}-*'):
        shutil.rmtree(scratch, ignore_errors=True)
    if ros:
        from stealth_bringup.ros_domain import remove_dead_shm

        removed = remove_dead_shm()
        if removed:
            say(f'sweep: removed {len(removed)} Fast DDS file(s) of stopped trials from /dev/shm')
