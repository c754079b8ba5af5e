"""`stealth bridge`: foxglove_bridge's job, on foxglove-sdk's WebSocket server
(stealth_tools.bridge serves the graph)."""

from __future__ import annotations

from stealth_tools.commands import PROG
from stealth_tools.commands.arguments import add_discovery_arguments, port


def bridge_command(args) -> int:
    from rclpy.parameter import Parameter

    from stealth_tools.bridge import serve

    overrides = [
        Parameter('port', value=args.port),
        Parameter('address', value=args.address),
        Parameter('discovery_period', value=args.polling_interval / 1000.0),
        Parameter('include_hidden_topics', value=args.include_hidden_topics),
    ]
    if args.topics:
        overrides.append(Parameter('topics', value=list(args.topics)))
    return serve(overrides, '--port N', f'{PROG} bridge')


def add_parser(commands) -> None:
    parser = commands.add_parser(
        'bridge',
        help="Relay the graph's topics to the Foxglove app (as foxglove_bridge)",
        description='Serve the ROS graph of this domain to the Foxglove app, as foxglove_bridge '
        "does, on Foxglove's own WebSocket server: in Foxglove, Open connection > Foxglove "
        'WebSocket > ws://localhost:PORT. Channels are CDR with ros2msg schemas; latched topics '
        'reach clients that connect late; /clock drives the timeline. Stop with Ctrl-C.',
    )
    parser.add_argument(
        '--port', type=port, default=8765, help='TCP port to listen on (default: %(default)s)'
    )
    parser.add_argument(
        '--address',
        default='127.0.0.1',
        help='address to listen on; 0.0.0.0 for a Foxglove app on another machine '
        '(default: %(default)s)',
    )
    parser.add_argument(
        '--topics', nargs='+', default=[], metavar='topic', help='only these (default: all)'
    )
    add_discovery_arguments(parser, 500)
    parser.set_defaults(handler=bridge_command)
