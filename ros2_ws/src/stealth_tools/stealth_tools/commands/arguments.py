"""What the commands share: argument types and groups (as ros2cli's), and the handlers that put
off importing a verb's implementation, and rclpy, until it runs."""

from __future__ import annotations

import argparse
from collections.abc import Callable
import importlib
import math

QOS_PROFILES = (
    'unknown',
    'default',
    'system_default',
    'sensor_data',
    'services_default',
    'parameters',
    'parameter_events',
    'action_status_default',
    'best_available',
)
RELIABILITIES = ('system_default', 'reliable', 'best_effort', 'best_available')
DURABILITIES = ('system_default', 'transient_local', 'volatile', 'best_available')
HISTORIES = ('system_default', 'keep_last', 'keep_all')


def whole_number(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a whole number') from None


def number(text: str) -> float:
    """A finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'{text} is not a finite number')
    return value


def positive_float(text: str) -> float:
    value = number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text} is not a positive number')
    return value


def non_negative_float(text: str) -> float:
    value = number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'{text} is negative')
    return value


def positive_int(text: str) -> int:
    value = whole_number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text} is not a positive integer')
    return value


def non_negative_int(text: str) -> int:
    value = whole_number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'{text} is negative')
    return value


def port(text: str) -> int:
    value = whole_number(text)
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f'{text} is not a TCP port (1-65535)')
    return value


def add_spin_time(parser: argparse.ArgumentParser, default: float) -> None:
    parser.add_argument(
        '--spin-time',
        type=non_negative_float,
        default=default,
        help='at most this many seconds to wait for discovery (no ros2cli daemon here; '
        'default: %(default)s)',
    )


def add_discovery_arguments(parser: argparse.ArgumentParser, default_ms: int) -> None:
    """How new topics are looked for (as ros2 bag record's options)."""
    parser.add_argument(
        '-p',
        '--polling-interval',
        type=positive_int,
        default=default_ms,
        metavar='MS',
        help='discovery period for new topics, in ms (default: %(default)s)',
    )
    parser.add_argument('--include-hidden-topics', action='store_true', help='hidden ones too')


def add_timeout(parser: argparse.ArgumentParser) -> None:
    """--timeout of the verbs that listen to a topic (echo, hz): as ros2 topic echo's, the
    command ends after N seconds, however many messages arrive."""
    parser.add_argument(
        '--timeout',
        metavar='N',
        type=positive_float,
        help="stop after N seconds, finding the topic's type included (default: no limit); "
        'exit status 1 when no message arrived',
    )


def add_qos_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        '--qos-profile',
        choices=QOS_PROFILES,
        default='sensor_data',
        help='QoS preset to subscribe with (default: %(default)s)',
    )
    parser.add_argument('--qos-depth', metavar='N', type=int, help='depth (overrides preset)')
    parser.add_argument('--qos-history', choices=HISTORIES, help='history (overrides preset)')
    parser.add_argument(
        '--qos-reliability',
        choices=RELIABILITIES,
        help='reliability (default: what the running publishers offer)',
    )
    parser.add_argument(
        '--qos-durability',
        choices=DURABILITIES,
        help='durability (default: what the running publishers offer)',
    )


def in_ros(verb: Callable) -> Callable:
    """Run a graph verb inside an rclpy session that owns SIGINT/SIGTERM."""

    def handler(args) -> int:
        from stealth_tools.ros_session import ros_session

        with ros_session() as stop:
            return verb(args, stop)

    return handler


def lazy(module: str, function: str, ros: bool = False) -> Callable:
    """A handler that imports its implementation only when run (keeps --help free of ROS)."""

    def handler(args) -> int:
        verb = getattr(importlib.import_module(f'stealth_tools.{module}'), function)
        return (in_ros(verb) if ros else verb)(args)

    return handler
