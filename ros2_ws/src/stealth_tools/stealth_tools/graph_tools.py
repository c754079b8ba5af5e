"""`topic list|echo|hz|info`: the ros2topic verbs over a short-lived hidden node.

Without the ros2cli daemon every call discovers the graph itself, so each verb first spins for
up to --spin-time until what it needs (a publisher of the topic) has been seen.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time

import rclpy
from rclpy.exceptions import InvalidTopicNameException
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSPresetProfiles,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rclpy.validate_full_topic_name import validate_full_topic_name

from stealth_tools.clock_arithmetic import RateWindow
from stealth_tools.errors import CommandError
from stealth_tools.interfaces import InterfaceError, message_class
from stealth_tools.message_yaml import message_to_yaml
from stealth_tools.qos_text import subscription_policies
from stealth_tools.ros_session import absolute_topic, describe_qos, spin_until, topic_types

GRAPH_SETTLE = 0.5  # s without a new topic before `topic list` trusts what it has seen
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'  # endpoint info before the node's discovery info arrived
HZ_PERIOD = 0.1  # s: the longest `topic hz` waits for a message before it looks at its window


@contextlib.contextmanager
def cli_node():
    """A hidden node (no /rosout, no parameter services) and its executor."""
    node = rclpy.create_node(
        f'_stealth_cli_{os.getpid()}', enable_rosout=False, start_parameter_services=False
    )
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()


def _wait_for_graph(node, executor, stop, timeout: float) -> None:
    """Spin until other nodes are known and the topic set has not changed for GRAPH_SETTLE s."""
    last = {'topics': None, 'since': time.monotonic()}

    def settled() -> bool:
        topics, now = frozenset(topic_types(node)), time.monotonic()
        if topics != last['topics']:
            last.update(topics=topics, since=now)
            return False
        return len(node.get_node_names()) > 1 and now - last['since'] >= GRAPH_SETTLE

    spin_until(executor, stop, settled, timeout)


def _types_once_published(node, executor, stop, topic: str, timeout: float | None):
    """The topic's types once a publisher of it is seen, or whatever is known at the timeout."""
    spin_until(executor, stop, lambda: node.count_publishers(topic) > 0, timeout)
    return topic_types(node).get(topic)


def _within(timeout: float | None, started: float, wait: float | None = None) -> float | None:
    """How long a step may wait: `wait` (None: no bound) cut to what is left of `timeout` s
    since `started` (monotonic), so --timeout bounds the whole command, discovery included."""
    if timeout is None:
        return wait
    left = max(timeout - (time.monotonic() - started), 0.0)
    return left if wait is None else min(wait, left)


def _topic_argument(name: str) -> str:
    """The topic a command-line name stands for (CommandError when it cannot be a topic)."""
    topic = absolute_topic(name)
    try:
        validate_full_topic_name(topic)
    except InvalidTopicNameException as error:
        reason = str(error).splitlines()[0].removeprefix('Invalid topic name: ').rstrip(':')
        raise CommandError(f'invalid topic name {name!r}: {reason}') from None
    return topic


def _class_of(type_name: str):
    try:
        return message_class(type_name)
    except InterfaceError as error:
        raise CommandError(str(error)) from None


def topic_list(args, stop: threading.Event) -> int:
    with cli_node() as (node, executor):
        _wait_for_graph(node, executor, stop, args.spin_time)
        topics = sorted(topic_types(node, args.include_hidden_topics).items())
        if args.count_topics:
            print(len(topics))
        elif args.verbose:
            for role, count in (
                ('Published', node.count_publishers),
                ('Subscribed', node.count_subscribers),
            ):
                noun = 'publisher' if role == 'Published' else 'subscriber'
                print(f'{role} topics:')
                for name, types in topics:
                    if n := count(name):
                        print(f' * {name} [{", ".join(types)}] {n} {noun}{"s" if n > 1 else ""}')
                print()
        else:
            for name, types in topics:
                print(f'{name} [{", ".join(types)}]' if args.show_types else name)
    return 0


def _echo_qos(node, topic: str, args):
    """ros2 topic echo's choice: the preset with explicit overrides, else adapted to offers."""
    profile = QoSPresetProfiles.get_from_short_key(args.qos_profile)
    overrides = {
        'reliability': (args.qos_reliability, ReliabilityPolicy),
        'durability': (args.qos_durability, DurabilityPolicy),
        'history': (args.qos_history, HistoryPolicy),
    }
    if any(value for value, _ in overrides.values()) or args.qos_depth is not None:
        for field, (value, enum) in overrides.items():
            if value:
                setattr(profile, field, enum.get_from_short_key(value))
        if args.qos_depth is not None:
            profile.depth = args.qos_depth
        return profile
    offers = [describe_qos(info.qos_profile) for info in node.get_publishers_info_by_topic(topic)]
    if offers:
        reliability, durability = subscription_policies(offers)
        profile.reliability = ReliabilityPolicy.get_from_short_key(reliability)
        profile.durability = DurabilityPolicy.get_from_short_key(durability)
    return profile


