"""The bridge node's parameters (bridge declares them), importable without rclpy: an
orchestrator checks parameter names against them before it starts the node."""

from stealth_node_kit.param_table import Param, Unset

from stealth_tools.bridge_core import DEFAULT_PORT

PARAMETERS = {
    'port': Param(DEFAULT_PORT, 'TCP port of the WebSocket server: the Foxglove app connects '
                  'to ws://localhost:PORT.', (1, 65535), read_only=True),
    'address': Param('127.0.0.1', 'Address the server listens on (0.0.0.0: every interface, '
                     'for a Foxglove app on another machine).', read_only=True),
    'topics': Param(Unset('STRING_ARRAY'), 'Topics to relay (/clock always is); unset: '
                    'every topic with publishers.', read_only=True),
    'discovery_period': Param(0.5, 'Seconds (steady) between looks for new topics.',
                              (0.05, 60.0), read_only=True),
    'include_hidden_topics': Param(False, 'Relay hidden topics (_name) too.', read_only=True),
}  # fmt: skip
