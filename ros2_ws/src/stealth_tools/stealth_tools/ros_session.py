"""The rclpy side shared by the recorder, the player and the topic verbs.

These tools own SIGINT and SIGTERM themselves (rclpy's handlers off): a signal only sets an
event, the spin loop notices it within a tenth of a second, and the tool then finishes its
work in order (close the bag, destroy the node) instead of dying inside a callback. Started by
the orchestrator (asked to die with it), a tool is watched for outliving it (``orphan_watch``).
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
from stealth_node_kit.orphan_watch import watch_for_orphaning

from stealth_tools.qos_text import INFINITE_NS, QosDescription

SPIN_PERIOD = 0.1  # s: how long a signal can go unnoticed


@contextlib.contextmanager
def ros_session(args: list[str] | None = None) -> Iterator[threading.Event]:
    """rclpy initialised with our own SIGINT/SIGTERM handling; yields the stop event."""
    stop = threading.Event()
    watch_for_orphaning()
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


def published_topics(node, include_hidden: bool = True, wanted=lambda topic: True):
    """(topic, types, offers) of every wanted topic that has publishers now (a topic with only
    subscribers has no offered QoS to match yet): what the recorder and the bridge discover."""
    for topic, types in topic_types(node, include_hidden).items():
        if not wanted(topic):
            continue
        offers = node.get_publishers_info_by_topic(topic)
        if offers:
            yield topic, types, offers


def discovered_topics(node, include_hidden: bool, wanted, skip):
    """(topic, type name, message class, ros2msg definition, offers) of every wanted topic that
    has publishers and one type this installation knows; skip(topic, why) for the others (the
    recorder's and the bridge's discovery)."""
    from stealth_tools.interfaces import InterfaceError, definition_text, message_class

    for topic, types, offers in published_topics(node, include_hidden, wanted):
        if len(types) != 1:
            skip(topic, f'it has several types ({", ".join(types)})')
            continue
        try:
            msg_type, definition = message_class(types[0]), definition_text(types[0])
        except InterfaceError as error:
            skip(topic, f'type {types[0]}: {error}')
            continue
        yield topic, types[0], msg_type, definition, offers


DRAIN_BATCH = 200  # messages taken per callback; bounded so timers and signals get a turn


def raw_subscription(node, topic: str, msg_type, qos, handle_one, on_loss=None, drain=True):
    """A subscription delivering (CDR bytes, message info) to handle_one, draining its queue.

    After the message it is called with, the callback takes what else is queued on the
    subscription (up to DRAIN_BATCH), because the executor's cost per callback is several times
    that of handling a message: it lifts the recorder's rate from ~3,000 to ~30,000 msg/s.
    With ``drain`` false, handle_one gets only the message it was called with (a caller that
    takes the queues itself). Event callbacks: only the loss report `on_loss(status)`, if
    given. rclpy's default handlers (incompatible QoS and type) cannot fire on a subscription
    that copies the publishers' QoS and type, yet each is one more entity in every executor
    wait. Measured in `make run` (19 topics): the recorder's CPU time went from 48 s to 35 s
    of a 65 s run.
    """
    from rclpy.event_handler import SubscriptionEventCallbacks, UnsupportedEventTypeError

    created = []  # filled once created: the callback drains it

    def on_message(data: bytes, info: dict) -> None:
        handle_one(data, info)
        if not drain:
            return
        handle = created[0].handle
        with handle:
            for _ in range(DRAIN_BATCH):
                taken = handle.take_message(msg_type, True)
                if taken is None:
                    break
                handle_one(*taken)

    quiet = SubscriptionEventCallbacks(use_default_callbacks=False)
    events = quiet
    if on_loss is not None:
        events = SubscriptionEventCallbacks(message_lost=on_loss, use_default_callbacks=False)
    try:
        subscription = node.create_subscription(
            msg_type, topic, on_message, qos, raw=True, event_callbacks=events
        )
    except UnsupportedEventTypeError:
        subscription = node.create_subscription(
            msg_type, topic, on_message, qos, raw=True, event_callbacks=quiet
        )
    created.append(subscription)
    return subscription


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
