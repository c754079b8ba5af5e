"""`stealth`: ros2cli's verbs and argument shapes for what this platform lacks, plus the
commands other packages add, so habits from a full ROS 2 install carry over.

    stealth run <package> <executable> [args...]      # ros2 run
    stealth topic list|echo|hz|info ...               # ros2 topic
    stealth interface show <pkg/msg/Type>             # ros2 interface show
    stealth bag record|play|info|recover ...          # ros2 bag (+ recover, as mcap recover)
    stealth bridge [--port 8765] [--topics ...]       # foxglove_bridge, on foxglove-sdk's server
    stealth train|rollout|render ...                  # added by stealth_bringup (see below)

Other packages add commands as ros2cli's extension points add verbs: an entry point in the
group `stealth.commands` names a mapping {command: (module, function, summary)}; the function
takes the command's argv and is imported only when the command runs. So this package knows
nothing above it, and `stealth train` works wherever stealth_bringup is installed.

Every failure is one line on stderr and exit status 1; parsing needs no ROS, so --help is fast.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
import importlib
import shlex
import sys

from stealth_tools.errors import CommandError

PROG = 'stealth'
# Entry points of this group add commands: see the module docstring.
COMMAND_GROUP = 'stealth.commands'
OWN_COMMANDS = ('run', 'topic', 'interface', 'bag', 'bridge')
QOS_PROFILES = (
    'unknown',
    'default',
    'system_default',
    'sensor_data',
    'services_default',
    'parameters',
    'parameter_events',
    'action_status_default',
    'best_available',
)
RELIABILITIES = ('system_default', 'reliable', 'best_effort', 'best_available')
DURABILITIES = ('system_default', 'transient_local', 'volatile', 'best_available')
HISTORIES = ('system_default', 'keep_last', 'keep_all')
COMPRESSIONS = ('zstd', 'lz4', 'none')


def _positive_float(text: str) -> float:
    value = float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text} is not positive')
    return value


def _non_negative_float(text: str) -> float:
    value = float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'{text} is negative')
    return value


def _positive_int(text: str) -> int:
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text} is not positive')
    return value


def _spin_time(parser: argparse.ArgumentParser, default: float) -> None:
    parser.add_argument(
        '--spin-time',
        type=_non_negative_float,
        default=default,
        help='at most this many seconds to wait for discovery (no ros2cli daemon here; '
        'default: %(default)s)',
    )


def _discovery_arguments(parser: argparse.ArgumentParser, default_ms: int) -> None:
    """How new topics are looked for (as ros2 bag record's options)."""
    parser.add_argument(
        '-p',
        '--polling-interval',
        type=_positive_int,
        default=default_ms,
        metavar='MS',
        help='discovery period for new topics, in ms (default: %(default)s)',
    )
    parser.add_argument('--include-hidden-topics', action='store_true', help='hidden ones too')


def _timeout(parser: argparse.ArgumentParser, help_text: str) -> None:
    parser.add_argument('--timeout', metavar='N', type=_positive_float, help=help_text)


def _in_ros(verb: Callable) -> Callable:
    """Run a graph verb inside an rclpy session that owns SIGINT/SIGTERM."""

    def handler(args) -> int:
        from stealth_tools.ros_session import ros_session

        with ros_session() as stop:
            return verb(args, stop)

    return handler


def _lazy(module: str, function: str, ros: bool = False) -> Callable:
    """A handler that imports its implementation only when run (keeps --help free of ROS)."""

    def handler(args) -> int:
        verb = getattr(importlib.import_module(f'stealth_tools.{module}'), function)
        return (_in_ros(verb) if ros else verb)(args)

    return handler


# --- run ---------------------------------------------------------------------------------------


def run_command(args) -> int:
    from stealth_tools.executables import (
        ExecutableNotFoundError,
        find_executable,
        run_supervised,
    )

    try:
        path = find_executable(args.package_name, args.executable_name)
    except ExecutableNotFoundError as error:
        raise CommandError(str(error)) from None
    prefix = shlex.split(args.prefix) if args.prefix else []
    label = f'{args.package_name} {args.executable_name}'
    return run_supervised([*prefix, str(path), *args.argv], label)


def _add_run(commands) -> None:
    parser = commands.add_parser(
        'run',
        help='Run a package specific executable',
        description='Run an executable of a package, found in <prefix>/lib/<package>/ of the '
        'ament index (as ros2 run). Arguments after the executable, --ros-args included, are '
        'passed on.',
    )
    parser.add_argument(
        '--prefix', help="command to put before the executable (e.g. 'gdb -ex run --args')"
    )
    parser.add_argument('package_name', help='name of the ROS package')
    parser.add_argument('executable_name', help='name of the executable')
    parser.add_argument('argv', nargs=argparse.REMAINDER, help='arguments for the executable')
    parser.set_defaults(handler=run_command)


# --- topic -------------------------------------------------------------------------------------


def _add_qos_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        '--qos-profile',
        choices=QOS_PROFILES,
        default='sensor_data',
        help='QoS preset to subscribe with (default: %(default)s)',
    )
    parser.add_argument('--qos-depth', metavar='N', type=int, help='depth (overrides preset)')
    parser.add_argument('--qos-history', choices=HISTORIES, help='history (overrides preset)')
    parser.add_argument(
        '--qos-reliability',
        choices=RELIABILITIES,
        help='reliability (default: what the running publishers offer)',
    )
    parser.add_argument(
        '--qos-durability',
        choices=DURABILITIES,
        help='durability (default: what the running publishers offer)',
    )


