"""Sample recordings for the tests (not a test module): known messages, known times.

Messages are CDR-encoded with mcap_ros2 from the definition text the recorder would store, so
writing them already exercises that text; no ROS graph or rclpy is needed.
"""

from dataclasses import dataclass
from pathlib import Path

from mcap_ros2._dynamic import serialize_dynamic
from stealth_tools.bag_format import BagWriter
from stealth_tools.interfaces import definition_text
from stealth_tools.qos_text import QosDescription

START_NS = 1_700_000_000_000_000_000
RELIABLE = QosDescription(history='unknown', depth=0)
LATCHED = QosDescription(history='unknown', depth=0, durability='transient_local')
TYPE_HASH = 'RIHS01_' + 'ab' * 32


class FakeClock:
    """A monotonic clock the test advances by hand."""

    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


@dataclass(frozen=True)
class Sample:
    topic: str
    type: str
    fields: dict
    log_time: int


def encoder(type_name: str):
    return serialize_dynamic(type_name, definition_text(type_name))[type_name]


def chatter_samples(count: int, spacing_ns: int = 100_000_000, topic: str = '/chatter'):
    return [
        Sample(topic, 'std_msgs/msg/String', {'data': f'hello {i}'}, START_NS + i * spacing_ns)
        for i in range(count)
    ]


def odometry_sample(index: int, log_time: int) -> Sample:
    fields = {
        'header': {'stamp': {'sec': 1, 'nanosec': 2}, 'frame_id': 'odom'},
        'child_frame_id': 'base_link',
        'pose': {
            'pose': {
                'position': {'x': float(index), 'y': 2.0, 'z': 0.0},
                'orientation': {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0},
            },
            'covariance': [0.0] * 36,
        },
        'twist': {
            'twist': {
                'linear': {'x': 0.5, 'y': 0.0, 'z': 0.0},
                'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0},
            },
            'covariance': [0.0] * 36,
        },
    }
    return Sample('/odom', 'nav_msgs/msg/Odometry', fields, log_time)


def write_bag(path: Path, samples: list[Sample], close: bool = True, **options) -> BagWriter:
    """A bag holding the samples in order; left open (as after SIGKILL) if close is False."""
    writer = BagWriter(path, **options)
    encoders = {}
    for sample in samples:
        if sample.type not in encoders:
            encoders[sample.type] = encoder(sample.type)
        if sample.topic not in writer.topics:
            offers = [LATCHED if 'description' in sample.topic else RELIABLE]
            definition = definition_text(sample.type)
            writer.add_topic(sample.topic, sample.type, definition, offers, TYPE_HASH)
        data = encoders[sample.type](sample.fields)
        writer.write(sample.topic, data, sample.log_time, sample.log_time - 1000)
    if close:
        writer.close()
    return writer
