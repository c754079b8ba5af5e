"""The bridge node (``bridge``): the run's DDS topics relayed to the Foxglove app over Foxglove's
own WebSocket server (the ``foxglove-sdk`` package), as foxglove_bridge does on a full ROS
install, which PyPI does not have.

    bridge --ros-args -p port:=8765          # or: stealth bridge [--port 8765] [--topics ...]

The Foxglove app connects to ``ws://localhost:PORT`` (Open connection, Foxglove WebSocket).

## Topics

Every topic with publishers (or the ``topics`` asked for, plus /clock) becomes a channel with
encoding ``cdr`` and a ``ros2msg`` schema holding the type's full definition with its nested
types (the text the recorder writes, stealth_tools.interfaces); messages are relayed as the CDR
bytes DDS delivered, never deserialized. Topics that appear later are advertised as discovery
(every ``discovery_period``) sees them. A topic is subscribed over DDS only while a client
subscribes to its channel (as foxglove_bridge), /clock always. Transient local topics (/map,
searchlight_markers, searchlights, rl_env/rl_env_description, visibility_grid, planned_path)
are subscribed transient local and their latest messages kept: a client that subscribes late
gets them again (the other clients then see them once more, the same content). Volatile
topics are subscribed best effort, so a bridge that falls behind drops view frames and never
holds back the run. /clock, when
published, sets the message times and the Foxglove timeline (server time), as foxglove_bridge
under use_sim_time; without it, the wall clock does.

## Services

None: no ROS services, and the WebSocket server's one capability is Time (the timeline).

## Parameters

The table in ``stealth_tools.bridge_parameters``: ``port`` (the server's TCP port),
``address`` (where it listens; 0.0.0.0 for a Foxglove app on another machine), ``topics``
(unset: every topic with publishers), ``discovery_period``, ``include_hidden_topics``.

## Bad input

A port in use stops the node with one line naming the port and the parameter (exit
2; ``stealth bridge`` names --port, exit 1); a topic whose type cannot be resolved (package not
installed, several types) is skipped with a warning naming it; a client that sends garbage or
disconnects mid-message is dropped by the server and logged once per kind of trouble.
"""

from __future__ import annotations

import logging
import queue
import sys
import time

from rclpy.clock import Clock, ClockType
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from stealth_node_kit.parameters import StartupError, declare_parameters
from stealth_node_kit.running import StartupNode, run_node

from stealth_tools.bridge_core import (
    CLOCK_TOPIC,
    MESSAGE_ENCODING,
    SCHEMA_ENCODING,
    ClientSubscriptions,
    LatchedCache,
    OnceFilter,
    Timeline,
    port_in_use_line,
    relay_policies,
    wanted_topic,
)
from stealth_tools.bridge_parameters import PARAMETERS
from stealth_tools.ros_session import (
    absolute_topic,
    describe_qos,
    discovered_topics,
    raw_subscription,
    ros_session,
    spin_until,
)

NODE_NAME = 'bridge'
EVENT_PERIOD = 0.05  # s: how soon a client's (un)subscription is acted on
WALL_TIME_PERIOD = 0.1  # s between server time broadcasts while no /clock is published
SDK_LOGGER = 'foxglove'  # the Python logger the SDK's server logs to

PORT_OPTION = '-p port:=N (stealth train: --set bridge.port=N)'


def _listener(events: queue.SimpleQueue):
    """The server's callbacks (they run on its own threads): (subscribed?, client, channel)
    queued for the node's executor, which does the work."""
    from foxglove.websocket import ServerListener

    class Listener(ServerListener):
        def on_subscribe(self, client, channel) -> None:
            events.put((True, client.id, channel.id))

        def on_unsubscribe(self, client, channel) -> None:
            events.put((False, client.id, channel.id))

    return Listener()


class _SdkLog(logging.Handler):
    """The SDK's log records into the node's logger, each kind of client trouble once."""

    def __init__(self, logger):
        super().__init__(logging.INFO)
        self.ros_logger = logger
        self.addFilter(OnceFilter())

    def emit(self, record: logging.LogRecord) -> None:
        text = f'websocket: {record.getMessage()}'
        if record.levelno >= logging.WARNING:
            self.ros_logger.warning(text + ' (ignored; further ones like it are not logged)')
        else:
            self.ros_logger.info(text)