def _add_topic(commands) -> None:
    topic = commands.add_parser(
        'topic', help='Various topic related sub-commands', description='ros2 topic, direct.'
    )
    verbs = topic.add_subparsers(dest='verb', metavar='verb', required=True)

    parser = verbs.add_parser(
        'list', help='Output a list of available topics', description="List the graph's topics."
    )
    parser.add_argument('-t', '--show-types', action='store_true', help='also show the types')
    parser.add_argument(
        '-c', '--count-topics', action='store_true', help='only show the number of topics'
    )
    parser.add_argument('-v', '--verbose', action='store_true', help='publishers and subscribers')
    parser.add_argument('--include-hidden-topics', action='store_true', help='show hidden topics')
    _spin_time(parser, 3.0)
    parser.set_defaults(handler=_lazy('graph_tools', 'topic_list', ros=True))

    parser = verbs.add_parser(
        'echo',
        help='Output messages from a topic',
        description='Print the messages of a topic as YAML, each followed by ---.',
    )
    parser.add_argument('topic_name', help="name of the topic (e.g. '/chatter')")
    parser.add_argument(
        'message_type', nargs='?', help="type of the messages (e.g. 'std_msgs/msg/String')"
    )
    _add_qos_arguments(parser)
    parser.add_argument('--field', help="print only this field, e.g. 'pose.pose.position'")
    parser.add_argument(
        '-f', '--full-length', action='store_true', help='do not truncate arrays and strings'
    )
    parser.add_argument(
        '-l',
        '--truncate-length',
        type=_positive_int,
        default=128,
        help='truncate arrays, bytes and strings after this length (default: %(default)s)',
    )
    parser.add_argument('--no-arr', action='store_true', help='do not print array fields')
    parser.add_argument('--no-str', action='store_true', help='do not print string fields')
    parser.add_argument('--flow-style', action='store_true', help='YAML flow style')
    parser.add_argument('--once', action='store_true', help='print the first message and exit')
    _timeout(parser, 'stop after N seconds; exit status 1 when no message arrived')
    _spin_time(parser, 5.0)
    parser.set_defaults(handler=_lazy('graph_tools', 'topic_echo', ros=True))

    parser = verbs.add_parser(
        'hz',
        help='Print the average publishing rate to screen',
        description='Print the rate of a topic about once a second: mean rate, min and max '
        'interval, standard deviation, window.',
    )
    parser.add_argument('topic_name', help="name of the topic (e.g. '/chatter')")
    parser.add_argument(
        '-w',
        '--window',
        dest='window_size',
        metavar='WINDOW',
        type=_positive_int,
        default=10000,
        help='window size, in messages, for the rate (default: %(default)s)',
    )
    parser.add_argument(
        '--wall-time',
        dest='use_wtime',
        action='store_true',
        help='use wall time (when /clock is not published in a simulation)',
    )
    _timeout(parser, 'give up, exit status 1, after N seconds without a message (default: wait)')
    _spin_time(parser, 5.0)
    parser.set_defaults(handler=_lazy('graph_tools', 'topic_hz', ros=True))

    parser = verbs.add_parser(
        'info',
        help='Print information about a topic',
        description='Print the type and the publisher and subscription counts of a topic.',
    )
    parser.add_argument('topic_name', help="name of the topic (e.g. '/chatter')")
    parser.add_argument(
        '-v', '--verbose', action='store_true', help='node, type hash, GID and QoS of each'
    )
    _spin_time(parser, 5.0)
    parser.set_defaults(handler=_lazy('graph_tools', 'topic_info', ros=True))


