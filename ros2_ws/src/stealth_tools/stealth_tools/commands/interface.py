"""`stealth interface show <pkg/msg/Type>`: ros2 interface show, from the definitions the ament
index holds (stealth_tools.interfaces)."""

from __future__ import annotations

import sys

from stealth_tools.errors import CommandError


def interface_show(args) -> int:
    from stealth_tools.interfaces import InterfaceError, show_interface_lines

    type_name = sys.stdin.readline().strip() if args.type == '-' else args.type
    try:
        lines = list(
            show_interface_lines(
                type_name,
                show_comments=not args.no_comments,
                show_nested_comments=args.all_comments,
            )
        )
    except InterfaceError as error:
        raise CommandError(str(error)) from None
    print('\n'.join(lines))
    return 0


def add_parser(commands) -> None:
    interface = commands.add_parser(
        'interface', help='Show information about ROS interfaces', description='ros2 interface.'
    )
    verbs = interface.add_subparsers(dest='verb', metavar='verb', required=True)
    parser = verbs.add_parser(
        'show',
        help='Output the interface definition',
        description='Print a message definition, nested definitions indented under their field.',
    )
    comments = parser.add_mutually_exclusive_group()
    comments.add_argument(
        '--all-comments', action='store_true', help='comments of nested definitions too'
    )
    comments.add_argument('--no-comments', action='store_true', help='no comments or blank lines')
    parser.add_argument(
        'type', help="the type (e.g. 'nav_msgs/msg/Odometry'); '-' reads it from stdin"
    )
    parser.set_defaults(handler=interface_show)
