"""Replay of an MCAP onto its topics with the original timing, as `ros2 bag play`.

Messages are published as recorded (serialized bytes, never deserialized), in log-time order,
each when its log time comes due on a timeline that runs `rate` times real time. Each topic is
offered the QoS its recorded publishers offered (from `offered_qos_profiles`), so transient
local topics stay latched and reliable ones reliable. With `clock_hz`, /clock carries the
playback's bag time, so nodes under use_sim_time follow the replayed run.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
import threading
import time

from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy

from stealth_tools.bag_files import bag_files
from stealth_tools.bag_format import BagError
from stealth_tools.bag_reading import open_indexed_reader
from stealth_tools.clock_arithmetic import NS, PlaybackTimeline
from stealth_tools.interfaces import InterfaceError, message_class
from stealth_tools.qos_text import parse_offered_qos_yaml, playback_profile
from stealth_tools.ros_session import absolute_topic, qos_profile

ACK_TIMEOUT = 2.0  # s to let reliable subscribers acknowledge the last messages before exiting
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)  # rclcpp::ClockQoS


@dataclass(frozen=True)
class PlayOptions:
    """`bag play` options, with ros2 bag play's meaning."""

    bag: str
    rate: float = 1.0
    topics: tuple[str, ...] = ()
    clock_hz: float = 0.0
    loop: bool = False
    start_offset: float = 0.0  # s into the bag
    delay: float = 0.0  # s to wait (for discovery) before the first message
    bridge_port: int = 0  # > 0: serve the played topics to Foxglove on this port (--bridge)


