"""The unknown-light baselines: Dark Path replanned on what has been sensed, unsensed places
assumed dark or lit where a lamp could reach them."""

import dataclasses

import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv
from stealth_core.planners import follow, value_iteration, walk
from stealth_core.replanning import SensedReplanner, lamp_reach, play
from stealth_core.reward import EpisodeOutcome
from stealth_core.task import WAIT, StealthTask

# The shipped scenarios whose lights stand still (their easy goals must be reached unseen).
STATIC = [
    'map1',
    'map1-bounce',
    'map1-exposure',
    'simple-maze',
    'simple-maze-exposure',
    'floorplan',
    'lgfloor',
    'lgfloor-bounce',
]


def checked(env, planner):
    """The planner's act, asserting it never drives into a wall (a move that goes nowhere)."""
    n = len(env.model.nodes)

    def act(observation):
        action = planner.act(observation)
        here = env.node % n
        assert action == WAIT or env.model.successors[env.node, action] % n != here, action
        return action

    return act


@pytest.mark.parametrize('unknown', ['dark', 'lit'])
@pytest.mark.parametrize('scenario', STATIC)
def test_the_replanners_reach_the_easy_goal_unseen_where_value_iteration_does(scenario, unknown):
    env = StealthNavEnv(scenario, 'easy', track='sensed')
    model = env.model
    optimum = value_iteration(model)
    assert (
        walk(model, follow(model, lambda i: int(optimum.policy[i]))).outcome
        is EpisodeOutcome.SUCCESS
    )
    result = play(env, checked(env, SensedReplanner(model, unknown)), seed=0)
    assert EpisodeOutcome(result['outcome']) is EpisodeOutcome.SUCCESS
    assert result['peak_visibility'] < model.task.scenario.detection_threshold
    assert result['total_reward'] <= optimum.optimal_return + 1e-9
    assert len(result['points']) == result['steps'] + 1


def test_with_every_way_seen_lit_the_robot_still_picks_a_real_move():
    env = StealthNavEnv('map1', track='sensed')
    planner = SensedReplanner(env.model, 'dark')
    observation, _ = env.reset(seed=0)
    lit = {
        **observation,
        'light': np.where(observation['light'] >= -1, 1.0, observation['light']),
        'moves': np.where(observation['moves'] >= -1, 1.0, observation['moves']),
    }
    assert planner.plan(lit) is None
    action = planner.act(lit)
    here = env.model.start
    assert env.model.successors[here, action] != here


def test_unsensed_places_are_dark_to_the_optimist_and_lit_to_the_pessimist_where_lamps_reach():
    env = StealthNavEnv('map1', track='sensed')
    observation, _ = env.reset(seed=0)
    dark = SensedReplanner(env.model, 'dark').estimates(observation)
    lit = SensedReplanner(env.model, 'lit').estimates(observation)
    sensed = env.sensor.memory.move_known
    threshold = env.scenario.detection_threshold
    assert np.array_equal(dark[sensed], lit[sensed])
    unsensed_dark = ~sensed & (dark == 0)
    assert unsensed_dark.any() and np.all(lit[unsensed_dark] == threshold)


def test_lamp_reach_is_nowhere_when_lights_reach_less_than_the_clearance():
    model = StealthNavEnv('map1').model
    assert lamp_reach(model).all()  # map1's lights reach several metres: every node
    lights = tuple(dataclasses.replace(light, range=0.01) for light in model.task.scenario.lights)
    tiny = dataclasses.replace(model.task.scenario, lights=lights)
    model = dataclasses.replace(model, task=StealthTask(tiny, model.task.goal))
    assert not lamp_reach(model).any()


def test_an_unknown_rule_is_refused():
    with pytest.raises(ValueError, match="unknown: expected one of dark, lit, got 'grey'"):
        SensedReplanner(StealthNavEnv('map1').model, 'grey')
