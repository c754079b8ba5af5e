"""The CLI without a ROS graph: --help everywhere, one-line errors, the file verbs (the graph
verbs are exercised in the repository's tests/test_cli.py; the commands stealth_bringup adds, in
its test_commands.py)."""

import argparse
import os
import pkgutil
import sys

from sample_bags import chatter_samples, write_bag
from stealth_tools import cli, commands
from stealth_tools.executables import failure_line, run_supervised


def command_paths(parser: argparse.ArgumentParser, prefix=()):
    """Every command and verb of the parser, e.g. ('topic', 'echo')."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*prefix, name)
                yield from command_paths(sub, (*prefix, name))


def run_cli(capsys, *argv):
    """(exit status, stdout, stderr) of `stealth argv...` run in this process."""
    try:
        status = cli.main(list(argv))
    except SystemExit as exit_:
        status = exit_.code
    out, err = capsys.readouterr()
    return status, out, err


def test_every_command_has_help(capsys):
    paths = list(command_paths(cli.build_parser(added={})))
    assert {('run',), ('topic', 'hz'), ('interface', 'show'), ('bag', 'recover')} <= set(paths)
    for path in [(), *paths]:
        status, out, _ = run_cli(capsys, *path, '--help')
        assert status == 0, path
        assert 'usage:' in out or 'Usage' in out, path


def test_each_own_command_is_a_module_of_commands():
    modules = {module.name for module in pkgutil.iter_modules(commands.__path__)}
    assert modules - {'arguments'} == set(cli.OWN_COMMANDS)


def test_commands_not_written_yet_say_so_in_one_line(capsys, monkeypatch):
    added = {'train': ('stealth_bringup.no_such_module', 'train_main', 'Train.')}
    monkeypatch.setattr(cli, 'added_commands', lambda: added)
    status, out, err = run_cli(capsys, 'train', '--episodes', '3')
    assert status == 1 and out == ''
    assert err == (
        'stealth train: not available yet (stealth_bringup.no_such_module.train_main does not '
        'exist)\n'
    )


def test_file_errors_are_one_line(capsys, tmp_path):
    status, _, err = run_cli(capsys, 'bag', 'info', str(tmp_path / 'nope.mcap'))
    assert status == 1
    assert err == f'stealth bag info: {tmp_path}/nope.mcap: no such file or directory\n'
    (tmp_path / 'notes.txt').write_text('hello')
    status, _, err = run_cli(capsys, 'bag', 'recover', str(tmp_path / 'notes.txt'))
    assert status == 1 and err.count('\n') == 1 and 'not an MCAP file' in err
    status, _, err = run_cli(capsys, 'interface', 'show', 'std_msgs/msg/Nope')
    assert status == 1 and err.count('\n') == 1
    assert err.startswith("stealth interface show: package 'std_msgs' has no message 'Nope'")


def test_bag_info_and_recover(capsys, tmp_path):
    write_bag(tmp_path / 'run.mcap', chatter_samples(5))
    status, out, _ = run_cli(capsys, 'bag', 'info', str(tmp_path / 'run.mcap'))
    assert status == 0 and 'Messages:          5\n' in out
    status, out, _ = run_cli(capsys, 'bag', 'info', '-t', str(tmp_path / 'run.mcap'))
    assert out == '/chatter\n'
    status, out, _ = run_cli(capsys, 'bag', 'recover', str(tmp_path / 'run.mcap'))
    assert status == 0 and out.startswith(f'{tmp_path}/run.recovered.mcap: recovered 5 messages')


def test_an_mcap_cut_before_its_header_gets_the_same_one_line_from_info_play_and_recover(
    capsys, tmp_path
):
    bag = tmp_path / 'x.mcap'
    write_bag(bag, chatter_samples(5))
    os.truncate(bag, 10)  # the magic and two bytes of the header record
    line = (
        f'{bag}: an MCAP file that ends before its header is complete (10 bytes): it holds no '
        'messages; nothing to play or recover\n'
    )
    for verb in ('info', 'play', 'recover'):
        assert run_cli(capsys, 'bag', verb, str(bag)) == (1, '', f'stealth bag {verb}: {line}')
    assert sorted(tmp_path.iterdir()) == [bag]  # no recovered copy
    bag.write_bytes(b'0123456789')  # and without even the magic
    line = f'{bag}: not an MCAP file (10 bytes, no MCAP magic): nothing to play or recover\n'
    for verb in ('info', 'play', 'recover'):
        assert run_cli(capsys, 'bag', verb, str(bag)) == (1, '', f'stealth bag {verb}: {line}')


def test_a_header_less_file_among_a_recordings_files_is_named_and_skipped(capsys, tmp_path):
    write_bag(tmp_path / 'recording.mcap', chatter_samples(5))
    stub = tmp_path / 'recording_1.mcap'  # a recorder restarted and killed as it began
    write_bag(stub, chatter_samples(2))
    os.truncate(stub, 12)
    line = (
        f'{stub}: an MCAP file that ends before its header is complete (12 bytes): it holds no '
        'messages; nothing to play or recover'
    )
    status, out, err = run_cli(capsys, 'bag', 'info', str(tmp_path))
    assert status == 0 and 'Messages:          5\n' in out and err == f'warning: {line}\n'
    status, out, err = run_cli(capsys, 'bag', 'recover', str(tmp_path))
    assert (status, out, err) == (0, f'{line} (skipped)\n', '')


def test_interface_show(capsys):
    status, out, _ = run_cli(capsys, 'interface', 'show', '--no-comments', 'std_msgs/msg/Header')
    assert status == 0
    assert out == 'builtin_interfaces/Time stamp\n\tint32 sec\n\tuint32 nanosec\nstring frame_id\n'


def test_a_failing_child_gets_one_line_with_its_last_words(capfd):
    status = run_supervised(
        [sys.executable, '-c', "import sys; print('starting'); sys.exit('cannot open map.yaml')"],
        'stealth_sim sim_node',
    )
    assert status == 1
    out, err = capfd.readouterr()
    assert out == 'starting\n'
    lines = err.splitlines()
    assert lines[0] == 'cannot open map.yaml'  # the child's own stderr, passed through
    assert lines[1].startswith('stealth run: stealth_sim sim_node exited with code 1 after ')
    assert lines[1].endswith(' s: cannot open map.yaml')


def test_failure_lines():
    assert failure_line('p e', 0, 1.0, 'x') is None
    assert failure_line('p e', -11, 2.04, '') == 'p e was killed by SIGSEGV after 2.0 s'
