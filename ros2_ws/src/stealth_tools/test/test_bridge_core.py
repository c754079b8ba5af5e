"""The bridge's decisions without ROS or a server: subscriptions, latched replay, /clock, the
port line, the once-per-kind log filter."""

import logging
import struct

import pytest
from stealth_tools.bridge_core import (
    LATCHED_DEPTH_MAX,
    VOLATILE_DEPTH,
    ClientSubscriptions,
    LatchedCache,
    OnceFilter,
    Timeline,
    clock_nanoseconds,
    port_in_use_line,
    relay_policies,
    wanted_topic,
)
from stealth_tools.qos_text import QosDescription

LATCHED = QosDescription(durability='transient_local', depth=1)
RELIABLE = QosDescription(reliability='reliable', history='keep_all')
BEST_EFFORT = QosDescription(reliability='best_effort')


def test_latched_topics_are_subscribed_reliable_transient_local_with_the_offered_depths():
    assert relay_policies([LATCHED]) == ('reliable', 'transient_local', 1)
    assert relay_policies([LATCHED, LATCHED]) == ('reliable', 'transient_local', 2)
    many = QosDescription(durability='transient_local', depth=1000)
    assert relay_policies([many]) == ('reliable', 'transient_local', LATCHED_DEPTH_MAX)


def test_volatile_topics_are_subscribed_best_effort_so_the_run_never_waits_for_the_bridge():
    for offers in ([RELIABLE], [BEST_EFFORT], [LATCHED, RELIABLE]):
        assert relay_policies(offers) == ('best_effort', 'volatile', VOLATILE_DEPTH)


def test_wanted_topics_are_all_or_the_requested_ones_and_always_the_clock():
    assert wanted_topic('/map', frozenset())
    assert wanted_topic('/map', frozenset({'/map'}))
    assert not wanted_topic('/scan', frozenset({'/map'}))
    assert wanted_topic('/clock', frozenset({'/map'}))


def test_the_latched_cache_keeps_the_last_messages_of_tracked_topics_only():
    cache = LatchedCache()
    cache.track('/markers', 2)
    for i in range(3):
        cache.add('/markers', bytes([i]), i)
        cache.add('/scan', bytes([i]), i)
    assert cache.messages('/markers') == [(b'\x01', 1), (b'\x02', 2)]
    assert cache.is_latched('/markers') and not cache.is_latched('/scan')
    assert cache.messages('/scan') == []


def clock_cdr(sec: int, nanosec: int, little: bool = True) -> bytes:
    header = b'\x00\x01\x00\x00' if little else b'\x00\x00\x00\x00'
    return header + struct.pack('<iI' if little else '>iI', sec, nanosec)


def test_clock_messages_decode_in_either_byte_order():
    assert clock_nanoseconds(clock_cdr(12, 345)) == 12_000_000_345
    assert clock_nanoseconds(clock_cdr(12, 345, little=False)) == 12_000_000_345


def test_clock_decoding_matches_rclpy_serialization():
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock

    message = Clock()
    message.clock.sec, message.clock.nanosec = 1234, 567_890_123
    assert clock_nanoseconds(serialize_message(message)) == 1234_567_890_123


@pytest.mark.parametrize(
    'data', [b'', b'\x00\x01\x00\x00\x01', b'\x07\x01\x00\x00' + bytes(8), clock_cdr(1, 10**9)]
)
def test_what_is_not_a_clock_message_gives_no_time(data):
    assert clock_nanoseconds(data) is None


def test_the_timeline_follows_the_clock_once_there_is_one():
    timeline = Timeline()
    assert timeline.now(wall_ns=5) == 5 and not timeline.follows_clock
    assert timeline.on_clock(b'junk') is None and timeline.now(wall_ns=6) == 6
    assert timeline.on_clock(clock_cdr(3, 0)) == 3 * 10**9
    assert timeline.now(wall_ns=7) == 3 * 10**9 and timeline.follows_clock


def test_a_published_clock_sets_the_time_to_0_until_it_ticks():
    timeline = Timeline()
    timeline.expect_clock()
    assert timeline.follows_clock and timeline.now(wall_ns=5) == 0
    timeline.on_clock(clock_cdr(2, 0))
    timeline.expect_clock()  # seen again by discovery: no step back
    assert timeline.now(wall_ns=5) == 2 * 10**9


def test_port_in_use_is_one_line_naming_the_port_and_the_option():
    line = port_in_use_line(8765, '--port N')
    assert '\n' not in line and '8765' in line and line.endswith('--port N')


def record(
    message: str, level: int = logging.ERROR, name: str = 'foxglove.ws'
) -> logging.LogRecord:
    return logging.LogRecord(name, level, __file__, 1, message, None, None)


def test_client_trouble_is_logged_once_per_kind_whatever_the_address():
    keep = OnceFilter()
    first = record('Invalid message from 127.0.0.1:46396: expected value at line 1 column 1')
    again = record('Invalid message from 127.0.0.1:50000: expected value at line 1 column 1')
    other = record('Dropping client 127.0.0.1:46412: handshake failed')
    assert keep.filter(first)
    assert not keep.filter(again)
    assert keep.filter(other)
    assert not keep.filter(record('Dropping client 127.0.0.1:5: handshake failed'))
    assert keep.filter(record('Registered client 127.0.0.1:1', logging.INFO))
    assert keep.filter(record('Registered client 127.0.0.1:1', logging.INFO))  # info: always


def test_a_topic_is_wanted_from_its_first_client_until_its_last_one_goes():
    clients = ClientSubscriptions()
    assert clients.add(channel=1, client=10)  # first: subscribe over DDS
    assert not clients.add(channel=1, client=11)  # a later one: resend the latched state
    assert not clients.add(channel=1, client=11)  # the same twice changes nothing
    assert not clients.remove(channel=1, client=10)
    assert not clients.remove(channel=1, client=99)  # never subscribed
    assert clients.remove(channel=1, client=11)  # last: unsubscribe
    assert clients.count(1) == 0
    assert not clients.remove(channel=2, client=10)  # unknown channel
