"""`stealth`: ros2cli's verbs and argument shapes for what this platform lacks, plus the
commands other packages add, so habits from a full ROS 2 install carry over.

    stealth run <package> <executable> [args...]      # ros2 run
    stealth topic list|echo|hz|info ...               # ros2 topic
    stealth interface show <pkg/msg/Type>             # ros2 interface show
    stealth bag record|play|info|recover ...          # ros2 bag (+ recover, as mcap recover)
    stealth bridge [--port 8765] [--topics ...]       # foxglove_bridge, on foxglove-sdk's server
    stealth train|rollout|render ...                  # added by stealth_bringup (see below)

Each command of this package is a module of stealth_tools.commands: its parser, its verbs and
their functions; this module builds the command line and runs it. Other packages add commands
as ros2cli's extension points add verbs: an entry point in the group `stealth.commands` names a
mapping {command: (module, function, summary)}; the function takes the command's argv and is
imported only when the command runs. So this package knows nothing above it, and
`stealth train` works wherever stealth_bringup is installed.

Every failure is one line on stderr and exit status 1; parsing needs no ROS, so --help is fast.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
import importlib
import sys

from stealth_tools.commands import PROG
from stealth_tools.errors import CommandError

# Entry points of this group add commands: see the module docstring.
COMMAND_GROUP = 'stealth.commands'
# This package's own commands, in --help's order: each a module of stealth_tools.commands.
OWN_COMMANDS = ('run', 'topic', 'interface', 'bag', 'bridge')


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
    for name in OWN_COMMANDS:
        importlib.import_module(f'stealth_tools.commands.{name}').add_parser(commands)
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
