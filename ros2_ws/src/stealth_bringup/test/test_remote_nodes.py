"""Nodes on other hosts (--remote): the command printed for the other host and what the graph
tells of such a node (no ROS)."""

import shlex

import pytest
from stealth_bringup.remote_nodes import RemoteNode, RemoteNodes, join_command
from stealth_bringup.run_arguments import train_parser
from stealth_bringup.run_config import RunConfigError, RunError, parse_value
from stealth_bringup.run_plan import _executables


def test_the_join_command_names_domain_range_and_every_parameter_inline():
    values = {
        'policy_file': '/runs/a b/policy.npz',
        'epsilon': 0.1,
        'seed': 3,
        'evaluate': False,
        'initial_pose': [1.0, 2.5, 0.0],
        'agent': '7',  # a string that looks like a number stays a string
    }
    command = join_command('agent', values, 42, 'subnet')
    assert command[:5] == [
        'env', '-u', 'ROS_LOCALHOST_ONLY', 'ROS_DOMAIN_ID=42',
        'ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET',
    ]  # fmt: skip
    assert command[5:10] == ['stealth', 'run', 'stealth_agent', 'agent_node', '--ros-args']
    # Through the shell and back, every -p gives the value it was made from.
    words = shlex.split(shlex.join(command))
    assert words == command
    given = dict(word.split(':=', 1) for word in words[11::2])
    assert words[10::2] == ['-p'] * len(values)
    assert {name: parse_value(text) for name, text in given.items()} == values
    assert join_command('simulator', {}, 7, 'localhost')[4:9] == [
        'ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST', 'stealth', 'run', 'stealth_sim', 'sim_node',
    ]  # fmt: skip


def test_a_remote_node_joins_once_and_leaving_afterwards_is_noted():
    node = RemoteNode('agent', ['stealth', 'run'], since=10.0)
    assert node.state == 'never joined' and node.seen(False, 11.0) == ''
    assert node.seen(True, 12.5) == 'joined' and node.seen(True, 13.0) == ''
    assert node.state == 'on the graph'
    assert node.seen(False, 20.0) == 'left' and node.seen(False, 21.0) == ''
    assert node.summary() == {
        'command': 'stealth run',
        'state': 'left',
        'joined_after_s': 2.5,
        'on_graph_s': 7.5,
    }


def test_remote_flags_parse_and_a_remote_node_is_not_started_here():
    args = train_parser().parse_args(
        ['--discovery', 'subnet', '--remote', 'agent', '--remote', 'simulator']
    )
    assert args.discovery == 'subnet' and args.remote == ['agent', 'simulator']
    assert train_parser().parse_args([]).discovery == 'localhost'
    with pytest.raises(SystemExit):
        train_parser().parse_args(['--remote', 'recorder'])  # it writes the run directory here
    with pytest.raises(RunConfigError, match=r"--executable 'agent=/x': agent is --remote"):
        _executables(['recorder', 'simulator', 'environment', 'agent'], ['agent=/x'], ('agent',))


def test_the_run_announces_follows_and_reminds_of_its_remote_nodes():
    lines = []
    remote = RemoteNodes(lines.append, 'stealth train')
    remote.announce('agent', {'seed': 3}, 17, 'subnet', 300.0)
    assert lines[0].startswith('waiting up to 300 s for agent to join ROS domain 17 from another')
    assert 'ROS_DOMAIN_ID=17' in lines[1] and 'seed:=3' in lines[1]
    assert 'ROS_STATIC_PEERS' in lines[2]
    assert remote.not_joined() == 'agent'
    assert remote.join_timeout('agent', 17, 300.0).startswith(
        'agent did not join ROS domain 17 within 300 s; start it on its host with: env '
    )
    remote.check({'agent', 'environment'}, 'during startup')
    assert remote.not_joined() == '' and lines[-1].startswith('agent (remote) joined the run')
    remote.remind('train', 'runs/x/policy.npz')
    assert lines[-1] == (
        'stealth train: agent runs on another host: stop it there (Ctrl-C); it saves the policy '
        'to runs/x/policy.npz (on its host) on exit'
    )
    with pytest.raises(RunError, match='agent .remote. left the ROS graph during the run after'):
        remote.check({'environment'}, 'during the run')


def test_with_every_node_remote_the_start_line_says_it_waits_for_them(tmp_path):
    from stealth_bringup.run_lifecycle import start_line
    from stealth_bringup.run_plan import make_plan

    argv = ['--no-record', '--remote', 'simulator', '--remote', 'environment', '--remote', 'agent']
    plan = make_plan(
        train_parser().parse_args([*argv, '--runs-dir', str(tmp_path)]), 'train', argv
    )
    local = [name for name in plan.nodes if name in plan.commands]
    assert local == []
    assert start_line(local, plan.remote, plan.composed) == (
        'no local nodes to start; waiting for the remote ones: simulator, environment, agent ...'
    )
    assert start_line(['recorder', 'simulator'], ('agent',), False) == (
        'starting recorder, simulator ...'
    )
    assert start_line(['recorder', 'environment'], (), True) == (
        'starting recorder, environment (the simulator in its process) ...'
    )
