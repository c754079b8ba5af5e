"""The recorder node (``recorder``): every topic on the graph, or a chosen set, into an MCAP as
rosbag2 does.

    recorder --ros-args -p output:=run.mcap -p topics:="['/rl_env/rl_state_reward']"

## Topics

Subscribes every topic with publishers (hidden ones with ``include_hidden_topics``), or the
``topics`` asked for; a topic with several types or a type not installed is skipped with a
warning naming it. Discovery polls the graph every ``discovery_period`` (steady time), so
topics that appear later are recorded too. Each topic is subscribed raw (CDR bytes, never
deserialized) with what all of its publishers offer: reliable only if all are reliable,
transient local only if all are (so latched /map and rl_env/rl_env_description arrive), and
KEEP_ALL history, so a slow moment makes DDS hold the publisher back instead of dropping a
step; a loss DDS does report is logged. The log time is the ROS clock at reception (sim time
under use_sim_time, waiting for /clock first, as rosbag2); the publish time is the
publisher's source timestamp.

## Services

None.

## Parameters

The table in ``stealth_tools.recorder_parameters`` (defaults, ranges; all read-only):
``output`` (the file; default rosbag2's name, rosbag2_YYYY_MM_DD-HH_MM_SS), ``topics`` (unset:
every topic), ``discovery_period`` (s), ``max_chunk_duration`` (s) and ``chunk_size`` (bytes):
when a chunk is closed, ``compression`` of the chunks (zstd, lz4, none),
``include_hidden_topics``, ``batch_period`` (s, 0 to MAX_BATCH_PERIOD; see Batches).

## Stopping

SIGINT and SIGTERM close the file with summary and indexes (a stop stuck for STOP_LIMIT s
writes every thread's stack to stderr and exits 1: an orphan of a killed orchestrator has no
one to SIGKILL it, and the file is recovered as after a SIGKILL); after a SIGKILL at most
~max_chunk_duration * 1.5 + batch_period is missing and `stealth bag recover` restores an
indexed file. A full disk stops the recorder with one line naming the file and the space left,
exit code EXIT_DISK_FULL (4): the file keeps the chunks written before, for `stealth bag
recover`.

## Batches

Messages are taken in batches: the recorder wakes at most once per `batch_period` and then takes
what every topic's queue holds (KEEP_ALL), writing the batch in log-time order; while messages
pour in (a batch took BUSY_TAKE from one queue) it takes them without pausing. rclpy's executor
costs about a quarter of a millisecond per wake-up, several times the cost of writing a message,
and a training run's ~1,200 messages/s arrive one at a time, so waking for each made the
recorder the run's second-largest CPU user. The log time is
still each message's reception time, so batching does not move it; under use_sim_time it is the
simulated time at reception: that of the latest ``/clock`` message received before it (of the
recorded ``/clock``; the ROS clock when the message is taken while ``/clock`` is not recorded).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
import faulthandler
import sys
import time

from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock as ClockMessage
from stealth_node_kit.full_disk import EXIT_DISK_FULL, disk_full_message, is_disk_full
from stealth_node_kit.on_demand import OnDemand, clock_on_demand
from stealth_node_kit.parameters import StartupError, declare_parameters
from stealth_node_kit.running import StartupNode

from stealth_tools.bag_format import BagError, BagWriter
from stealth_tools.qos_text import subscription_policies
from stealth_tools.recorder_parameters import PARAMETERS
from stealth_tools.ros_session import (
    DRAIN_BATCH,
    absolute_topic,
    describe_qos,
    discovered_topics,
    raw_subscription,
    ros_session,
    spin_until,
)

NODE_NAME = 'recorder'
# A batch that took this many from one queue means messages pour in: the next is taken without
# a pause, so that a queue never nears DDS's limit of a KEEP_ALL reader (5,000 samples; beyond
# it a best-effort sample is dropped and a reliable one waits for the writer's repair).
BUSY_TAKE = 100
CLOSING_TAKE = 2.0  # s: the longest a stop spends taking what is still queued
STOP_LIMIT = 30.0  # s from the stop to the end of the process before a stuck stop dumps, exits 1


def default_output() -> str:
    """rosbag2's default bag name: rosbag2_YYYY_MM_DD-HH_MM_SS (a bag directory)."""
    return time.strftime('rosbag2_%Y_%m_%d-%H_%M_%S')


