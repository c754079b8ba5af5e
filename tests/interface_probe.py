"""Fill every field of every stealth_interfaces message with distinct values; publish them.

The test process and a separate publisher process both build the same sample of each message
from its rosidl introspection data, so a received message can be compared field for field with
what was sent, nested types and arrays included. Run as a script it is the publisher node:
`python interface_probe.py publish [COUNT]`.
"""

import importlib
import sys

from rosidl_parser.definition import (
    AbstractNestedType,
    Array,
    BasicType,
    BoundedSequence,
    NamespacedType,
)

MESSAGE_NAMES = (
    'RLAction',
    'RLStateReward',
    'RLEnvDescription',
    'RLExperimentInfo',
    'Searchlight',
    'SearchlightArray',
    'EpisodeSummary',
    'StepInfo',
    'AgentEpisodeInfo',
    'GridObservation',
)
INTEGER_TYPES = {'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64'}
FLOAT_TYPES = {'float', 'double'}
TOPIC_PREFIX = 'probe/'


def message_class(name: str):
    return getattr(importlib.import_module('stealth_interfaces.msg'), name)


def _message_class_of(namespaced_type: NamespacedType):
    module = importlib.import_module('.'.join(namespaced_type.namespaces))
    return getattr(module, namespaced_type.name)


def _sample_value(slot_type, seed: int):
    """A value for one field: different for every field and seed, exact in float32."""
    if isinstance(slot_type, AbstractNestedType):
        size = slot_type.size if isinstance(slot_type, Array) else 3
        if isinstance(slot_type, BoundedSequence):
            size = min(size, slot_type.maximum_size)
        return [_sample_value(slot_type.value_type, seed + i) for i in range(size)]
    if isinstance(slot_type, NamespacedType):
        return sample_message(_message_class_of(slot_type), seed)
    if isinstance(slot_type, BasicType):
        type_name = slot_type.typename
        if type_name == 'boolean':
            return seed % 2 == 1
        if type_name in INTEGER_TYPES:
            return (seed * 7 + 3) % 100
        if type_name in FLOAT_TYPES:
            return seed * 0.25 + 0.5  # quarters are exact in float32
        if type_name in {'octet', 'char'}:
            return bytes([seed % 256]) if type_name == 'octet' else chr(65 + seed % 26)
    # Strings (bounded or not).
    return f'field-{seed}-ü'


def sample_message(cls, seed: int = 1):
    """An instance of `cls` with every field, recursively, set from `seed`."""
    message = cls()
    for index, (field_name, slot_type) in enumerate(
        zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES, strict=True)
    ):
        setattr(message, field_name, _sample_value(slot_type, seed * 31 + index))
    return message


def publish(count: int) -> None:
    """Publish every message type `count` times (reliable, transient local) and stay alive."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    qos = QoSProfile(
        depth=count,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    rclpy.init()
    node = rclpy.create_node('interface_probe')
    try:
        publishers = {
            name: node.create_publisher(message_class(name), TOPIC_PREFIX + name, qos)
            for name in MESSAGE_NAMES
        }
        for seed in range(1, count + 1):
            for name, publisher in publishers.items():
                publisher.publish(sample_message(message_class(name), seed))
        node.get_logger().info(f'published {count} of each of {len(publishers)} message types')
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    if len(sys.argv) < 2 or sys.argv[1] != 'publish':
        sys.exit('usage: interface_probe.py publish [COUNT]')
    publish(int(sys.argv[2]) if len(sys.argv) > 2 else 3)