# --- interface ---------------------------------------------------------------------------------


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


def _add_interface(commands) -> None:
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


# --- bag ---------------------------------------------------------------------------------------


def bag_record(args) -> int:
    from rclpy.parameter import Parameter

    from stealth_tools.recorder import RecorderSettings, record

    topics = [*args.topics_positional, *args.topics]
    if not topics and not args.all:
        raise CommandError('name the topics to record, or record them all with -a')
    settings = RecorderSettings(
        output=args.output or '',
        topics=() if args.all else tuple(topics),
        discovery_period=args.polling_interval / 1000.0,
        max_chunk_duration=args.max_chunk_duration,
        chunk_size=args.chunk_size,
        compression=args.compression,
        include_hidden_topics=args.include_hidden_topics,
    )
    overrides = settings.parameters()
    if args.use_sim_time:
        overrides.append(Parameter('use_sim_time', value=True))
    return record([PROG], overrides=overrides)


def bag_play(args, stop) -> int:
    from stealth_tools.player import PlayOptions, play_bag

    options = PlayOptions(
        bag=args.bag_path,
        rate=args.rate,
        topics=tuple(args.topics),
        clock_hz=args.clock,
        loop=args.loop,
        start_offset=args.start_offset,
        delay=args.delay,
        bridge_port=args.bridge_port if args.bridge else 0,
    )
    return play_bag(options, stop)


def bag_info(args) -> int:
    from stealth_tools.bag_reading import format_bag_info, read_bag_info

    info = read_bag_info(args.bag_path)
    for path in info.unindexed:
        print(
            f'warning: {path} was not closed (no summary); numbers come from a scan. '
            f'`stealth bag recover {path}` writes an indexed copy.',
            file=sys.stderr,
        )
    if args.topic_name:
        print('\n'.join(t.name for t in info.topics))
    else:
        print(format_bag_info(info, args.bag_path), end='')
    return 0


def bag_recover(args) -> int:
    from stealth_tools.bag_files import bag_files
    from stealth_tools.bag_reading import read_bag_info
    from stealth_tools.bag_recover import recover

    files = bag_files(args.bag_path)
    if len(files) > 1:  # a split bag: every file that was never closed
        if args.output:
            raise CommandError(
                f'{args.bag_path} holds {len(files)} files; -o names the copy of one: '
                'give that file instead of the directory'
            )
        files = [f for f in files if not read_bag_info(f).indexed]
        if not files:
            print(f'{args.bag_path}: every file is complete and indexed; nothing to recover')
    for file in files:
        output, report = recover(file, args.output, compression=args.compression)
        print(f'{output}: {report.summary()}')
    return 0


def bag_compare(args) -> int:
    from stealth_tools.rl_compare import complete_episodes, first_difference, read_rl_topics

    first, second = read_rl_topics(args.first), read_rl_topics(args.second)
    count = args.episodes
    if count is None:
        count = min(complete_episodes(first), complete_episodes(second))
        if count == 0:
            raise CommandError('no complete episode to compare (a recording holds none)')
    difference = first_difference(first, second, count)
    if difference is not None:
        print(difference)
        return 1
    print(f'the first {count} episodes are the same, message for message')
    return 0


