"""The recorder node's parameters (recorder declares them), importable without rclpy: an
orchestrator checks parameter files against them (names, types, ranges) before it starts the
node. RecorderSettings (recorder.py) takes its defaults from here."""

from stealth_node_kit.param_table import Param, Unset

from stealth_tools.bag_format import DEFAULT_CHUNK_SIZE, DEFAULT_MAX_CHUNK_DURATION

MAX_BATCH_PERIOD = 1.0  # s: a longer wait would only hold more in DDS's queues
PARAMETERS = {
    'output': Param(
        '',
        "The recording: NAME.mcap one file, NAME a rosbag2 directory; '' = rosbag2's name "
        '(rosbag2_YYYY_MM_DD-HH_MM_SS).',
        read_only=True,
    ),
    'topics': Param(
        Unset('STRING_ARRAY'), 'Topics to record; unset: every topic.', read_only=True
    ),
    'discovery_period': Param(
        0.2, 'Seconds (steady) between looks for new topics.', (0.001, 3600.0), read_only=True
    ),
    'max_chunk_duration': Param(
        DEFAULT_MAX_CHUNK_DURATION,
        'Seconds after which a chunk is closed (bounds what a SIGKILL loses).',
        (0.001, 3600.0),
        read_only=True,
    ),
    'chunk_size': Param(
        DEFAULT_CHUNK_SIZE, 'Bytes after which a chunk is closed.', (1, 2**31 - 1), read_only=True
    ),
    'compression': Param('zstd', 'Compression of the chunks: zstd, lz4 or none.', read_only=True),
    'include_hidden_topics': Param(False, 'Record hidden topics (_name) too.', read_only=True),
    'batch_period': Param(
        0.05,
        'Seconds between wake-ups that take every queue (0: each message at once).',
        (0.0, MAX_BATCH_PERIOD),
        read_only=True,
    ),
}
