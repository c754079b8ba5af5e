"""Our recordings read by the tools users open them with, not by the library that wrote them.

The recorder records real traffic (std_msgs, nav_msgs, visualization_msgs and stealth_interfaces
types: nested messages, fixed and variable arrays, arrays of messages, strings, latched topics)
and two independent readers check the result:

- rosbags (Ternaris' pure-Python implementation of rosbag2's metadata.yaml and MCAP storage, the
  closest thing to `ros2 bag info/play` without a ROS install): the bag directory and the lone
  .mcap open, metadata and per-topic counts agree with the file, every connection has the right
  type, definition, serialization and offered QoS, the RIHS01 hash of the stored definition is
  the publisher's type hash, and every message decodes with types built from nothing but the
  definitions stored in the bag;
- Foxglove's own JavaScript libraries (tools/mcap-js-check: @mcap/core indexed and streaming
  readers with CRCs checked, @foxglove/rosmsg, @foxglove/rosmsg2-serialization), as Foxglove
  Studio opens a file.

Both also read what `stealth bag recover` salvaged from a recording cut off mid-chunk.
"""

import collections
import json
import shutil
import signal
import subprocess
import time
from typing import NamedTuple

from mcap.reader import make_reader
import pytest
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_support import REPO_ROOT, node_tool, wait_for_output
from rosbags.interfaces import MessageDefinitionFormat, QosDurability, QosReliability
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from stealth_tools.bag_recover import recover
from stealth_tools.interfaces import definition_text
from test_recorder import COUNT, RATE, RECORDER, TRAFFIC
import yaml

JS_CHECK = REPO_ROOT / 'tools' / 'mcap-js-check'

LATCHED_TOPICS = ('/rl_env/rl_env_description', '/searchlights', '/searchlight_markers')
VOLATILE_TOPICS = ('/chatter', '/odom', '/rl_env/step_info')


class Recorded(NamedTuple):
    """One topic as the mcap library reads it."""

    type: str
    type_hash: str  # the channel's topic_type_hash: what the publishers announced over DDS
    log_times: list[int]


