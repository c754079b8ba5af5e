"""The train command line checked and laid out before anything starts (no ROS)."""

from pathlib import Path

import pytest
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
