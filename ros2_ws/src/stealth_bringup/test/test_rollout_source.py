"""stealth rollout checks the policy's scenario by content (map and lights), not by its name
alone, before anything starts (no ROS)."""

from pathlib import Path
import re

import pytest
from stealth_agent.learners import make_learner
from stealth_agent.policy_store import save_policy
from stealth_agent.state_index import StateIndex
from stealth_bringup.run_arguments import rollout_parser
from stealth_bringup.run_config import RunConfigError
from stealth_bringup.run_plan import make_plan
from stealth_core.scenario import content_identity, load_scenario
from stealth_core.task import StealthTask

REPO = Path(__file__).resolve().parents[4]
MAZE = (REPO / 'scenarios' / 'simple-maze.yaml').read_text()


def scenario_copy(directory: Path, text: str = MAZE, map_dir: Path = REPO / 'maps') -> Path:
    """scenarios/simple-maze.yaml as <directory>/simple-maze.yaml: the same name."""
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / 'simple-maze.yaml'
    path.write_text(text.replace('map: ../maps/', f'map: {map_dir}/'))
    return path


def policy_for(path: Path, scenario_path: Path, content: bool = True) -> Path:
    """A policy file as a run on that scenario saves it (content: a run that knew the hashes)."""
    scenario = load_scenario(scenario_path)
    identity = {'title': StealthTask(scenario, 'easy').title}
    if content:
        identity.update(content_identity(scenario))
    save_policy(path, make_learner('qlearning', 4), StateIndex(), scenario=identity)
    return path


def rollout_plan(policy: Path, scenario: Path, runs_dir: Path):
    argv = ['--policy', str(policy), '--scenario', str(scenario), '--goal', 'easy']
    args = rollout_parser().parse_args([*argv, '--runs-dir', str(runs_dir)])
    return make_plan(args, 'eval', ['stealth', 'rollout', *argv])


def test_the_scenario_it_was_trained_on_runs_without_a_word(tmp_path):
    trained = scenario_copy(tmp_path / 'a')
    policy = policy_for(tmp_path / 'policy.npz', trained)
    plan = rollout_plan(policy, scenario_copy(tmp_path / 'b'), tmp_path / 'runs')  # a copy
    assert plan.notes == []


def test_other_lights_under_the_same_name_are_refused(tmp_path):
    policy = policy_for(tmp_path / 'policy.npz', scenario_copy(tmp_path / 'a'))
    moved = MAZE.replace('x: 0.75, y: 8.0', 'x: 0.75, y: 8.5')
    assert moved != MAZE
    other = scenario_copy(tmp_path / 'b', moved)
    with pytest.raises(RunConfigError) as error:
        rollout_plan(policy, other, tmp_path / 'runs')
    assert str(error.value) == (
        f"{policy} was trained on scenario 'simple-maze' with different lights than {other} has "
        'now (the same name, other content): give --scenario the scenario file it was trained '
        'on, or train a policy on this one'
    )
    assert not (tmp_path / 'runs').exists()


def test_another_map_under_the_same_name_is_refused(tmp_path):
    maps = tmp_path / 'maps'
    maps.mkdir()
    (maps / 'simple-maze.yaml').write_text((REPO / 'maps' / 'simple-maze.yaml').read_text())
    image = bytearray((REPO / 'maps' / 'simple-maze.pgm').read_bytes())
    header = len(re.match(rb'P5\s+\d+\s+\d+\s+\d+\s', image).group(0))
    wall = image.index(b'\x00', header)  # one wall pixel made free: another map, still valid
    image[wall] = 254
    (maps / 'simple-maze.pgm').write_bytes(bytes(image))
    policy = policy_for(tmp_path / 'policy.npz', scenario_copy(tmp_path / 'a'))
    other = scenario_copy(tmp_path / 'b', map_dir=maps)
    with pytest.raises(RunConfigError, match=r"trained on scenario 'simple-maze' with a "
                       r'different map than .* has now'):  # fmt: skip
        rollout_plan(policy, other, tmp_path / 'runs')


def test_a_policy_saved_before_the_hashes_gets_a_note_that_only_the_name_is_checked(tmp_path):
    scenario = scenario_copy(tmp_path / 'a')
    policy = policy_for(tmp_path / 'policy.npz', scenario, content=False)
    plan = rollout_plan(policy, scenario, tmp_path / 'runs')
    assert plan.notes == [
        f'{policy} records no map or lights hash (saved before policies did): only its '
        f'scenario name is checked, not whether {scenario} still has the map and lights it was '
        'trained on'
    ]