def _add_bag(commands) -> None:
    bag = commands.add_parser(
        'bag', help='Various rosbag related sub-commands', description='ros2 bag, MCAP only.'
    )
    verbs = bag.add_subparsers(dest='verb', metavar='verb', required=True)

    parser = verbs.add_parser(
        'record',
        help='Record ROS data to a bag',
        description='Record topics into MCAP as rosbag2 does. -o NAME.mcap writes one file; '
        '-o NAME (the default is rosbag2_<time>) writes a rosbag2 directory NAME/NAME_0.mcap '
        'with metadata.yaml. Stop with Ctrl-C or SIGTERM.',
    )
    parser.add_argument('topics_positional', metavar='topic', nargs='*', help='topics to record')
    parser.add_argument('--topics', nargs='+', default=[], metavar='topic', help='(same)')
    parser.add_argument('-a', '--all', action='store_true', help='record every topic')
    parser.add_argument('-o', '--output', help='bag directory, or a file name ending in .mcap')
    parser.add_argument('--use-sim-time', action='store_true', help='log times from /clock')
    parser.add_argument(
        '--compression', choices=COMPRESSIONS, default='zstd', help='chunk compression'
    )
    parser.add_argument(
        '--max-chunk-duration',
        type=_positive_float,
        default=0.5,
        metavar='S',
        help='close a chunk after S seconds, bounding what a SIGKILL loses (default: %(default)s)',
    )
    parser.add_argument(
        '--chunk-size',
        type=_positive_int,
        default=256 * 1024,
        metavar='BYTES',
        help='close a chunk at this size (default: %(default)s)',
    )
    _discovery_arguments(parser, 200)
    parser.set_defaults(handler=bag_record)

    parser = verbs.add_parser(
        'play',
        help='Play back ROS data from a bag',
        description='Publish the messages of a bag with their original timing and QoS.',
    )
    parser.add_argument(
        'bag_path', help='bag directory (a run directory: all its recording files) or .mcap file'
    )
    parser.add_argument(
        '-r', '--rate', type=_positive_float, default=1.0, help='playback rate factor'
    )
    parser.add_argument('--topics', nargs='+', default=[], metavar='topic', help='topics to play')
    parser.add_argument(
        '--clock',
        type=_positive_float,
        nargs='?',
        const=40.0,
        default=0.0,
        metavar='HZ',
        help='publish /clock at HZ (default when given: 40) as a ROS time source',
    )
    parser.add_argument('-l', '--loop', action='store_true', help='play again and again')
    parser.add_argument(
        '--start-offset',
        type=_non_negative_float,
        default=0.0,
        metavar='S',
        help='start S seconds into the bag',
    )
    parser.add_argument(
        '-d',
        '--delay',
        type=_non_negative_float,
        default=0.0,
        metavar='S',
        help='wait S seconds (for subscribers to connect) before playing',
    )
    parser.add_argument(
        '--bridge',
        action='store_true',
        help='also serve the played topics to the Foxglove app (ws://localhost:8765; as '
        '`stealth bridge`)',
    )
    parser.add_argument(
        '--bridge-port',
        type=_port,
        default=8765,
        metavar='PORT',
        help='the port of --bridge (default: %(default)s)',
    )
    parser.set_defaults(handler=_in_ros(bag_play))

    parser = verbs.add_parser(
        'info',
        help='Print information about a bag to the screen',
        description="Print a bag's files, size, duration, start, end and topics with counts.",
    )
    parser.add_argument(
        'bag_path', help='bag directory (a run directory: all its recording files) or .mcap file'
    )
    parser.add_argument('-t', '--topic-name', action='store_true', help='only the topic names')
    parser.set_defaults(handler=bag_info)

    parser = verbs.add_parser(
        'recover',
        help='Rebuild a complete, indexed bag from a truncated one',
        description='Salvage every readable record of an MCAP that was not closed (SIGKILL, '
        'power loss) into a new complete, indexed file.',
    )
    parser.add_argument(
        'bag_path',
        help='bag directory or .mcap file (a directory: each of its files that was not closed)',
    )
    parser.add_argument('-o', '--output', help='output file (default: <input>.recovered.mcap)')
    parser.add_argument(
        '--compression', choices=COMPRESSIONS, default='zstd', help='chunk compression'
    )
    parser.set_defaults(handler=bag_recover)

    parser = verbs.add_parser(
        'compare',
        help="Compare two recordings' RL episodes message for message",
        description='Compare the RL topics of two recordings (rl_state_reward, rl_action, '
        'step_info, episode_summary, rl_experiment_info, episode_info), stamps aside, over '
        'their first complete episodes: two runs with the same seed and settings must match. '
        'Prints the first message that differs (exit status 1) or that they are the same (0).',
    )
    parser.add_argument('first', help='bag directory or .mcap file (e.g. runs/<name>)')
    parser.add_argument('second', help='the other bag directory or .mcap file')
    parser.add_argument(
        '--episodes',
        metavar='N',
        type=_positive_int,
        help='compare the first N episodes (default: as many as both hold complete)',
    )
    parser.set_defaults(handler=bag_compare)


