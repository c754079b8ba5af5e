"""The commands stealth_bringup adds to `stealth`, found the way `stealth` finds them: through
the entry-point group its setup.py registers."""

import pytest
from stealth_bringup.commands import COMMANDS
from stealth_tools import cli


def test_stealth_finds_train_rollout_eval_and_doctor_in_this_order():
    added = cli.added_commands()
    assert list(added)[:4] == ['train', 'rollout', 'eval', 'doctor']
    assert {name: added[name] for name in COMMANDS} == COMMANDS
    assert ', plus train, rollout, eval, doctor' in cli.build_parser().description


@pytest.mark.parametrize('command', list(COMMANDS))
def test_every_added_command_has_help(capsys, command):
    try:
        status = cli.main([command, '--help'])
    except SystemExit as exit_:
        status = exit_.code
    out, _ = capsys.readouterr()
    assert status == 0
    assert 'usage:' in out


def test_the_old_name_eval_says_it_is_now_rollout_and_runs_rollout(capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main(['eval', '--help'])
    out, err = capsys.readouterr()
    assert exit_.value.code == 0
    assert err == 'stealth eval is now stealth rollout\n'
    assert out.startswith('usage: stealth rollout ')