def mcap_contents(path) -> dict[str, Recorded]:
    """Every channel of the file with the log times of its messages, read with mcap."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        topics = {
            channel.topic: Recorded(
                summary.schemas[channel.schema_id].name, channel.metadata['topic_type_hash'], []
            )
            for channel in summary.channels.values()
        }
        for _, channel, message in reader.iter_messages():
            topics[channel.topic].log_times.append(message.log_time)
    return topics


def read_with_rosbags(path, expected):
    """Open `path` (bag directory or .mcap) with rosbags, check everything; decoded messages.

    Types are registered from each connection's stored definition only (an empty typestore),
    as a user's tool without our packages would.
    """
    typestore = get_typestore(Stores.EMPTY)
    decoded = collections.defaultdict(list)
    with Reader(path) as reader:
        log_times = [t for topic in expected.values() for t in topic.log_times]
        assert reader.message_count == len(log_times)
        assert reader.start_time == min(log_times)
        assert reader.duration == max(log_times) - min(log_times) + 1  # rosbags' convention
        assert {c.topic: c.msgcount for c in reader.connections} == {
            name: len(topic.log_times) for name, topic in expected.items()
        }
        for connection in reader.connections:
            type_name = expected[connection.topic].type
            assert connection.msgtype == type_name
            assert connection.msgdef.format == MessageDefinitionFormat.MSG
            assert connection.msgdef.data == definition_text(type_name)
            assert connection.ext.serialization_format == 'cdr'
            (offer, *_) = connection.ext.offered_qos_profiles
            assert offer.reliability == QosReliability.RELIABLE
            if connection.topic in LATCHED_TOPICS:
                assert offer.durability == QosDurability.TRANSIENT_LOCAL
            elif connection.topic in VOLATILE_TOPICS:
                assert offer.durability == QosDurability.VOLATILE
            typestore.register(get_types_from_msg(connection.msgdef.data, type_name))
            # The stored definition hashes to what the publishers announced over DDS (rosbags
            # reads the hash from metadata.yaml; of a lone .mcap it leaves it empty).
            type_hash = typestore.hash_rihs01(type_name)
            assert expected[connection.topic].type_hash == type_hash, connection.topic
            assert connection.digest == ('' if path.is_file() else type_hash)
        for connection, timestamp, data in reader.messages():
            decoded[connection.topic].append(
                (timestamp, typestore.deserialize_cdr(data, connection.msgtype))
            )
    counts = {name: len(topic.log_times) for name, topic in expected.items() if topic.log_times}
    assert {topic: len(messages) for topic, messages in decoded.items()} == counts
    return decoded


def foxglove_check(path):
    """tools/mcap-js-check's JSON report of `path`; fails (never skips) without Node.js."""
    node = node_tool(JS_CHECK, '@mcap/core')
    result = subprocess.run(
        [node, str(JS_CHECK / 'check.mjs'), str(path), '--samples'],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.stdout, f'check.mjs printed nothing: {result.stderr}'
    report = json.loads(result.stdout)
    assert result.returncode == 0 and report['ok'], report['problems'] or result.stderr
    return report


def assert_foxglove_agrees(report, expected):
    """Per topic: the type, every message in both passes, nothing undecodable."""
    assert report['profile'] == 'ros2' and 'rosbag2' in report['metadata']
    assert report['messages'] == sum(len(topic.log_times) for topic in expected.values())
    for name, topic in expected.items():
        entry = report['topics'][name]
        assert (entry['schema'], entry['schema_encoding'], entry['message_encoding']) == (
            topic.type,
            'ros2msg',
            'cdr',
        )
        assert entry['count'] == entry['streamed_count'] == len(topic.log_times)
        assert entry['decode_errors'] == entry['trailing_bytes'] == 0


def publish_latched_extras(node):
    """Arrays of nested messages on two more latched topics; the publishers, to keep alive."""
    from geometry_msgs.msg import Point
    from stealth_interfaces.msg import Searchlight, SearchlightArray
    from visualization_msgs.msg import Marker, MarkerArray

    latched = QoSProfile(
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    lights = node.create_publisher(SearchlightArray, 'searchlights', latched)
    markers = node.create_publisher(MarkerArray, 'searchlight_markers', latched)
    array = SearchlightArray()
    array.header.frame_id = 'map'
    for i in range(2):
        light = Searchlight(name=f'lamp {i}', motion=Searchlight.MOTION_PATROL, range=4.5)
        light.position = Point(x=float(i), y=2.0)
        light.waypoints = [Point(x=float(i + k), y=3.0) for k in range(3)]
        array.lights.append(light)
    lights.publish(array)
    cone = Marker(ns='cones', id=7, type=Marker.TRIANGLE_LIST, text='cone')
    cone.header.frame_id = 'map'
    cone.points = [Point(x=0.0), Point(x=1.0), Point(y=1.0)]
    markers.publish(MarkerArray(markers=[cone, Marker(ns='names', text='lamp 0')]))
    return lights, markers


def record_bag(node_processes, ros_context, tmp_path):
    """A rosbag2 directory the real recorder made of real traffic, stopped by SIGINT."""
    node = rclpy.create_node('latched_extras', context=ros_context)
    publishers = publish_latched_extras(node)  # latched: the recorder gets them on subscribing
    traffic = node_processes.start_python(TRAFFIC, 'traffic', str(COUNT), str(RATE), 'wall')
    bag = tmp_path / 'compat'  # compat/compat_0.mcap + compat/metadata.yaml
    recorder = node_processes.start([RECORDER, '--ros-args', '-p', f'output:={bag}'], 'recorder')
    wait_for_output(traffic, 'done')
    for topic in LATCHED_TOPICS:  # this process's publishers may be discovered last
        wait_for_output(recorder, f"Subscribed to topic '{topic}'")
    time.sleep(0.5)  # the last messages are on their way
    recorder.send_signal(signal.SIGINT)
    assert recorder.wait(20) == 0, recorder.log_path.read_text()
    for publisher in publishers:
        node.destroy_publisher(publisher)
    node.destroy_node()
    return bag


def test_recorded_bag_opens_in_rosbags_and_foxglove(node_processes, ros_context, tmp_path):
    bag = record_bag(node_processes, ros_context, tmp_path)
    mcap_file = bag / 'compat_0.mcap'
    expected = mcap_contents(mcap_file)
    assert {*VOLATILE_TOPICS, *LATCHED_TOPICS} <= set(expected)
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert (info['version'], info['storage_identifier']) == (9, 'mcap')
    assert info['relative_file_paths'] == ['compat_0.mcap']

    decoded = read_with_rosbags(bag, expected)  # as `ros2 bag info/play compat`
    read_with_rosbags(mcap_file, expected)  # as `ros2 bag info compat/compat_0.mcap`
    assert [m.data for _, m in decoded['/chatter']] == [f'message {i}' for i in range(COUNT)]
    assert [m.step for _, m in decoded['/rl_env/step_info']] == list(range(COUNT))
    assert list(decoded['/rl_env/step_info'][-1][1].state) == [COUNT - 1, 0.5]
    assert [m.pose.pose.position.x for _, m in decoded['/odom']] == list(map(float, range(COUNT)))
    assert decoded['/odom'][0][1].pose.covariance.shape == (36,)
    ((_, lights),) = decoded['/searchlights']
    assert [light.name for light in lights.lights] == ['lamp 0', 'lamp 1']
    assert [p.x for p in lights.lights[1].waypoints] == [1.0, 2.0, 3.0]

    report = foxglove_check(mcap_file)
    assert_foxglove_agrees(report, expected)
    topics = report['topics']
    assert topics['/chatter']['first'] == {'data': 'message 0'}
    assert topics['/rl_env/step_info']['last']['state'] == [COUNT - 1, 0.5]
    assert topics['/rl_env/rl_env_description']['first']['title'] == 'traffic'
    light = topics['/searchlights']['first']['lights'][1]
    assert (light['name'], [p['x'] for p in light['waypoints']]) == ('lamp 1', [1.0, 2.0, 3.0])
    markers = topics['/searchlight_markers']['first']['markers']
    assert [(m['ns'], m['text'], len(m['points'])) for m in markers] == [
        ('cones', 'cone', 3),
        ('names', 'lamp 0', 0),
    ]


def test_recovered_bag_opens_in_rosbags_and_foxglove(node_processes, ros_context, tmp_path):
    """A recording cut off in the middle of a chunk, salvaged by `stealth bag recover`."""
    source = record_bag(node_processes, ros_context, tmp_path) / 'compat_0.mcap'
    last_chatter = max(mcap_contents(source)['/chatter'].log_times)
    with open(source, 'rb') as stream:
        chunks = make_reader(stream).get_summary().chunk_indexes
    chunk = min(
        (c for c in chunks if c.message_start_time <= last_chatter <= c.message_end_time),
        key=lambda c: c.chunk_start_offset,
    )
    cut = tmp_path / 'cut.mcap'  # ends in the middle of the chunk with the last /chatter
    cut.write_bytes(source.read_bytes()[: chunk.chunk_start_offset + chunk.chunk_length // 2])
    recovered, report = recover(cut, tmp_path / 'recovered.mcap')  # `stealth bag recover`
    assert not report.salvage.complete
    expected = mcap_contents(recovered)
    kept = len(expected['/chatter'].log_times)
    assert 0 < kept < COUNT

    decoded = read_with_rosbags(recovered, expected)  # as `ros2 bag info/play recovered.mcap`
    assert [m.data for _, m in decoded['/chatter']] == [f'message {i}' for i in range(kept)]
    assert_foxglove_agrees(foxglove_check(recovered), expected)


def test_the_foxglove_check_fails_rather_than_skips_without_node(monkeypatch):
    monkeypatch.setattr(shutil, 'which', lambda name: None)
    with pytest.raises(pytest.fail.Exception, match='needs node and npm: install Node.js'):
        foxglove_check(JS_CHECK / 'missing.mcap')