def test_a_training_run_gives_the_agent_the_hashes_to_save(tmp_path):
    from stealth_bringup.run_arguments import train_parser

    args = train_parser().parse_args(['--runs-dir', str(tmp_path)])
    plan = make_plan(args, 'train', ['stealth', 'train'])
    identity = content_identity(load_scenario('simple-maze'))
    assert {key: plan.parameters['agent'].values[key] for key in identity} == identity


def plugin_plan(runs_dir: Path, *argv: str):
    parser = rollout_parser()
    args = parser.parse_args([*argv, '--runs-dir', str(runs_dir)])
    return make_plan(args, 'eval', ['stealth', 'rollout', *argv])


def test_a_policy_plugin_runs_with_the_grid_sent_to_it(tmp_path):
    pytest.importorskip('jax', reason='the generalist plugin needs the learning extra')
    plan = plugin_plan(tmp_path, '--learner', 'generalist', '--scenario', 'simple-maze')
    agent = plan.parameters['agent'].values
    assert agent['agent'] == 'generalist' and agent['evaluate'] is True
    assert agent['policy_file'].endswith('policies/generalist-full.npz')
    assert plan.parameters['environment'].values['observation_layout'] == 'grid'
    assert 'policy generalist ' in plan.describe()
    with pytest.raises(RunConfigError, match=r'--learner generalist: .*none\.npz: no such'):
        plugin_plan(tmp_path, '--learner', 'generalist', '--scenario', 'simple-maze',
                    '--policy', str(tmp_path / 'none.npz'))  # fmt: skip


def test_a_plugin_refuses_a_scenario_it_cannot_play_naming_both(tmp_path):
    """The generalist reads no phase and cannot wait: a moving-light scenario is refused
    before anything starts, naming the weights and the scenario (issue 42)."""
    pytest.importorskip('jax', reason='the generalist plugin needs the learning extra')
    from stealth_core.scenario import find_scenario

    with pytest.raises(RunConfigError) as error:
        plugin_plan(tmp_path, '--learner', 'generalist', '--scenario', 'map1-moving')
    message = str(error.value)
    assert message.startswith('--learner generalist: ')
    assert 'policies/generalist-full.npz: the policy was trained for static lights' in message
    assert f"scenario 'map1-moving' ({find_scenario('map1-moving')}) has moving lights" in message
    assert '\n' not in message and not list(tmp_path.iterdir())


def test_time_aware_weights_play_moving_lights_of_their_cycle_on_both_tracks(tmp_path):
    """The time-aware weights run on moving lights, lights known or sensed (the environment
    sends the phased grid, or the phased grid of what was sensed); they are refused before
    anything starts, in one line, on static lights and for another cycle (naming both layouts).
    Exposure is refused on either track (no grid carries the heading)."""
    pytest.importorskip('jax', reason='the generalist plugin needs the learning extra')
    from stealth_learn.generalist import GeneralistPolicy
    from stealth_learn.policy_file import SHIPPED, save

    moving = str(SHIPPED.with_name('generalist-moving.npz'))
    plan = plugin_plan(tmp_path / 'ok', '--learner', 'generalist', '--policy', moving,
                       '--scenario', 'simple-maze-moving')  # fmt: skip
    assert plan.parameters['agent'].values['policy_file'] == moving
    assert plan.parameters['environment'].values['observation_layout'] == 'grid'
    sensed = plugin_plan(
        tmp_path / 'sensed',
        '--learner',
        'generalist',
        '--policy',
        moving,
        '--scenario',
        'simple-maze-moving',
        '--set',
        'environment.track=sensed',
    )
    assert sensed.parameters['environment'].values['track'] == 'sensed'
    assert sensed.parameters['environment'].values['observation_layout'] == 'grid'
    refused = tmp_path / 'refused'
    with pytest.raises(RunConfigError) as error:
        plugin_plan(refused, '--learner', 'generalist', '--policy', moving,
                    '--scenario', 'simple-maze')  # fmt: skip
    message = str(error.value)
    assert "the policy is time-aware (layout 'stealth-phased-v1/full/8phases-1perstep')" in message
    assert "has static lights (layout 'stealth-grid-v1/full')" in message
    architecture = {'iterations': 20, 'hidden': 4, 'features': 2, 'threshold': 0.3}
    architecture.update(layers=4, advance=1)
    other = save(tmp_path / 'four.npz', GeneralistPolicy.untrained(architecture).variables[
        'params'], 'full', architecture)  # fmt: skip
    with pytest.raises(RunConfigError) as cycle:
        plugin_plan(refused, '--learner', 'generalist', '--policy', str(other),
                    '--scenario', 'simple-maze-moving')  # fmt: skip
    assert "'stealth-phased-v1/full/4phases-1perstep'" in str(cycle.value)
    assert "'stealth-phased-v1/full/8phases-1perstep'" in str(cycle.value)
    with pytest.raises(RunConfigError) as exposure:
        plugin_plan(refused, '--learner', 'generalist', '--scenario', 'simple-maze-exposure',
                    '--set', 'environment.track=sensed')  # fmt: skip
    assert str(exposure.value).startswith('--learner generalist: environment.track sensed: ')
    assert "scenario 'simple-maze-exposure' weighs exposure" in str(exposure.value)
    for each in (error, cycle, exposure):
        assert '\n' not in str(each.value)
    assert not refused.exists()


