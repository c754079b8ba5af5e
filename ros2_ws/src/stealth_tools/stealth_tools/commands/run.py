"""`stealth run <package> <executable> [args...]`: ros2 run, over the ament index of this
workspace (stealth_tools.executables finds and supervises the executable)."""

from __future__ import annotations

import argparse
import shlex

from stealth_tools.errors import CommandError


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


def add_parser(commands) -> None:
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
