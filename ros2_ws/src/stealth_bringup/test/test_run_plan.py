"""The train command line checked and laid out before anything starts (no ROS)."""

from pathlib import Path
import socket

import pytest
from stealth_bringup.run_config import RunConfigError
from stealth_bringup.run_plan import make_plan, train_parser

SCENARIOS = Path(__file__).resolve().parents[4] / 'scenarios'


def plan_of(*argv, runs_dir):
    args = train_parser().parse_args([*argv, '--runs-dir', str(runs_dir)])
    return make_plan(args, 'train', ['stealth', 'train', *argv])


@pytest.mark.parametrize(
    'scenario', ['simple-maze', str(SCENARIOS / 'simple-maze.yaml'), 'scenarios/simple-maze.yaml']
)
def test_the_default_scenario_defaults_to_its_quick_goal_however_it_is_named(
    scenario, tmp_path, monkeypatch
):
    monkeypatch.chdir(SCENARIOS.parent)
    assert plan_of('--scenario', scenario, runs_dir=tmp_path).goal == 'easy'


def test_other_scenarios_default_to_their_own_goal(tmp_path):
    from stealth_env.scenario import load_scenario

    plan = plan_of('--scenario', 'lgfloor', runs_dir=tmp_path)
    assert plan.goal == load_scenario('lgfloor').default_goal


@pytest.mark.parametrize(
    ('argv', 'message'),
    [
        (['--seed', 'abc'], "argument --seed: 'abc' is not a whole number"),
        (['--episodes', '2.5'], "argument --episodes: '2.5' is not a whole number"),
        (['--stall-timeout', 'soon'], "argument --stall-timeout: 'soon' is not a number"),
    ],
)
def test_bad_numbers_name_the_option_and_the_value(argv, message, capsys):
    with pytest.raises(SystemExit):
        train_parser().parse_args(argv)
    assert capsys.readouterr().err.strip().splitlines()[-1].endswith(message)


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def test_watch_adds_the_foxglove_bridge_on_its_port(tmp_path):
    plain = plan_of(runs_dir=tmp_path)
    assert 'bridge' not in plain.nodes and plain.watch_port is None
    port = free_port()
    plan = plan_of('--watch', '--set', f'bridge.port={port}', runs_dir=tmp_path)
    assert plan.nodes == ['recorder', 'bridge', 'simulator', 'environment', 'agent']
    assert plan.commands['bridge'][0].endswith('/stealth_tools/bridge')
    assert plan.watch_port == port
    assert plan.parameters['simulator'].values['real_time_factor'] == 1.0


def test_watch_with_the_bridge_port_in_use_is_one_line_naming_port_and_option(tmp_path):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(RunConfigError) as error:
            plan_of('--watch', '--set', f'bridge.port={port}', runs_dir=tmp_path)
    message = str(error.value)
    assert '\n' not in message and f'port {port} is in use' in message
    assert message.endswith('--set bridge.port=N')
    assert not (tmp_path / 'runs').exists()  # nothing was made


def test_a_bridge_executable_without_watch_is_refused(tmp_path):
    with pytest.raises(RunConfigError, match='this run has no bridge node'):
        plan_of('--executable', 'bridge=/bin/true', runs_dir=tmp_path)