def test_a_plugin_needs_a_scenario_and_must_exist(tmp_path):
    with pytest.raises(RunConfigError, match='give --scenario'):
        plugin_plan(tmp_path, '--learner', 'generalist')
    with pytest.raises(RunConfigError, match="no policy plugin 'ppo'"):
        plugin_plan(tmp_path, '--learner', 'ppo', '--scenario', 'simple-maze')


def test_a_refused_rollout_leaves_no_directory_in_the_run(tmp_path):
    """A rollout of a run's policy goes into the run's directory: refused, it adds nothing."""
    scenario = scenario_copy(tmp_path / 'a')
    run = tmp_path / 'runs' / 'trained'
    run.mkdir(parents=True)
    policy_for(run / 'policy.npz', scenario)
    before = sorted(run.iterdir())
    argv = ['--run', str(run), '--scenario', str(scenario), '--goal', 'easy']
    argv += ['--set', 'agent.log_every=-1']
    args = rollout_parser().parse_args(argv)
    with pytest.raises(RunConfigError, match='--set agent.log_every: expected a whole number'):
        make_plan(args, 'eval', ['stealth', 'rollout', *argv])
    assert sorted(run.iterdir()) == before


def light_model_policy_for(path: Path, scenario_path: Path) -> Path:
    """A light-model policy as its agent saves it: attached to the scenario without its lights,
    one detected step of evidence, the true scenario's identity (the run's hashes)."""
    import numpy as np
    from stealth_agent.light_model import LightModelLearner
    from stealth_core.light_world import LightWorld

    scenario = load_scenario(scenario_path)
    learner = LightModelLearner(4)
    index = StateIndex()
    learner.attach(LightWorld(scenario, 'easy'), index, np.random.default_rng(0))
    learner.update(0, 0, -1010.0, None, True)  # a detection on the first step
    learner.end_episode()
    identity = {'title': StealthTask(scenario, 'easy').title, **content_identity(scenario)}
    save_policy(path, learner, index, scenario=identity)
    return path


def test_a_light_model_policy_runs_only_on_its_own_scenario(tmp_path):
    policy = light_model_policy_for(tmp_path / 'policy.npz', scenario_copy(tmp_path / 'a'))
    assert rollout_plan(policy, scenario_copy(tmp_path / 'b'), tmp_path / 'runs').notes == []
    moved = scenario_copy(tmp_path / 'c', MAZE.replace('x: 0.75, y: 8.0', 'x: 0.75, y: 8.5'))
    with pytest.raises(RunConfigError, match='with different lights than'):
        rollout_plan(policy, moved, tmp_path / 'runs2')
    argv = ['--policy', str(policy), '--scenario', 'map1']
    args = rollout_parser().parse_args([*argv, '--runs-dir', str(tmp_path / 'runs3')])
    with pytest.raises(RunConfigError) as other:
        make_plan(args, 'eval', ['stealth', 'rollout', *argv])
    assert 'simple-maze' in str(other.value) and '\n' not in str(other.value)
    assert not (tmp_path / 'runs2').exists() and not (tmp_path / 'runs3').exists()
