"""The Jazzy ``main()`` of every node, with one error policy.

Init, build the node, spin until Ctrl-C or an external shutdown, then tidy up and shut down, as
ros2/demos does. A node that cannot start (bad ``--ros-args``, a parameter out of range, a
missing scenario) logs one fatal line saying why and the process exits with 2, never with a
traceback; the orchestrator reports that line. A node whose file cannot be written because the
disk is full (full_disk.DiskFullError) logs that line and exits with EXIT_DISK_FULL (4).

SIGINT and SIGTERM are handled here, not by rclpy (whose handler shuts the context down at
once, from another thread): either raises KeyboardInterrupt, as Python's own SIGINT handler
does (a node being built, a callback, a long plan is interrupted), and the node stops in order
with its context still up. Its exit hook runs (later signals are ignored until it is gone, so a
policy being saved is not cut short), then it waits (at most ACK_WAIT s) until every subscriber
has acknowledged its reliable messages: a recorder that fell behind under load gets what DDS
dropped on the way resent (a reliable writer resends only on its next heartbeat, 3 s apart in
Fast DDS, and a writer that is gone resends nothing: a loaded run once lost 170 steps of a
recording so). A node whose parent died (a killed orchestrator: PR_SET_PDEATHSIG) does not
wait: the run's recorder is stopping too, and the dead parent's readers stay matched until
their DDS lease ends, so the wait would only hold the orphan. A stop that hangs after the exit
hook (STOP_LIMIT s) dumps every thread's stack to stderr and exits 1: an orphan has no one to
kill it (and ``orphan_watch`` ends an orphan stuck anywhere else).
"""

from __future__ import annotations

from collections.abc import Callable
import faulthandler
import os
import re
import signal
import time

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
import rclpy.node
from rclpy.qos import ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from stealth_node_kit.full_disk import EXIT_DISK_FULL, DiskFullError
from stealth_node_kit.orphan_watch import watch_for_orphaning

EXIT_CANNOT_START = 2
SPIN_WAKE = 0.1  # s: the longest a stop signal goes unnoticed while the nodes spin
ACK_WAIT = 5.0  # s a stopping node waits for its reliable messages to be acknowledged
ACK_SLICE = 0.1  # s between looks at whether to give up waiting (the parent died meanwhile)
STOP_LIMIT = ACK_WAIT + 10.0  # s after the exit hook before a stuck stop dumps stacks, exits 1
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequested(Exception):  # noqa: N818 - a request, not an error
    """Raised by a node's callback to stop its process in order, as a stop signal does (the
    exit hook, then the acknowledgements): the environment giving up on its robot."""


class StopSignals:
    """SIGINT and SIGTERM as KeyboardInterrupt until the process begins to stop, then ignored
    (the orchestrator's SIGKILL stays the hard stop). ``received`` stays set: a KeyboardInterrupt
    raised inside rclpy's pybind11 code (a message being taken) comes out as a RuntimeError, or
    not at all, and the spin loop must still stop."""

    def __init__(self):
        self.stopping = False
        self.received = False
        self.parent = os.getppid()
        self._previous = {}

    def __enter__(self) -> StopSignals:
        watch_for_orphaning()
        self._previous = {
            signum: signal.signal(signum, self._on_signal) for signum in STOP_SIGNALS
        }
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)

    @property
    def orphaned(self) -> bool:
        """Whether the process that started this one has died."""
        return os.getppid() != self.parent

    def _on_signal(self, signum, frame) -> None:
        if not self.stopping:
            self.received = True
            raise KeyboardInterrupt


class StartupNode(rclpy.node.Node):
    """A node whose ``set_up()`` may refuse to start (StartupError) or be interrupted: it then
    destroys itself before the error leaves, so no DDS participant (nor its shared memory)
    outlives a node that never ran."""

    def __init__(self, node_name: str, **kwargs):
        super().__init__(node_name, **kwargs)
        try:
            self.set_up()
        except BaseException:
            self.destroy_node()
            raise

    def set_up(self) -> None:
        raise NotImplementedError


def spin_until_shutdown(nodes: list[rclpy.node.Node], stop: StopSignals) -> None:
    """``rclpy.spin`` for several nodes until a stop signal or an external shutdown, the
    executor waking at least every SPIN_WAKE s to notice either (a signal's handler runs only
    between bytecodes).

    rclpy's global executor: one of our own, only woken at a shutdown, once went on to take
    messages from endpoints being torn down (a pybind11 RuntimeError, exit code 1 at a run's
    end).
    """
    executor = rclpy.get_global_executor()
    for node in nodes:
        executor.add_node(node)
    try:
        while executor.context.ok() and not stop.received:
            executor.spin_once(timeout_sec=SPIN_WAKE)
    finally:
        for node in nodes:
            executor.remove_node(node)


