"""The Jazzy ``main()`` of every node, with one error policy.

Init, build the node, spin until Ctrl-C or an external shutdown, then tidy up and shut down, as
ros2/demos does. A node that cannot start (bad ``--ros-args``, a parameter out of range, a
missing scenario) logs one fatal line saying why and the process exits with 2, never with a
traceback; the orchestrator reports that line. A node whose file cannot be written because the
disk is full (full_disk.DiskFullError) logs that line and exits with EXIT_DISK_FULL (4).
"""

from __future__ import annotations

from collections.abc import Callable
import re

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
import rclpy.node

from stealth_node_kit.full_disk import EXIT_DISK_FULL, DiskFullError

EXIT_CANNOT_START = 2
SPIN_WAKE = 1.0  # s: the longest the executor waits before it looks at the context again


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


def spin_until_shutdown(nodes: list[rclpy.node.Node]) -> None:
    """``rclpy.spin`` for several nodes, the executor waking at least every SPIN_WAKE s.

    rclpy's global executor, which is shut down with the context on SIGINT (one of our own was
    only woken, and went on to take messages from endpoints being torn down: a pybind11
    RuntimeError while the context still looked up, exit code 1 at a run's end). The wake-ups
    bound a missed one: twice in one session an agent (a node with no timer, whose executor
    waits without a timeout) sat out a SIGINT until the test's 15 s were up.
    """
    executor = rclpy.get_global_executor()
    for node in nodes:
        executor.add_node(node)
    try:
        while executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_WAKE)
    finally:
        for node in nodes:
            executor.remove_node(node)


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
    is destroyed (save a policy, log totals); after Ctrl-C its logging goes to the console only.
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
    logger = rclpy.logging.get_logger(name)
    try:
        rclpy.init(args=args)
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
            # rclpy's SIGINT handler shut the context down while the node was being built, and
            # an rcl call failed on it before Python raised the KeyboardInterrupt: a stop too.
            return 0
        logger.fatal(f'not starting: {_without_source_locations(error)}')
        rclpy.try_shutdown()
        return EXIT_CANNOT_START
    code = 0
    try:
        spin_until_shutdown(nodes)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except DiskFullError as error:
        code = _stop_for_full_disk(logger, error)
    except (_rclpy.RCLError, RuntimeError):
        # rclpy's SIGINT handler shuts the context down from another thread: a wait set being
        # built then fails (RCLError), and a message being taken fails to convert (a plain
        # RuntimeError from pybind11, seen as a node's exit code 1 at a run's end). Either is
        # part of the stop once the context is down; while it is up, a real failure.
        if rclpy.ok():
            raise
    finally:
        if on_exit is not None:
            try:
                on_exit(nodes)
            except DiskFullError as error:
                code = _stop_for_full_disk(logger, error)
        for node in reversed(nodes):
            node.destroy_node()
        rclpy.try_shutdown()
    return code


def _stop_for_full_disk(logger, error: DiskFullError) -> int:
    """A node's file could not be written for want of space: one fatal line, and the exit
    code that tells the orchestrator not to restart it."""
    logger.fatal(f'{error}; stopping')
    return EXIT_DISK_FULL