# --- bridge ------------------------------------------------------------------------------------


def _port(text: str) -> int:
    value = int(text)
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f'{text} is not a TCP port (1-65535)')
    return value


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


def _add_bridge(commands) -> None:
    parser = commands.add_parser(
        'bridge',
        help="Relay the graph's topics to the Foxglove app (as foxglove_bridge)",
        description='Serve the ROS graph of this domain to the Foxglove app, as foxglove_bridge '
        "does, on Foxglove's own WebSocket server: in Foxglove, Open connection > Foxglove "
        'WebSocket > ws://localhost:PORT. Channels are CDR with ros2msg schemas; latched topics '
        'reach clients that connect late; /clock drives the timeline. Stop with Ctrl-C.',
    )
    parser.add_argument(
        '--port', type=_port, default=8765, help='TCP port to listen on (default: %(default)s)'
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
    _discovery_arguments(parser, 500)
    parser.set_defaults(handler=bridge_command)


# --- commands other packages add ---------------------------------------------------------------


def added_commands() -> dict[str, tuple[str, str, str]]:
    """{command: (module, function, summary)} from every installed package that adds commands
    (entry-point group COMMAND_GROUP), packages in name order, each in its own order."""
    from importlib.metadata import entry_points

    added = {}
    for entry in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        for name, spec in entry.load().items():
            if name not in OWN_COMMANDS:
                added.setdefault(name, spec)
    return added


def _delegate(module_name: str, function_name: str) -> Callable:
    def handler(args) -> int:
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name and module_name.startswith(error.name):
                function = None
            else:
                raise CommandError(f'{module_name} cannot be imported: {error}') from None
        else:
            function = getattr(module, function_name, None)
        if function is None:
            if {'-h', '--help'} & set(args.argv):
                args.parser.print_help()
                return 0
            raise CommandError(f'not available yet ({module_name}.{function_name} does not exist)')
        return int(function(list(args.argv)) or 0)

    return handler


def _add_delegates(commands, added: dict[str, tuple[str, str, str]]) -> None:
    for name, (module_name, function_name, summary) in added.items():
        parser = commands.add_parser(
            name,
            help=summary,
            description=f'{summary} Runs {module_name}.{function_name}; its options follow.',
            add_help=False,
        )
        parser.add_argument('argv', nargs=argparse.REMAINDER, help='options of the command')
        parser.set_defaults(handler=_delegate(module_name, function_name), parser=parser)


def _and_list(names) -> str:
    """'a', 'a and b', 'a, b and c'."""
    names = list(names)
    return ' and '.join(filter(None, [', '.join(names[:-1]), *names[-1:]]))


# --- main --------------------------------------------------------------------------------------


def build_parser(added: dict[str, tuple[str, str, str]] | None = None) -> argparse.ArgumentParser:
    """The whole command line; `added` defaults to the installed packages' commands."""
    added = added_commands() if added is None else added
    also = f' plus {_and_list(added)}' if added else ''
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=f'stealth-nav command line: ros2cli verbs ({", ".join(OWN_COMMANDS)}) for '
        f'a platform without ros2cli, launch and rosbag2,{also}.',
    )
    commands = parser.add_subparsers(dest='command', metavar='command', required=True)
    _add_run(commands)
    _add_topic(commands)
    _add_interface(commands)
    _add_bag(commands)
    _add_bridge(commands)
    _add_delegates(commands, added)
    return parser


def _command_name(args) -> str:
    return ' '.join(filter(None, (PROG, args.command, getattr(args, 'verb', None))))


def parse(argv: Sequence[str]) -> argparse.Namespace:
    """The parsed command line; an added command gets every later argument verbatim."""
    added = added_commands()
    parser = build_parser(added)
    if argv and argv[0] in added:
        args = parser.parse_args(argv[:1])
        args.argv = list(argv[1:])
        return args
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(sys.argv[1:] if argv is None else list(argv))
    from stealth_tools.bag_format import BagError

    try:
        return args.handler(args)
    except (CommandError, BagError) as error:
        print(f'{_command_name(args)}: {error}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        sys.stderr.close()  # the reader went away (e.g. `| head`): no traceback
        return 0


if __name__ == '__main__':
    sys.exit(main())