def _field_of(message, path: list[str]):
    for name in path:
        try:
            message = getattr(message, name)
        except AttributeError:
            raise CommandError(f"invalid field '{'.'.join(path)}': no '{name}'") from None
    return message


def topic_echo(args, stop: threading.Event) -> int:
    topic = _topic_argument(args.topic_name)
    field = [part for part in (args.field or '').split('.') if part]
    truncate = None if args.full_length else args.truncate_length
    started = time.monotonic()
    with cli_node() as (node, executor):
        discovery = _within(args.timeout, started, args.spin_time)
        types = _types_once_published(node, executor, stop, topic, discovery)
        type_name = args.message_type or (types[0] if types else None)
        if type_name is None:
            waited = args.spin_time if args.timeout is None else min(args.spin_time, args.timeout)
            raise CommandError(
                f"could not determine the type of '{topic}': nothing published it within "
                f'{waited:g} s (pass the type: stealth topic echo {topic} pkg/msg/Type)'
            )
        received = []

        def show(message) -> None:
            shown = _field_of(message, field)
            if hasattr(shown, 'get_fields_and_field_types'):
                text = message_to_yaml(
                    shown,
                    truncate_length=truncate,
                    no_arr=args.no_arr,
                    no_str=args.no_str,
                    flow_style=args.flow_style,
                )
            else:
                text = f'{shown}\n'
            sys.stdout.write(text + '---\n')
            sys.stdout.flush()
            received.append(True)

        node.create_subscription(_class_of(type_name), topic, show, _echo_qos(node, topic, args))
        spin_until(
            executor, stop, lambda: args.once and bool(received), _within(args.timeout, started)
        )
    if args.timeout is not None and not received and not stop.is_set():
        raise CommandError(f'no message on {topic} within {args.timeout:g} s')
    return 0


def topic_hz(args, stop: threading.Event) -> int:
    topic = _topic_argument(args.topic_name)
    with cli_node() as (node, executor):
        started = time.monotonic()
        discovery = _within(args.timeout, started, args.spin_time)
        types = _types_once_published(node, executor, stop, topic, discovery)
        if not types:
            print(f'WARNING: topic [{topic}] does not appear to be published yet', flush=True)
            types = _types_once_published(
                node, executor, stop, topic, _within(args.timeout, started)
            )
        if not types and args.timeout is not None and not stop.is_set():
            raise CommandError(f'nothing published {topic} within {args.timeout:g} s')
        if not types:
            return 0  # stopped while waiting
        window = RateWindow(args.window_size)
        received = [False]
        clock = node.get_clock()

        def on_message(_) -> None:
            window.add(time.time_ns() if args.use_wtime else clock.now().nanoseconds)
            received[0] = True

        node.create_subscription(
            _class_of(types[0]), topic, on_message, qos_profile_sensor_data, raw=True
        )
        while not stop.is_set():
            left = _within(args.timeout, started, HZ_PERIOD)
            if left is not None and left <= 0.0:  # --timeout: the command's time is up
                stats = window.final_report()  # what came since the last line, however short
                if stats:
                    print(stats.text(), flush=True)
                break
            executor.spin_once(timeout_sec=left)
            stats = window.report()
            if stats:
                print(stats.text(), flush=True)
    if args.timeout is not None and not received[0] and not stop.is_set():
        raise CommandError(f'no message on {topic} within {args.timeout:g} s')
    return 0


def topic_info(args, stop: threading.Event) -> int:
    topic = _topic_argument(args.topic_name)
    with cli_node() as (node, executor):
        types = _types_once_published(node, executor, stop, topic, args.spin_time)
        if not types:
            raise CommandError(f"Unknown topic '{topic}'")
        end = '\n\n' if args.verbose else '\n'
        if args.verbose:  # let the node names of the endpoints arrive
            endpoints = (node.get_publishers_info_by_topic, node.get_subscriptions_info_by_topic)
            spin_until(
                executor,
                stop,
                lambda: all(i.node_name != UNKNOWN_NODE for f in endpoints for i in f(topic)),
                timeout=1.0,
            )
        print(f'Type: {types[0] if len(types) == 1 else types}', end=end)
        for label, count, infos in (
            ('Publisher count', node.count_publishers, node.get_publishers_info_by_topic),
            ('Subscription count', node.count_subscribers, node.get_subscriptions_info_by_topic),
        ):
            print(f'{label}: {count(topic)}', end=end)
            if args.verbose:
                for info in infos(topic):
                    print(info, end=end)
    return 0
