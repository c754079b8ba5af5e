"""The recorder node's parameter names (recorder declares them), importable without rclpy: an
orchestrator checks parameter files against them before it starts the node. Their defaults are
RecorderSettings' (recorder.py); `topics` is declared without a value (every topic)."""

SETTINGS = (
    'output',
    'discovery_period',
    'max_chunk_duration',
    'chunk_size',
    'compression',
    'include_hidden_topics',
    'batch_period',
)
PARAMETERS = frozenset({'topics', *SETTINGS})
