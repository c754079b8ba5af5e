"""The command stealth_experiments adds to `stealth`, found the way `stealth` finds it: through
the entry-point group its setup.py registers."""

from stealth_experiments.commands import COMMANDS
from stealth_tools import cli


def test_stealth_finds_sweep():
    added = cli.added_commands()
    assert {name: added[name] for name in COMMANDS} == COMMANDS
    assert cli.build_parser().description.endswith(' and sweep.')


def test_sweep_has_help(capsys):
    try:
        status = cli.main(['sweep', '--help'])
    except SystemExit as exit_:
        status = exit_.code
    out, _ = capsys.readouterr()
    assert status == 0
    assert out.startswith('usage: stealth sweep ')
