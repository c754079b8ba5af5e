"""`stealth topic list|echo|hz|info`: ros2 topic's verbs and options; their implementation,
over a short-lived hidden node, is stealth_tools.graph_tools."""

from __future__ import annotations

from stealth_tools.commands.arguments import (
    add_qos_arguments,
    add_spin_time,
    add_timeout,
    lazy,
    positive_int,
)


def add_parser(commands) -> None:
    topic = commands.add_parser(
        'topic', help='Various topic related sub-commands', description='ros2 topic, direct.'
    )
    verbs = topic.add_subparsers(dest='verb', metavar='verb', required=True)
    for add_verb in (_add_list, _add_echo, _add_hz, _add_info):
        add_verb(verbs)


def _add_list(verbs) -> None:
    parser = verbs.add_parser(
        'list', help='Output a list of available topics', description="List the graph's topics."
    )
    parser.add_argument('-t', '--show-types', action='store_true', help='also show the types')
    parser.add_argument(
        '-c', '--count-topics', action='store_true', help='only show the number of topics'
    )
    parser.add_argument('-v', '--verbose', action='store_true', help='publishers and subscribers')
    parser.add_argument('--include-hidden-topics', action='store_true', help='show hidden topics')
    add_spin_time(parser, 3.0)
    parser.set_defaults(handler=lazy('graph_tools', 'topic_list', ros=True))


def _add_echo(verbs) -> None:
    parser = verbs.add_parser(
        'echo',
        help='Output messages from a topic',
        description='Print the messages of a topic as YAML, each followed by ---.',
    )
    parser.add_argument('topic_name', help="name of the topic (e.g. '/chatter')")
    parser.add_argument(
        'message_type', nargs='?', help="type of the messages (e.g. 'std_msgs/msg/String')"
    )
    add_qos_arguments(parser)
    parser.add_argument('--field', help="print only this field, e.g. 'pose.pose.position'")
    parser.add_argument(
        '-f', '--full-length', action='store_true', help='do not truncate arrays and strings'
    )
    parser.add_argument(
        '-l',
        '--truncate-length',
        type=positive_int,
        default=128,
        help='truncate arrays, bytes and strings after this length (default: %(default)s)',
    )
    parser.add_argument('--no-arr', action='store_true', help='do not print array fields')
    parser.add_argument('--no-str', action='store_true', help='do not print string fields')
    parser.add_argument('--flow-style', action='store_true', help='YAML flow style')
    parser.add_argument('--once', action='store_true', help='print the first message and exit')
    add_timeout(parser)
    add_spin_time(parser, 5.0)
    parser.set_defaults(handler=lazy('graph_tools', 'topic_echo', ros=True))


def _add_hz(verbs) -> None:
    parser = verbs.add_parser(
        'hz',
        help='Print the average publishing rate to screen',
        description='Print the rate of a topic about once a second: mean rate, min and max '
        'interval, standard deviation, window; until Ctrl-C, or for --timeout seconds.',
    )
    parser.add_argument('topic_name', help="name of the topic (e.g. '/chatter')")
    parser.add_argument(
        '-w',
        '--window',
        dest='window_size',
        metavar='WINDOW',
        type=positive_int,
        default=10000,
        help='window size, in messages, for the rate (default: %(default)s)',
    )
    parser.add_argument(
        '--wall-time',
        dest='use_wtime',
        action='store_true',
        help='use wall time (when /clock is not published in a simulation)',
    )
    add_timeout(parser)
    add_spin_time(parser, 5.0)
    parser.set_defaults(handler=lazy('graph_tools', 'topic_hz', ros=True))


def _add_info(verbs) -> None:
    parser = verbs.add_parser(
        'info',
        help='Print information about a topic',
        description='Print the type and the publisher and subscription counts of a topic.',
    )
    parser.add_argument('topic_name', help="name of the topic (e.g. '/chatter')")
    parser.add_argument(
        '-v', '--verbose', action='store_true', help='node, type hash, GID and QoS of each'
    )
    add_spin_time(parser, 5.0)
    parser.set_defaults(handler=lazy('graph_tools', 'topic_info', ros=True))