def wait_for_acknowledgements(
    nodes: list[rclpy.node.Node], timeout: float, give_up: Callable[[], bool] = lambda: False
) -> list[str]:
    """Wait (at most `timeout` s in all, looking at `give_up()` every ACK_SLICE s) until every
    subscriber has acknowledged every message of the nodes' reliable publishers; the topics
    still waiting then."""
    deadline = time.monotonic() + timeout
    waiting = []
    for node in nodes:
        for publisher in node.publishers:
            if publisher.qos_profile.reliability != ReliabilityPolicy.RELIABLE:
                continue
            while not publisher.wait_for_all_acked(
                _seconds(min(ACK_SLICE, deadline - time.monotonic()))
            ):
                if time.monotonic() >= deadline or give_up():
                    waiting.append(publisher.topic_name)
                    break
    return waiting


def _seconds(value: float) -> Duration:
    return Duration(nanoseconds=int(max(0.0, value) * 1e9))


def _without_source_locations(error: Exception) -> str:
    """rcl's messages end in ', at /path/file.c:123': useless to a user."""
    return re.sub(r', at [^,]*:\d+', '', str(error))


def run_node(
    make_node: Callable[[], rclpy.node.Node],
    name: str,
    *,
    args=None,
    on_exit: Callable[[rclpy.node.Node], None] | None = None,
) -> int:
    """Run one node in this process; the exit code (0, 2 when it could not start, or
    EXIT_DISK_FULL when a DiskFullError left its callbacks or `on_exit`).

    `name` names the logger of the fatal line; `on_exit` runs after spinning, before the node
    is destroyed (save a policy, log totals), with the context still up after a stop signal.
    """
    return run_nodes(
        lambda: [make_node()],
        name,
        args=args,
        on_exit=None if on_exit is None else (lambda nodes: on_exit(nodes[0])),
    )


def run_nodes(
    make_nodes: Callable[[], list[rclpy.node.Node]],
    name: str,
    *,
    args=None,
    on_exit: Callable[[list[rclpy.node.Node]], None] | None = None,
) -> int:
    """:func:`run_node` for several nodes in one process, spun by rclpy's global executor
    (single-threaded: their callbacks never run at the same time); `make_nodes` destroys what
    it built if it fails part-way. They are destroyed in the reverse order."""
    with StopSignals() as stop:
        return _run(make_nodes, rclpy.logging.get_logger(name), args, on_exit, stop)


def _run(make_nodes, logger, args, on_exit, stop: StopSignals) -> int:
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as error:  # e.g. an unreadable --params-file
        logger.fatal(f'not starting: bad arguments: {_without_source_locations(error)}')
        return EXIT_CANNOT_START
    try:
        nodes = make_nodes()
    except KeyboardInterrupt:  # stopped (Ctrl-C, the orchestrator) while it was starting
        rclpy.try_shutdown()
        return 0
    except Exception as error:  # StartupError, or rcl's own (e.g. a bad remapping)
        if not rclpy.ok():
            # The context was shut down while the node was being built (rclpy.shutdown from
            # elsewhere in the process) and an rcl call failed on it: a stop too.
            return 0
        logger.fatal(f'not starting: {_without_source_locations(error)}')
        rclpy.try_shutdown()
        return EXIT_CANNOT_START
    code = 0
    try:
        spin_until_shutdown(nodes, stop)
    except (KeyboardInterrupt, ExternalShutdownException, StopRequested):
        pass
    except DiskFullError as error:
        code = _stop_for_full_disk(logger, error)
    except (_rclpy.RCLError, RuntimeError):
        # A stop signal's KeyboardInterrupt raised while pybind11 converts a message being
        # taken comes out as a plain RuntimeError ('Unable to convert call argument'), and a
        # context shut down from elsewhere in the process can leave a wait set being built
        # failing (RCLError): the stop, either of them. Otherwise a real failure.
        if rclpy.ok() and not stop.received:
            raise
    finally:
        stop.stopping = True
        if on_exit is not None:
            try:
                on_exit(nodes)
            except DiskFullError as error:
                code = _stop_for_full_disk(logger, error)
        _finish(nodes, logger, stop)
    return code


def _finish(nodes, logger, stop: StopSignals) -> None:
    """After the exit hook: wait for the acknowledgements (not as an orphan), destroy the nodes
    in the reverse order, shut down. Stuck here for STOP_LIMIT s: every thread's stack to
    stderr, and exit 1."""
    faulthandler.dump_traceback_later(STOP_LIMIT, exit=True)
    try:
        waiting = []
        if rclpy.ok() and not stop.orphaned:
            waiting = wait_for_acknowledgements(nodes, ACK_WAIT, lambda: stop.orphaned)
        if stop.orphaned:
            logger.info('the process that started this one is gone: not waiting for its acks')
        elif waiting:
            logger.warning(
                f'stopping with messages on {", ".join(waiting)} not acknowledged by every '
                f'subscriber within {ACK_WAIT:g} s: a subscriber that fell behind (a '
                'recorder, a bridge) misses them, or one that died is still matched until '
                'its DDS lease ends'
            )
        for node in reversed(nodes):
            node.destroy_node()
        rclpy.try_shutdown()
    finally:
        faulthandler.cancel_dump_traceback_later()


def _stop_for_full_disk(logger, error: DiskFullError) -> int:
    """A node's file could not be written for want of space: one fatal line, and the exit
    code that tells the orchestrator not to restart it."""
    logger.fatal(f'{error}; stopping')
    return EXIT_DISK_FULL
