"""The light model in the agent: attached to the world of its world file (the scenario without
its lights), refused in one line where that cannot be (no ROS)."""

import numpy as np
import pytest
from stealth_agent.agent_parameters import PARAMETERS, startup_problem
from stealth_agent.agent_setup import set_up_agent
from stealth_agent.light_model import LightModelLearner
from stealth_agent.policy_store import save_policy
from stealth_agent.protocol import parse_description
from stealth_core.scenario import load_scenario
from stealth_core.task import StealthTask
from stealth_core.world_file import write_world_file

DEFAULTS = {name: param.default for name, param in PARAMETERS.items()}


def description(name='simple-maze', goal='easy'):
    """The RLEnvDescription the environment sends, as the agent reads it (float32 ranges)."""
    fields = StealthTask(load_scenario(name), goal).description(False)
    for key in ('min_state_range', 'max_state_range'):
        fields[key] = list(np.float32(fields[key]))
    return parse_description(**fields)


@pytest.fixture(scope='module')
def world_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('run') / 'world.yaml'
    return write_world_file(load_scenario('simple-maze'), 'easy', path)


def light_model(**values):
    return {**DEFAULTS, 'agent': 'light-model', 'gamma': 1.0, **values}


def test_it_learns_on_the_world_of_its_file(world_file):
    setup = set_up_agent(description(), light_model(world_file=str(world_file)))
    assert setup.error == '' and setup.core is not None
    learner = setup.core.learner
    assert isinstance(learner, LightModelLearner) and learner.world.scenario.lights == ()
    assert len(setup.core.index) == learner.world.model.size  # a row for every place
    assert f'the world of {world_file} (no lights)' in setup.summary
    assert 'planning rule expected, pose jitter 0.15 m' in setup.summary
    assert learner.belief.settings.pose_jitter == 0.15  # through ROS the pose stops off its node
    assert learner.plan_margin == 0.0 and 'plan margin 0,' in setup.summary


def test_the_pose_jitter_and_the_plan_margin_reach_the_learner(world_file):
    values = light_model(world_file=str(world_file), pose_jitter=0.0, plan_margin=0.1)
    setup = set_up_agent(description(), values)
    assert setup.core.learner.belief.settings.pose_jitter == 0.0
    assert setup.core.learner.plan_margin == 0.1
    assert 'pose jitter 0 m' in setup.summary


def test_a_resumed_light_model_replays_its_evidence(world_file, tmp_path):
    first = set_up_agent(description(), light_model(world_file=str(world_file))).core
    first.handle(list(first.learner.world.model.states[0]), 0.0, False)
    first.handle(list(first.learner.world.model.states[0]), -1010.0, True)  # detected
    path = tmp_path / 'policy.npz'
    save_policy(path, first.learner, first.index, scenario={'title': description().title},
                rng=first.rng)  # fmt: skip
    values = light_model(world_file=str(world_file), load_policy=True, policy_file=str(path))
    resumed = set_up_agent(description(), values)
    assert resumed.error == ''
    assert len(resumed.core.learner.belief.evidence) == len(first.learner.belief.evidence) == 1
    evaluated = set_up_agent(description(), {**values, 'evaluate': True, 'world_file': ''})
    assert evaluated.error == '' and not evaluated.core.learning  # greedy on its table


def test_no_world_file_is_refused_at_startup():
    problem = startup_problem(light_model())
    assert 'world_file is empty' in problem and 'world.yaml' in problem
    assert startup_problem(light_model(evaluate=True, policy_file='p.npz')) is None
    assert startup_problem({**DEFAULTS, 'agent': 'prioritized'}) is None


def unusable(tmp_path, name):
    """World files the agent must refuse, by what is wrong with them."""
    if name == 'missing':
        return tmp_path / 'nowhere.yaml'
    if name == 'lights':
        return load_scenario('simple-maze').path  # the scenario itself
    if name == 'other lattice':
        return write_world_file(load_scenario('map1'), 'easy', tmp_path / 'map1.yaml')
    scenario = load_scenario('simple-maze')  # probabilistic detection: a law it cannot model
    text = write_world_file(scenario, 'easy', tmp_path / 'w.yaml').read_text()
    path = tmp_path / 'probabilistic.yaml'
    path.write_text(text.replace('detection_mode: threshold', 'detection_mode: probabilistic'))
    return path


@pytest.mark.parametrize(
    'name, part',
    [
        ('missing', 'world_file: '),
        ('lights', 'it has 2 lights, which the agent must not be told'),
        ('other lattice', "its title is 'stealth-nav: map1 (easy)'"),
        ('probabilistic', "detection_mode 'probabilistic' is not modelled by light-model"),
    ],
)
def test_an_unusable_world_file_leaves_the_agent_without_a_core(tmp_path, name, part):
    path = unusable(tmp_path, name)
    setup = set_up_agent(description(), light_model(world_file=str(path)))
    assert setup.core is None and part in setup.error and '\n' not in setup.error


def test_a_binned_state_index_is_refused(world_file):
    setup = set_up_agent(description(), light_model(world_file=str(world_file), nstates=7))
    assert setup.core is None and 'numbers states otherwise' in setup.error
