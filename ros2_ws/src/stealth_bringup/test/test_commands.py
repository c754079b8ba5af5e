"""The commands stealth_bringup adds to `stealth`, found the way `stealth` finds them: through
the entry-point group its setup.py registers."""

import pytest
from stealth_bringup.commands import COMMANDS
from stealth_tools import cli


def test_stealth_finds_train_eval_render_sweep_and_doctor_in_this_order():
    added = cli.added_commands()
    assert list(added)[:5] == ['train', 'eval', 'render', 'sweep', 'doctor']
    assert {name: added[name] for name in COMMANDS} == COMMANDS
    assert cli.build_parser().description.endswith(', plus train, eval, render, sweep and doctor.')


@pytest.mark.parametrize('command', list(COMMANDS))
def test_every_added_command_has_help(capsys, command):
    try:
        status = cli.main([command, '--help'])
    except SystemExit as exit_:
        status = exit_.code
    out, _ = capsys.readouterr()
    assert status == 0
    assert 'usage:' in out or command == 'render'
