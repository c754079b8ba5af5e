"""The plumbing for real: every stealth_interfaces message crosses DDS between two processes."""

import time

from interface_probe import MESSAGE_NAMES, TOPIC_PREFIX, message_class, sample_message
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_support import REPO_ROOT

PROBE = str(REPO_ROOT / 'tests' / 'interface_probe.py')
COPIES = 3


def messages_equal(a, b) -> bool:
    """Field-by-field equality that also handles numpy-backed array fields."""
    if type(a) is not type(b):
        return False
    for field in a.get_fields_and_field_types():
        x, y = getattr(a, field), getattr(b, field)
        if hasattr(x, 'get_fields_and_field_types'):
            if not messages_equal(x, y):
                return False
        elif isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not np.array_equal(np.asarray(x), np.asarray(y)):
                return False
        elif isinstance(x, list) and x and hasattr(x[0], 'get_fields_and_field_types'):
            if len(x) != len(y) or not all(
                messages_equal(p, q) for p, q in zip(x, y, strict=True)
            ):
                return False
        elif x != y:
            return False
    return True


def test_sample_messages_fill_every_field():
    """The probe sets every field away from its default, so equality below means something."""
    for name in MESSAGE_NAMES:
        cls = message_class(name)
        assert not messages_equal(sample_message(cls, 1), cls()), name
        assert not messages_equal(sample_message(cls, 1), sample_message(cls, 2)), name


def test_every_message_type_crosses_processes_intact(node_processes, ros_context):
    publisher = node_processes.start_python(
        f'import runpy, sys; sys.argv = ["probe", "publish", "{COPIES}"]; '
        f'runpy.run_path("{PROBE}", run_name="__main__")',
        'interface_probe',
    )
    node = rclpy.create_node('probe_listener', context=ros_context)
    qos = QoSProfile(
        depth=COPIES,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    received = {name: [] for name in MESSAGE_NAMES}
    for name in MESSAGE_NAMES:
        node.create_subscription(
            message_class(name), TOPIC_PREFIX + name, received[name].append, qos
        )
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(len(v) < COPIES for v in received.values()):
        executor.spin_once(timeout_sec=0.1)
        if publisher.poll() is not None:
            pytest.fail(f'publisher died: {publisher.log_path.read_text()}')
    executor.shutdown()
    node.destroy_node()
    for name in MESSAGE_NAMES:
        assert len(received[name]) == COPIES, f'{name}: got {len(received[name])} of {COPIES}'
        for seed, message in enumerate(received[name], start=1):
            expected = sample_message(message_class(name), seed)
            assert messages_equal(message, expected), f'{name} #{seed} arrived altered'


def test_interfaces_import_in_a_process_started_from_install(node_processes):
    """A process with only the install space and venv on its paths finds the interfaces."""
    process = node_processes.start_python(
        'import stealth_interfaces.msg as m, stealth_interfaces; '
        'print(stealth_interfaces.__file__); print(m.EpisodeSummary.DETECTED)',
        'import_check',
    )
    assert process.wait(30) == 0, process.log_path.read_text()
    output = process.log_path.read_text().splitlines()
    assert '/ros2_ws/install/stealth_interfaces/' in output[0]
    assert output[1] == '1'
