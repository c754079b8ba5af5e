"""What the Foxglove bridge decides, without rclpy or a server: which topics it relays, how a
topic's subscription is chosen, what a late client is sent again, the time /clock gives, the
line a port in use gets, and the log filter that reports each kind of client trouble once.
The ROS and WebSocket shell is stealth_tools.bridge.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import logging
import re
import struct

from stealth_tools.qos_text import QosDescription, subscription_policies

CLOCK_TOPIC = '/clock'
MESSAGE_ENCODING = 'cdr'  # foxglove_bridge's channels: CDR messages ...
SCHEMA_ENCODING = 'ros2msg'  # ... described by the full .msg text, nested types included
VOLATILE_DEPTH = 10  # queue of a volatile topic's subscription: a viewer drops, never stalls
LATCHED_DEPTH_MAX = 25  # foxglove_bridge's cap on what a transient local topic keeps
DEFAULT_PORT = 8765  # Foxglove's default for a WebSocket connection


def relay_policies(offers: list[QosDescription]) -> tuple[str, str, int]:
    """(reliability, durability, depth) of the bridge's subscription to a topic.

    Transient local when every publisher is (latched /map, markers, searchlights, description
    arrive), then reliable with the publishers' depths; otherwise best effort, so that a bridge
    that falls behind loses view frames instead of holding back a KEEP_ALL publisher of the run
    (rl_env/step_info): the run must not notice the viewer.
    """
    _, durability = subscription_policies(offers)
    if durability == 'transient_local':
        depth = sum(max(o.depth, 1) for o in offers) if offers else 1
        return 'reliable', durability, min(depth, LATCHED_DEPTH_MAX)
    return 'best_effort', durability, VOLATILE_DEPTH


def wanted_topic(topic: str, requested: frozenset[str]) -> bool:
    """Every topic when none was requested; /clock always (it drives the timeline)."""
    return not requested or topic in requested or topic == CLOCK_TOPIC


class LatchedCache:
    """The latest messages of each transient local topic, for clients that subscribe late.

    DDS gives a transient local topic's history to a new subscription; the WebSocket server has
    no such memory, so the bridge keeps the last `depth` messages (the publishers' depths) and
    sends them again when a client subscribes to the topic.
    """

    def __init__(self):
        self._kept: dict[str, deque] = {}

    def track(self, topic: str, depth: int) -> None:
        self._kept[topic] = deque(maxlen=max(depth, 1))

    def is_latched(self, topic: str) -> bool:
        return topic in self._kept

    def add(self, topic: str, data: bytes, log_time: int) -> None:
        kept = self._kept.get(topic)
        if kept is not None:
            kept.append((data, log_time))

    def messages(self, topic: str) -> list[tuple[bytes, int]]:
        """(CDR bytes, log time) of the kept messages, oldest first."""
        return list(self._kept.get(topic, ()))


class ClientSubscriptions:
    """Which clients subscribe to which channel: the bridge subscribes to a topic over DDS only
    while some client wants it (as foxglove_bridge), so a bridge nobody watches, and the
    publishers that build their messages only for subscribers, cost next to nothing."""

    def __init__(self):
        self._clients: dict[int, set[int]] = {}

    def add(self, channel: int, client: int) -> bool:
        """True when this is the channel's first client."""
        clients = self._clients.setdefault(channel, set())
        first = not clients
        clients.add(client)
        return first

    def remove(self, channel: int, client: int) -> bool:
        """True when the channel's last client went."""
        clients = self._clients.get(channel)
        if not clients or client not in clients:
            return False
        clients.discard(client)
        return not clients

    def count(self, channel: int) -> int:
        return len(self._clients.get(channel, ()))


def clock_nanoseconds(cdr: bytes) -> int | None:
    """The time in a serialized rosgraph_msgs/Clock (CDR: 4-byte encapsulation header, then
    int32 sec and uint32 nanosec); None when the bytes are not one."""
    if len(cdr) < 12 or cdr[0] != 0 or cdr[1] not in (0, 1):
        return None
    sec, nanosec = struct.unpack('<iI' if cdr[1] == 1 else '>iI', cdr[4:12])
    if sec < 0 or nanosec >= 10**9:
        return None
    return sec * 10**9 + nanosec


class Timeline:
    """The bridge's time, for message log times and the Foxglove timeline: once /clock is
    published, the latest /clock (simulated time; 0 until the first arrives, as
    foxglove_bridge under use_sim_time), else the wall clock."""

    def __init__(self):
        self.clock_ns: int | None = None

    @property
    def follows_clock(self) -> bool:
        return self.clock_ns is not None

    def expect_clock(self) -> None:
        """/clock has a publisher: its time from now on."""
        if self.clock_ns is None:
            self.clock_ns = 0

    def on_clock(self, cdr: bytes) -> int | None:
        value = clock_nanoseconds(cdr)
        if value is not None:
            self.clock_ns = value
        return value

    def now(self, wall_ns: int) -> int:
        return wall_ns if self.clock_ns is None else self.clock_ns


def port_in_use_line(port: int, option: str) -> str:
    return (
        f'port {port} is in use (another bridge or Foxglove server?): choose a free one with '
        f'{option}'
    )


_VARYING = re.compile(r'\d+\.\d+\.\d+\.\d+:\d+|\[[0-9a-f:]+\]:\d+|\d+')


def trouble_kind(record: logging.LogRecord) -> tuple[str, str]:
    """A log record's kind: its logger and message with addresses and numbers taken out."""
    return record.name, _VARYING.sub('#', record.getMessage())


@dataclass
class OnceFilter(logging.Filter):
    """Lets through the first warning or error of each kind (trouble_kind) and every record
    below warning: a client sending garbage or vanishing mid-message is logged once, not once
    per message or reconnection."""

    seen: set | None = None

    def __post_init__(self):
        super().__init__()
        self.seen = set() if self.seen is None else self.seen

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno < logging.WARNING:
            return True
        kind = trouble_kind(record)
        if kind in self.seen:
            return False
        self.seen.add(kind)
        return True
