"""`stealth bag record|play|info|recover|compare`: ros2 bag's verbs, MCAP only, plus recover (as
mcap recover) and compare (two runs' RL episodes). Each verb's options sit beside its function;
the work is done by the bag modules of stealth_tools (recorder, player, bag_reading, ...)."""

from __future__ import annotations

import sys

from stealth_tools.commands import PROG
from stealth_tools.commands.arguments import (
    add_discovery_arguments,
    in_ros,
    non_negative_float,
    port,
    positive_float,
    positive_int,
)
from stealth_tools.errors import CommandError

COMPRESSIONS = ('zstd', 'lz4', 'none')


def add_parser(commands) -> None:
    bag = commands.add_parser(
        'bag', help='Various rosbag related sub-commands', description='ros2 bag, MCAP only.'
    )
    verbs = bag.add_subparsers(dest='verb', metavar='verb', required=True)
    for add_verb in (_add_record, _add_play, _add_info, _add_recover, _add_compare):
        add_verb(verbs)


# --- record ------------------------------------------------------------------------------------


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


def _add_record(verbs) -> None:
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
        type=positive_float,
        default=0.5,
        metavar='S',
        help='close a chunk after S seconds, bounding what a SIGKILL loses (default: %(default)s)',
    )
    parser.add_argument(
        '--chunk-size',
        type=positive_int,
        default=256 * 1024,
        metavar='BYTES',
        help='close a chunk at this size (default: %(default)s)',
    )
    add_discovery_arguments(parser, 200)
    parser.set_defaults(handler=bag_record)


# --- play --------------------------------------------------------------------------------------


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


def _add_play(verbs) -> None:
    parser = verbs.add_parser(
        'play',
        help='Play back ROS data from a bag',
        description='Publish the messages of a bag with their original timing and QoS.',
    )
    parser.add_argument(
        'bag_path', help='bag directory (a run directory: all its recording files) or .mcap file'
    )
    parser.add_argument(
        '-r', '--rate', type=positive_float, default=1.0, help='playback rate factor'
    )
    parser.add_argument('--topics', nargs='+', default=[], metavar='topic', help='topics to play')
    parser.add_argument(
        '--clock',
        type=positive_float,
        nargs='?',
        const=40.0,
        default=0.0,
        metavar='HZ',
        help='publish /clock at HZ (default when given: 40) as a ROS time source',
    )
    parser.add_argument('-l', '--loop', action='store_true', help='play again and again')
    parser.add_argument(
        '--start-offset',
        type=non_negative_float,
        default=0.0,
        metavar='S',
        help='start S seconds into the bag',
    )
    parser.add_argument(
        '-d',
        '--delay',
        type=non_negative_float,
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
        type=port,
        default=8765,
        metavar='PORT',
        help='the port of --bridge (default: %(default)s)',
    )
    parser.set_defaults(handler=in_ros(bag_play))


# --- info --------------------------------------------------------------------------------------


def bag_info(args) -> int:
    from stealth_tools.bag_format import cut_before_header
    from stealth_tools.bag_reading import format_bag_info, read_bag_info

    info = read_bag_info(args.bag_path)
    for path in info.unindexed:
        if empty := cut_before_header(path):  # one file of several: it adds nothing
            print(f'warning: {empty}', file=sys.stderr)
            continue
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


def _add_info(verbs) -> None:
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


# --- recover -----------------------------------------------------------------------------------


def bag_recover(args) -> int:
    from stealth_tools.bag_files import bag_files
    from stealth_tools.bag_format import cut_before_header
    from stealth_tools.bag_reading import read_bag_info
    from stealth_tools.bag_recover import recover

    files = bag_files(args.bag_path)
    if len(files) > 1:  # a split bag: every file that was never closed
        if args.output:
            raise CommandError(
                f'{args.bag_path} holds {len(files)} files; -o names the copy of one: '
                'give that file instead of the directory'
            )
        empty = [line for line in map(cut_before_header, files) if line]
        for line in empty:
            print(f'{line} (skipped)')
        files = [f for f in files if not cut_before_header(f) and not read_bag_info(f).indexed]
        if not files and not empty:
            print(f'{args.bag_path}: every file is complete and indexed; nothing to recover')
    for file in files:
        output, report = recover(file, args.output, compression=args.compression)
        print(f'{output}: {report.summary()}')
    return 0


def _add_recover(verbs) -> None:
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


# --- compare -----------------------------------------------------------------------------------


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


def _add_compare(verbs) -> None:
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
        type=positive_int,
        help='compare the first N episodes (default: as many as both hold complete)',
    )
    parser.set_defaults(handler=bag_compare)