@dataclass(frozen=True)
class RecorderSettings:
    """The recorder's parameters (names as on the command line: -p name:=value)."""

    output: str = PARAMETERS['output'].default
    topics: tuple[str, ...] = ()
    discovery_period: float = PARAMETERS['discovery_period'].default
    max_chunk_duration: float = PARAMETERS['max_chunk_duration'].default
    chunk_size: int = PARAMETERS['chunk_size'].default
    compression: str = PARAMETERS['compression'].default
    include_hidden_topics: bool = PARAMETERS['include_hidden_topics'].default
    batch_period: float = PARAMETERS['batch_period'].default

    def parameters(self) -> list[Parameter]:
        """As parameter overrides for the node (how `stealth bag record` configures it)."""
        topics = [Parameter('topics', value=list(self.topics))] if self.topics else []
        return topics + [
            Parameter('output', value=self.output),
            Parameter('discovery_period', value=float(self.discovery_period)),
            Parameter('max_chunk_duration', value=float(self.max_chunk_duration)),
            Parameter('chunk_size', value=int(self.chunk_size)),
            Parameter('compression', value=self.compression),
            Parameter('include_hidden_topics', value=bool(self.include_hidden_topics)),
            Parameter('batch_period', value=float(self.batch_period)),
        ]


class Recorder(StartupNode):
    """Subscribes to topics as they appear and writes what arrives to a BagWriter."""

    def __init__(self, **node_kwargs):
        super().__init__(NODE_NAME, **node_kwargs)

    def set_up(self) -> None:
        self.settings = self._declare_settings()
        self.bag = BagWriter(
            self.settings.output or default_output(),
            compression=self.settings.compression,
            chunk_size=self.settings.chunk_size,
            max_chunk_duration=self.settings.max_chunk_duration,
        )
        self.requested = {absolute_topic(t) for t in self.settings.topics if t}
        self.recorded: dict[str, object] = {}
        self.skipped: set[str] = set()
        self.use_sim_time = bool(self.get_parameter('use_sim_time').value)
        # Its ROS clock is read only at those moments: /clock waits in its queue till then,
        # rather than waking the recorder at each message (the recorded /clock is another
        # subscription, taken in batches).
        self._clock_messages = OnDemand()
        clock_on_demand(self, self._clock_messages)
        self._told_waiting_for_clock = False
        # (subscription, message type, topic) of every recorded topic, for taking a batch
        self._queues: list[tuple[object, object, str]] = []
        self._batch_period = self.settings.batch_period
        self._sim_ns = 0  # under use_sim_time: the latest /clock taken (ns; 0: none yet)
        self._last_batch = 0.0  # time.monotonic() when the last batch was taken
        self._largest_take = 0  # the most messages the last batch took from one queue
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(self.settings.discovery_period, self.discover, clock=steady)
        flush_period = self.settings.max_chunk_duration / 2
        self.create_timer(flush_period, self.bag.flush_if_due, clock=steady)
        self.get_logger().info(
            f'Recording to {self.bag.paths.mcap} ({self.settings.compression} chunks closed '
            f'every {self.settings.max_chunk_duration:g} s or {self.settings.chunk_size} bytes)'
        )
        self.discover()

    def _declare_settings(self) -> RecorderSettings:
        """The parameters declared with their table's descriptors: rclpy refuses a value out
        of range (StartupError naming it)."""
        values = declare_parameters(self, PARAMETERS)
        topics = values.pop('topics')
        return RecorderSettings(topics=tuple(topics or ()), **values)

    def _clock_started(self) -> bool:
        """Under sim time, nothing is recorded before /clock (log times would be 0)."""
        if not self.use_sim_time or self._now_ns() > 0:
            return True
        if not self._told_waiting_for_clock:
            self.get_logger().info('use_sim_time set: waiting for /clock before recording')
            self._told_waiting_for_clock = True
        return False

    def _wanted(self, topic: str) -> bool:
        if topic in self.recorded or topic in self.skipped:
            return False
        return not self.requested or topic in self.requested

    def discover(self) -> None:
        """Subscribe to every wanted topic that has publishers and is not recorded yet."""
        if not self._clock_started():
            return
        include_hidden = self.settings.include_hidden_topics or bool(self.requested)
        for topic, *found in discovered_topics(self, include_hidden, self._wanted, self._skip):
            self._record(topic, *found)

    def _skip(self, topic: str, why: str) -> None:
        self.skipped.add(topic)
        self.get_logger().warning(f"Not recording '{topic}': {why}")

    def _record(self, topic: str, type_name: str, msg_type, definition: str, offers) -> None:
        offered = [describe_qos(info.qos_profile) for info in offers]
        hashes = {str(info.topic_type_hash) for info in offers} - {'INVALID'}
        self.bag.add_topic(
            topic, type_name, definition, offered, hashes.pop() if len(hashes) == 1 else ''
        )
        reliability, durability = subscription_policies(offered)
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_ALL,
            reliability=ReliabilityPolicy[reliability.upper()],
            durability=DurabilityPolicy[durability.upper()],
        )
        self.recorded[topic] = self._subscribe(topic, msg_type, qos)
        self.get_logger().info(f"Subscribed to topic '{topic}' ({reliability}, {durability})")

    def _subscribe(self, topic: str, msg_type, qos: QoSProfile):
        def report_loss(status) -> None:
            self.get_logger().warning(
                f"'{topic}': DDS lost {status.total_count_change} messages "
                f'({status.total_count} so far)'
            )

        write = self.bag.write
        if self._batch_period > 0.0:

            def record_batch(data: bytes, info: dict) -> None:
                self._take_batch(topic, data, info)

            subscription = raw_subscription(
                self, topic, msg_type, qos, record_batch, report_loss, drain=False
            )
            # /clock is taken last, so what a batch takes of other topics has the /clock
            # received before it (_on_sim_time).
            at = len(self._queues) if topic == '/clock' else 0
            self._queues.insert(at, (subscription, msg_type, topic))
            return subscription

        def record_one(data: bytes, info: dict) -> None:
            write(topic, data, *self._times(info))

        return raw_subscription(self, topic, msg_type, qos, record_one, report_loss)

    def _times(self, info: dict) -> tuple[int, int]:
        """(log time, publish time) in ns of a message taken now with this message info; in
        batches under use_sim_time, the wall time of reception instead (see _on_sim_time)."""
        if self.use_sim_time and not self._batch_period:
            return self._now_ns(), info.get('source_timestamp', 0)
        received = info.get('received_timestamp', 0)
        if self.use_sim_time:
            received = received or time.time_ns()
        return received or self._now_ns(), info.get('source_timestamp', 0)

    def _now_ns(self) -> int:
        """The ROS clock now (ns), with the latest /clock taken first under use_sim_time."""
        self._clock_messages.drain()
        return self.get_clock().now().nanoseconds

    def _on_sim_time(self, batch: list) -> list:
        """A batch in order of reception (wall ns) with log times in simulated time: that of
        the latest /clock received before each message (the ROS clock before any is taken)."""
        stamped = []
        for _, publish_time, topic, data in batch:
            if topic == '/clock':
                clock = deserialize_message(data, ClockMessage).clock
                self._sim_ns = clock.sec * 1_000_000_000 + clock.nanosec
            log_time = self._sim_ns or self._now_ns()
            stamped.append((log_time, publish_time, topic, data))
        return stamped

    def _take_batch(self, topic: str, data: bytes, info: dict) -> None:
        """A message woke the recorder: unless messages are pouring in, let batch_period pass
        since the last batch; then take what every queue holds and write it in log-time order.
        """
        pause = self._last_batch + self._batch_period - time.monotonic()
        if pause > 0.0 and self._largest_take < BUSY_TAKE:
            time.sleep(pause)
        self._write_batch([(*self._times(info), topic, data)])

    def _write_batch(self, batch: list) -> None:
        """Add what every queue holds (at most DRAIN_BATCH each, so timers get a turn; what is
        left wakes the recorder again) to ``batch`` (log time, publish time, topic, CDR bytes)
        and write it all in log-time order."""
        largest = 0
        for subscription, msg_type, topic in self._queues:
            handle, taken_here = subscription.handle, 0
            with handle:
                while taken_here < DRAIN_BATCH:
                    taken = handle.take_message(msg_type, True)
                    if taken is None:
                        break
                    batch.append((*self._times(taken[1]), topic, taken[0]))
                    taken_here += 1
            largest = max(largest, taken_here)
        batch.sort(key=lambda item: item[0])
        if self.use_sim_time:
            batch = self._on_sim_time(batch)
        for log_time, publish_time, topic, data in batch:
            self.bag.write(topic, data, log_time, publish_time)
        self._last_batch, self._largest_take = time.monotonic(), largest

    def close(self) -> str:
        """Take what is still queued (a stop can come between batches; for at most
        CLOSING_TAKE seconds, should publishers outpace the takes), finish the bag; a line
        saying what was recorded."""
        deadline = time.monotonic() + CLOSING_TAKE
        self._write_batch([])
        while self._largest_take == DRAIN_BATCH and time.monotonic() < deadline:
            self._write_batch([])
        self.bag.close()
        return (
            f'Recorded {self.bag.message_count} messages on {len(self.bag.topics)} topics '
            f'to {self.bag.paths.directory or self.bag.paths.mcap}'
        )


