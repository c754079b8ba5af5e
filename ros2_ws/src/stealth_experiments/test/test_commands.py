"""The commands stealth_experiments adds to `stealth`, found the way `stealth` finds it: through
the entry-point group its setup.py registers."""

import pytest
from stealth_experiments.commands import COMMANDS
from stealth_tools import cli


def test_stealth_finds_sweep_benchmark_and_generalist():
    added = cli.added_commands()
    assert {name: added[name] for name in COMMANDS} == COMMANDS
    assert set(COMMANDS) == {'sweep', 'benchmark', 'generalist'}
    assert cli.build_parser().description.endswith(', sweep, benchmark and generalist.')


@pytest.mark.parametrize('command', ['sweep', 'benchmark', 'generalist'])
def test_each_command_has_help(capsys, command):
    try:
        status = cli.main([command, '--help'])
    except SystemExit as exit_:
        status = exit_.code
    out, _ = capsys.readouterr()
    assert status == 0
    assert out.startswith(f'usage: stealth {command} ')