class Bridge(StartupNode):
    """Discovers topics, relays their CDR bytes to the WebSocket server's channels."""

    def __init__(self, port_option: str = PORT_OPTION, **kwargs):
        self.port_option = port_option
        super().__init__(NODE_NAME, **kwargs)

    def set_up(self) -> None:
        import foxglove
        from foxglove.websocket import Capability

        values = declare_parameters(self, PARAMETERS)
        self.port = values['port']
        self.include_hidden = values['include_hidden_topics']
        topics = values['topics'] or []
        self.requested = frozenset(absolute_topic(t) for t in topics if t)
        self.channels: dict[str, object] = {}  # topic -> foxglove Channel
        self.topic_of: dict[int, str] = {}  # channel id -> topic
        self.skipped: set[str] = set()
        self.relayed = 0
        self.latched = LatchedCache()
        self.timeline = Timeline()
        self.watchers = ClientSubscriptions()
        self.relays: dict[str, tuple] = {}  # topic -> (message type, QoS, forward callback)
        self.dds: dict[str, object] = {}  # topic -> its DDS subscription, while wanted
        self._events: queue.SimpleQueue = queue.SimpleQueue()
        self._sdk_log = _SdkLog(self.get_logger())
        sdk_logger = logging.getLogger(SDK_LOGGER)
        sdk_logger.setLevel(logging.INFO)
        sdk_logger.addHandler(self._sdk_log)
        sdk_logger.propagate = False
        foxglove.set_log_level('INFO')
        self.fox_context = foxglove.Context()
        try:
            self.server = foxglove.start_server(
                name='stealth-nav',
                host=values['address'],
                port=self.port,
                capabilities=[Capability.Time],
                supported_encodings=[MESSAGE_ENCODING],
                server_listener=_listener(self._events),
                context=self.fox_context,
            )
        except RuntimeError as error:
            sdk_logger.removeHandler(self._sdk_log)
            if 'in use' in str(error):
                raise StartupError(port_in_use_line(self.port, self.port_option)) from None
            raise StartupError(
                f'cannot start the WebSocket server on port {self.port}: {error}'
            ) from None
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(values['discovery_period'], self.discover, clock=steady)
        self.create_timer(EVENT_PERIOD, self._client_events, clock=steady)
        self.create_timer(WALL_TIME_PERIOD, self._wall_time, clock=steady)
        self.get_logger().info(
            f'Foxglove: open connection ws://localhost:{self.server.port} '
            f'(listening on {values["address"]})'
        )
        self.discover()

    @property
    def url(self) -> str:
        return f'ws://localhost:{self.server.port}'

    def discover(self) -> None:
        """A channel for every wanted topic that has publishers now (subscribed when wanted)."""

        def new(topic: str) -> bool:
            fresh = topic not in self.channels and topic not in self.skipped
            return fresh and wanted_topic(topic, self.requested)

        include_hidden = self.include_hidden or bool(self.requested)
        found = list(discovered_topics(self, include_hidden, new, self._skip))
        if any(topic == CLOCK_TOPIC for topic, *_ in found):
            self.timeline.expect_clock()  # from now on, times are the clock's (0 until it ticks)
        for topic, *rest in found:
            self._relay(topic, *rest)

    def _skip(self, topic: str, why: str) -> None:
        self.skipped.add(topic)
        self.get_logger().warning(f"Not relaying '{topic}': {why}")

    def _relay(self, topic: str, type_name: str, msg_type, definition: str, offers) -> None:
        from foxglove import Channel, Schema

        reliability, durability, depth = relay_policies(
            [describe_qos(info.qos_profile) for info in offers]
        )
        schema = Schema(name=type_name, encoding=SCHEMA_ENCODING, data=definition.encode())
        channel = Channel(
            topic, schema=schema, message_encoding=MESSAGE_ENCODING, context=self.fox_context
        )
        self.channels[topic] = channel
        self.topic_of[channel.id()] = topic
        if durability == 'transient_local':
            self.latched.track(topic, depth)
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=depth,
            reliability=ReliabilityPolicy[reliability.upper()],
            durability=DurabilityPolicy[durability.upper()],
        )
        self.relays[topic] = (msg_type, qos, self._forwarder(topic, channel))
        if topic == CLOCK_TOPIC:  # the timeline, whoever watches
            self._subscribe(topic)
        self.get_logger().info(
            f"Advertising '{topic}' ({type_name}; subscribed {reliability}, {durability} while "
            'a client wants it)'
        )

    def _subscribe(self, topic: str) -> None:
        msg_type, qos, forward = self.relays[topic]
        self.dds[topic] = raw_subscription(self, topic, msg_type, qos, forward)

    def _forwarder(self, topic: str, channel):
        timeline, latched, log = self.timeline, self.latched, channel.log
        is_clock, keep = topic == CLOCK_TOPIC, latched.is_latched(topic)
        server = self.server

        def forward(data: bytes, _info: dict) -> None:
            if is_clock and timeline.on_clock(data) is not None:
                server.broadcast_time(timeline.clock_ns)
            log_time = timeline.now(time.time_ns())
            if keep:
                latched.add(topic, data, log_time)
            log(data, log_time=log_time)
            self.relayed += 1

        return forward

    def _client_events(self) -> None:
        """Act on the clients' (un)subscriptions since the last call: a DDS subscription for a
        channel's first client (transient local ones bring the latched state with them), the
        kept latched messages for a later one, and no DDS subscription once none is left."""
        resend = set()
        while not self._events.empty():
            subscribed, client, channel = self._events.get()
            topic = self.topic_of.get(channel)
            if topic is None:
                continue
            if not subscribed:
                if self.watchers.remove(channel, client) and topic != CLOCK_TOPIC:
                    self.destroy_subscription(self.dds.pop(topic))
                continue
            self.watchers.add(channel, client)
            if topic not in self.dds:
                self._subscribe(topic)
            elif self.latched.is_latched(topic):
                resend.add(topic)
        now = self.timeline.now(time.time_ns())
        for topic in resend:
            for data, _ in self.latched.messages(topic):
                self.channels[topic].log(data, log_time=now)  # still the current state

    def _wall_time(self) -> None:
        if not self.timeline.follows_clock:
            self.server.broadcast_time(time.time_ns())

    def close(self) -> None:
        """Stop the server; a line of totals."""
        logging.getLogger(SDK_LOGGER).removeHandler(self._sdk_log)  # its logger may be gone
        self.server.stop()
        logger = self.get_logger() if self.context.ok() else None
        line = f'relayed {self.relayed} messages on {len(self.channels)} topics' + (
            f'; skipped {", ".join(sorted(self.skipped))}' if self.skipped else ''
        )
        if logger is not None:
            logger.info(line)
        else:
            import rclpy.logging

            rclpy.logging.get_logger(f'{NODE_NAME}.exit').info(line)


def serve(overrides: list[Parameter], port_option: str, prog: str) -> int:
    """`stealth bridge`: the node in this process until SIGINT/SIGTERM; 1 and one line on
    stderr when it cannot start."""
    with ros_session() as stop:
        try:
            node = Bridge(port_option=port_option, parameter_overrides=overrides)
        except StartupError as error:
            print(f'{prog}: {error}', file=sys.stderr)
            return 1
        print(f'{prog}: open Foxglove and connect to {node.url} (Ctrl-C stops)', file=sys.stderr)
        from rclpy.executors import SingleThreadedExecutor

        executor = SingleThreadedExecutor()
        executor.add_node(node)
        try:
            spin_until(executor, stop)
        finally:
            node.close()
            executor.shutdown()
            node.destroy_node()
    return 0


def main(args: list[str] | None = None) -> int:
    return run_node(Bridge, NODE_NAME, args=args, on_exit=Bridge.close)


if __name__ == '__main__':
    sys.exit(main())