def record(args: list[str] | None = None, overrides: list[Parameter] | None = None) -> int:
    """Run the recorder until SIGINT or SIGTERM; 1 with one line on stderr if it cannot."""
    try:
        return _record(args, overrides)
    finally:  # the stop's watchdog, once rclpy is shut down too
        faulthandler.cancel_dump_traceback_later()


def _record(args, overrides) -> int:
    with ros_session(args) as stop:
        try:
            node = Recorder(parameter_overrides=overrides or [])
        except (BagError, ParameterException, StartupError) as error:
            print(f'{NODE_NAME}: {error}', file=sys.stderr)
            return 1
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        status = 0
        try:
            spin_until(executor, stop)
        except OSError as error:
            status = _write_failed(node.bag.paths.mcap, 'writing', error)
        finally:
            faulthandler.dump_traceback_later(STOP_LIMIT, exit=True)  # cancelled by record()
            if status == EXIT_DISK_FULL:  # closing would only fail the same way
                node.bag.abandon()
            else:
                try:
                    node.get_logger().info(node.close())
                except OSError as error:
                    status = _write_failed(node.bag.paths.mcap, 'closing', error)
            executor.shutdown()
            node.destroy_node()
        return status


def _write_failed(path, doing: str, error: OSError) -> int:
    """One line on stderr; EXIT_DISK_FULL for a full disk (the recorder is then not restarted:
    a new file would not fit either), else 1."""
    full = is_disk_full(error)
    line = f'{disk_full_message(path)}; stopping' if full else f'{doing} {path} failed: {error}'
    with contextlib.suppress(OSError):  # stderr is a log file, likely on the same full disk
        print(f'{NODE_NAME}: {line}', file=sys.stderr, flush=True)
    return EXIT_DISK_FULL if full else 1


def main(args: list[str] | None = None) -> int:
    return record(args)


if __name__ == '__main__':
    sys.exit(main())
