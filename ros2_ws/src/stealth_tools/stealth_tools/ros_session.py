"""The rclpy side shared by the recorder, the player and the topic verbs.

These tools own SIGINT and SIGTERM themselves (rclpy's handlers off): a signal only sets an
event, the spin loop notices it within a tenth of a second, and the tool then finishes its
work in order (close the bag, destroy the node) instead of dying inside a callback.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
import contextlib
import signal
import threading
import time

import rclpy
from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.signals import SignalHandlerOptions

from stealth_tools.qos_text import INFINITE_NS, QosDescription

SPIN_PERIOD = 0.1  # s: how long a signal can go unnoticed


@contextlib.contextmanager
def ros_session(args: list[str] | None = None) -> Iterator[threading.Event]:
    """rclpy initialised with our own SIGINT/SIGTERM handling; yields the stop event."""
    stop = threading.Event()
    previous = {
        signum: signal.signal(signum, lambda *_: stop.set())
        for signum in (signal.SIGINT, signal.SIGTERM)
    }
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield stop
    finally:
        rclpy.try_shutdown()
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def spin_until(
    executor,
    stop: threading.Event,
    done: Callable[[], bool] = lambda: False,
    timeout: float | None = None,
) -> bool:
    """Spin until stop is set, done() is true or the timeout passes; True if done() ended it."""
    deadline = None if timeout is None else time.monotonic() + timeout
    while not stop.is_set():
        if done():
            return True
        if deadline is not None and time.monotonic() >= deadline:
            return False
        executor.spin_once(timeout_sec=SPIN_PERIOD)
    return done()


def _duration_ns(duration: Duration) -> int:
    return min(int(duration.nanoseconds), INFINITE_NS)


def describe_qos(profile: QoSProfile) -> QosDescription:
    """An rclpy profile (e.g. a publisher's offered one) as plain data."""
    return QosDescription(
        history=profile.history.name.lower(),
        depth=int(profile.depth),
        reliability=profile.reliability.name.lower(),
        durability=profile.durability.name.lower(),
        deadline_ns=_duration_ns(profile.deadline),
        lifespan_ns=_duration_ns(profile.lifespan),
        liveliness=profile.liveliness.name.lower(),
        liveliness_lease_duration_ns=_duration_ns(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
    )


def _policy(enum, name: str, fallback: str):
    """The enum member of a policy name; the fallback's for 'unknown' or names rclpy lacks."""
    members = enum.__members__
    if name != 'unknown' and name.upper() in members:
        return members[name.upper()]
    return members[fallback.upper()]


def qos_profile(description: QosDescription) -> QoSProfile:
    """The rclpy profile of a description (durations of 0 stay unspecified)."""
    kwargs = {}
    for key, value in (
        ('deadline', description.deadline_ns),
        ('lifespan', description.lifespan_ns),
        ('liveliness_lease_duration', description.liveliness_lease_duration_ns),
    ):
        if value:
            kwargs[key] = Duration(nanoseconds=value)
    return QoSProfile(
        history=_policy(HistoryPolicy, description.history, 'keep_last'),
        depth=max(description.depth, 1),
        reliability=_policy(ReliabilityPolicy, description.reliability, 'reliable'),
        durability=_policy(DurabilityPolicy, description.durability, 'volatile'),
        liveliness=_policy(LivelinessPolicy, description.liveliness, 'automatic'),
        avoid_ros_namespace_conventions=description.avoid_ros_namespace_conventions,
        **kwargs,
    )


def topic_types(node, include_hidden: bool = True) -> dict[str, list[str]]:
    """{topic: [types]} of the graph as this node sees it."""
    from rclpy.topic_or_service_is_hidden import topic_or_service_is_hidden

    return {
        name: types
        for name, types in node.get_topic_names_and_types()
        if include_hidden or not topic_or_service_is_hidden(name)
    }


def wait_for_topic(node, executor, stop, topic: str, timeout: float | None) -> list[str] | None:
    """The types of `topic` once discovery has seen it; None if it did not show up in time."""
    found: list[list[str]] = []

    def seen() -> bool:
        types = topic_types(node).get(topic)
        if types:
            found.append(types)
        return bool(types)

    spin_until(executor, stop, seen, timeout)
    return found[0] if found else None


def absolute_topic(name: str) -> str:
    """'/name' for 'name' (the CLI resolves names in the root namespace, as a node there)."""
    return name if name.startswith('/') else '/' + name