class _Publishers:
    """A publisher per replayed topic, created with the recorded QoS; the files of a split bag
    share them (each file has channel ids of its own)."""

    def __init__(self, node, summaries, topics: tuple[str, ...]):
        self.node = node
        self.wanted = {absolute_topic(t) for t in topics}
        self.by_topic: dict[str, object] = {}
        self.reliable: list[object] = []
        bag_topics = {c.topic for summary in summaries for c in summary.channels.values()}
        if self.wanted and not self.wanted & bag_topics:
            raise BagError(
                f'none of {", ".join(sorted(self.wanted))} is in the bag '
                f'(it has {", ".join(sorted(bag_topics)) or "no topics"})'
            )
        self.by_file = [self._channels(summary) for summary in summaries]

    def _channels(self, summary) -> dict[int, object]:
        """{channel id: publisher} of one file."""
        by_channel = {}
        for channel_id, channel in sorted(summary.channels.items()):
            if self.wanted and channel.topic not in self.wanted:
                continue
            if channel.topic not in self.by_topic:
                publisher = self._create(summary, channel)
                if publisher is None:
                    continue
                self.by_topic[channel.topic] = publisher
            by_channel[channel_id] = self.by_topic[channel.topic]
        return by_channel

    def _create(self, summary, channel):
        node = self.node
        schema = summary.schemas.get(channel.schema_id)
        try:
            msg_type = message_class(schema.name if schema else '')
        except InterfaceError as error:
            node.get_logger().warning(f"Not replaying '{channel.topic}': {error}")
            return None
        offers = parse_offered_qos_yaml(channel.metadata.get('offered_qos_profiles', ''))
        profile, agreed = playback_profile(offers)
        if not agreed:
            node.get_logger().warning(
                f"'{channel.topic}': its publishers offered different QoS; replaying with "
                'the default profile'
            )
        publisher = node.create_publisher(msg_type, channel.topic, qos_profile(profile))
        if profile.reliability == 'reliable':
            self.reliable.append(publisher)
        return publisher

    @property
    def topics(self) -> list[str]:
        return sorted(self.by_topic)

    def wait_for_acks(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        for publisher in self.reliable:
            remaining = max(0.0, deadline - time.monotonic())
            publisher.wait_for_all_acked(Duration(nanoseconds=int(remaining * NS)))


class _ClockPublisher:
    """Publishes the timeline's bag time on /clock at a fixed wall-clock rate."""

    def __init__(self, node, hz: float):
        from rosgraph_msgs.msg import Clock

        self.message = Clock()
        self.publisher = node.create_publisher(Clock, '/clock', CLOCK_QOS) if hz > 0 else None
        self.period = 1.0 / hz if hz > 0 else None
        self.next_tick = 0.0

    def start(self, wall: float) -> None:
        self.next_tick = wall

    def due_before(self, wall: float) -> float:
        """The next tick if it comes before `wall`, else `wall`."""
        return min(wall, self.next_tick) if self.publisher else wall

    def tick_if_due(self, timeline: PlaybackTimeline, now: float) -> None:
        if self.publisher is None or now < self.next_tick:
            return
        stamp = timeline.bag_time(self.next_tick)
        self.message.clock.sec, self.message.clock.nanosec = divmod(stamp, NS)
        self.publisher.publish(self.message)
        self.next_tick += self.period


def _wait_until(
    due: float, timeline: PlaybackTimeline, clock: _ClockPublisher, stop: threading.Event
) -> bool:
    """Sleep until `due`, ticking /clock on the way; False if stopped."""
    while True:
        now = time.monotonic()
        clock.tick_if_due(timeline, now)
        if now >= due:
            return True
        if stop.wait(max(0.0, clock.due_before(due) - now)):
            return False


def play(node, options: PlayOptions, stop: threading.Event) -> int:
    """Publish the bag's messages (every file of a split bag, in order) on schedule; the number
    published."""
    if options.rate <= 0:
        raise BagError('--rate must be positive')
    paths = bag_files(options.bag)
    published = 0
    with contextlib.ExitStack() as files:
        readers = [open_indexed_reader(files.enter_context(open(p, 'rb'))) for p in paths]
        summaries = [reader.get_summary() for reader in readers]
        publishers = _Publishers(node, summaries, options.topics)
        clock = _ClockPublisher(node, options.clock_hz)
        shown = str(paths[0]) if len(paths) == 1 else f'{options.bag} ({len(paths)} files)'
        node.get_logger().info(
            f'Playing {shown} ({", ".join(publishers.topics) or "no topics"}) at rate '
            f'{options.rate:g}'
        )
        if stop.wait(options.delay):
            return 0
        start = min(s.statistics.message_start_time for s in summaries)
        first = start + round(options.start_offset * NS)
        while not stop.is_set():
            timeline = PlaybackTimeline(first, time.monotonic(), options.rate)
            clock.start(timeline.wall_start)
            this_pass = 0
            for reader, by_channel in zip(readers, publishers.by_file, strict=True):
                messages = reader.iter_messages(log_time_order=True, starting_at=first)
                for _, channel, message in messages:
                    if channel.id not in by_channel:
                        continue
                    if not _wait_until(
                        timeline.wall_time(message.log_time), timeline, clock, stop
                    ):
                        break
                    by_channel[channel.id].publish(bytes(message.data))
                    this_pass += 1
                if stop.is_set():
                    break
            published += this_pass
            if not options.loop or not this_pass:
                break
        publishers.wait_for_acks(ACK_TIMEOUT)
    return published


def play_bag(options: PlayOptions, stop: threading.Event) -> int:
    """`bag play` in an initialised rclpy session: a node, the playback, cleanup; with
    `bridge_port`, the Foxglove bridge beside it (its own executor, in a thread)."""
    import rclpy

    node = rclpy.create_node('player', enable_rosout=False)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    bridge = _start_bridge(options.bridge_port, stop) if options.bridge_port else None
    try:
        count = play(node, options, stop)
        node.get_logger().info(f'Published {count} messages')
    finally:
        executor.shutdown()
        node.destroy_node()
        if bridge is not None:
            bridge()
    return 0


def _start_bridge(port: int, stop: threading.Event):
    """The bridge node spinning in a thread; the function that stops it."""
    from rclpy.parameter import Parameter
    from stealth_node_kit.parameters import StartupError

    from stealth_tools.bridge import Bridge
    from stealth_tools.ros_session import spin_until

    try:
        bridge = Bridge(
            port_option='--bridge-port PORT',
            parameter_overrides=[Parameter('port', value=port)],
        )
    except StartupError as error:
        raise BagError(f'--bridge: {error}') from None
    executor = SingleThreadedExecutor()
    executor.add_node(bridge)
    done = threading.Event()
    thread = threading.Thread(
        target=spin_until, args=(executor, done, stop.is_set), name='bridge', daemon=True
    )
    thread.start()

    def finish() -> None:
        done.set()
        thread.join()
        bridge.close()
        executor.shutdown()
        bridge.destroy_node()

    return finish
