"""The Gymnasium environment: API conformance, determinism, and the same task as the core."""

import dataclasses
import warnings

import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import numpy as np
import pytest
from stealth_core.gym_env import ENV_ID, StealthNavEnv
from stealth_core.planners import astar, follow, value_iteration
from stealth_core.reward import step_reward
from stealth_core.scenario import load_scenario

SCENARIO = 'map1'
UP, LEFT = 0, 2


@pytest.fixture
def env():
    environment = gym.make(ENV_ID, scenario=SCENARIO)
    yield environment
    environment.close()


def actions_of(model, path):
    """The actions that walk a path of node indices."""
    steps = zip(path, path[1:], strict=False)
    return [int(np.flatnonzero(model.successors[a] == b)[0]) for a, b in steps]


def rollout(environment, actions, seed):
    observation, _ = environment.reset(seed=seed)
    trace = [observation.tolist()]
    for action in actions:
        observation, reward, terminated, truncated, info = environment.step(action)
        trace.append((observation.tolist(), reward, terminated, truncated, info['outcome']))
        if terminated or truncated:
            break
    return trace


def test_check_env_passes_without_any_warning():
    environment = gym.make(ENV_ID, scenario=SCENARIO, render_mode='ansi')
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        check_env(environment.unwrapped)  # also makes it in every render mode through its spec


def test_the_id_is_registered_and_takes_the_arguments():
    environment = gym.make(ENV_ID, scenario='simple-maze', goal='easy', slip=0.25)
    unwrapped = environment.unwrapped
    assert isinstance(unwrapped, StealthNavEnv)
    assert unwrapped.task.title == 'stealth-nav: simple-maze (easy)'
    assert unwrapped.slip == 0.25
    assert environment.action_space == gym.spaces.Discrete(4)


@pytest.mark.parametrize('bad', [{'slip': 1.5}, {'render_mode': 'human'}, {'goal': 'nowhere'}])
def test_bad_arguments_are_refused(bad):
    with pytest.raises(ValueError):
        StealthNavEnv(SCENARIO, **bad)


def test_two_envs_with_the_same_seed_roll_out_identically():
    actions = np.random.default_rng(5).integers(4, size=400).tolist()
    first = gym.make(ENV_ID, scenario=SCENARIO, slip=0.3)
    second = gym.make(ENV_ID, scenario=SCENARIO, slip=0.3)
    assert rollout(first, actions, seed=11) == rollout(second, actions, seed=11)
    assert rollout(first, actions, seed=11) != rollout(first, actions, seed=12)


def test_observations_are_the_task_states_of_the_true_pose(env):
    observation, info = env.reset(seed=0)
    task = env.unwrapped.task
    for action in np.random.default_rng(1).integers(4, size=60).tolist():
        assert observation.dtype == np.float32 and observation in env.observation_space
        assert observation.tolist() == list(np.float32(task.state_of(*info['pose'])))
        observation, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break


def walk_to_the_wall(environment, action=LEFT):
    """Reset, then move until the next move would hit a wall; returns the steps taken."""
    environment.reset(seed=0)
    model = environment.unwrapped.model
    node, steps = model.start, 0
    while model.successors[node, action] != node:
        node = model.successors[node, action]
        assert environment.step(action)[2:4] == (False, False)
        steps += 1
    return steps


def test_a_move_into_a_wall_stays_put_and_costs_a_step(env):
    steps = walk_to_the_wall(env)
    _, _, _, _, before = env.step(LEFT)
    _, reward, terminated, truncated, info = env.step(LEFT)
    assert info['pose'] == before['pose'] and info['steps'] == steps + 2
    rewards = env.unwrapped.scenario.rewards
    expected = step_reward(info['visibility'], info['distance_to_goal'], rewards)
    assert reward == pytest.approx(expected) and info['visibility'] == before['visibility']
    assert not (terminated or truncated)


def test_the_step_limit_truncates(env):
    steps = walk_to_the_wall(env)
    limit = env.unwrapped.task.step_limit
    for _ in range(limit - steps - 1):
        assert env.step(LEFT)[2:4] == (False, False)
    _, _, terminated, truncated, info = env.step(LEFT)
    assert (terminated, truncated, info['outcome'], info['steps']) == (
        False,
        True,
        'TIMEOUT',
        limit,
    )


def test_the_optimal_policy_earns_the_optimal_return(env):
    model = env.unwrapped.model
    optimum = value_iteration(model)
    path = follow(model, lambda i: int(optimum.policy[i]))
    trace = rollout(env, actions_of(model, path), seed=0)
    assert trace[-1][2:] == (True, False, 'SUCCESS')
    assert sum(step[1] for step in trace[1:]) == pytest.approx(optimum.optimal_return)


def test_the_shortest_path_is_seen(env):
    model = env.unwrapped.model
    trace = rollout(env, actions_of(model, astar(model)), seed=0)
    assert trace[-1][2:] == (True, False, 'DETECTED')
    assert trace[-1][1] < -model.task.scenario.rewards.detection_penalty + 1e-9


def test_slip_moves_sideways():
    environment = gym.make(ENV_ID, scenario=SCENARIO, slip=1.0)
    environment.reset(seed=3)
    start = np.array(environment.unwrapped.model.points[environment.unwrapped.model.start])
    moved = set()
    for _ in range(40):
        environment.reset()
        _, _, _, _, info = environment.step(UP)  # slips left or right, never up
        moved.add(tuple(np.sign(np.array(info['pose']) - start)))
    assert moved <= {(-1.0, 0.0), (1.0, 0.0), (0.0, 0.0)} and (0.0, 1.0) not in moved


def test_render_modes():
    text_env = gym.make(ENV_ID, scenario=SCENARIO, render_mode='ansi')
    text_env.reset(seed=0)
    text = text_env.render()
    assert 'R' in text and 'G' in text and '!' in text and text.startswith('stealth-nav: map1')
    picture_env = gym.make(ENV_ID, scenario=SCENARIO, render_mode='rgb_array')
    picture_env.reset(seed=0)
    before = picture_env.render()
    picture_env.step(0)
    after = picture_env.render()
    height, width = picture_env.unwrapped.scenario.map.blocked.shape
    assert before.shape == (height, width, 3) and before.dtype == np.uint8
    assert not np.array_equal(before, after)  # the robot moved
    silent = gym.make(ENV_ID, scenario=SCENARIO)
    silent.reset(seed=0)
    assert silent.render() is None


def test_a_probabilistic_scenario_draws_from_the_env_seed():
    scenario = dataclasses.replace(load_scenario(SCENARIO), detection_mode='probabilistic')
    actions = np.random.default_rng(2).integers(4, size=300).tolist()
    runs = [rollout(StealthNavEnv(scenario), actions, seed=7) for _ in range(2)]
    assert runs[0] == runs[1]
