"""The generalist as an agent of the Gym env: on the full track its grid is the JAX env's
observation, one value map an episode; on the sensed track the belief, unknown dark, with a
value map per sensed field; moving lights refused, naming the weights and the scenario."""

import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv
from stealth_learn.generalist import DEFAULT_POLICY
from stealth_learn.generalist_agent import GeneralistAgent, load_policy
from stealth_learn.jax_deps import jax
from stealth_learn.jax_env import build
from stealth_learn.obs_layout import CHANNELS, LayoutError
from stealth_learn.policy_file import MAX_ITERATIONS

LIGHT, MOVE_UP, MOVE_RIGHT = (CHANNELS.index(c) for c in ('light', 'move_up', 'move_right'))
LIGHT_CHANNELS = slice(LIGHT, MOVE_RIGHT + 1)  # what the value map depends on


@pytest.fixture(scope='module')
def policy():
    return load_policy(iterations=120)


def test_full_track_grid_is_the_jax_envs_with_one_value_map_an_episode(generated, policy):
    scenario = generated['still']
    gym = StealthNavEnv(scenario)
    agent = GeneralistAgent(policy, gym)
    env, params = build([scenario], track='full')
    one = env.scenario(params, 0)
    observation, _ = gym.reset(seed=0)
    ours, state = env.reset(jax.random.key(0), one)
    step = jax.jit(env.step)
    rows, cols = agent.tables.free.shape
    for t in range(60):
        grid = np.asarray(ours.grid)[:rows, :cols, LIGHT_CHANNELS]
        np.testing.assert_array_equal(agent.grid(observation)[..., LIGHT_CHANNELS], grid)
        action = agent.act(observation)
        assert 0 <= action < 4
        observation, _, terminated, truncated, _ = gym.step(action)
        ours, state, _, done, _ = step(jax.random.key(t), state, action, one)
        if terminated or truncated:
            break
    assert t > 10 and agent.value_maps == 1


def test_moving_lights_are_refused_naming_the_weights_and_the_scenario(generated, policy):
    """The network reads no phase and cannot wait (issue 42's bad input): not played on a
    stand-in for time, refused in one line."""
    scenario = generated['moving']
    with pytest.raises(LayoutError) as error:
        GeneralistAgent(policy, StealthNavEnv(scenario))
    message = str(error.value)
    assert message.startswith(f'{policy.source}: the policy was trained for static lights')
    assert f'scenario {scenario.name!r} ({scenario.path}) has moving lights' in message
    assert '\n' not in message
    assert str(DEFAULT_POLICY) == policy.source


def test_sensed_track_belief_is_the_observation_with_unknown_dark(generated, policy):
    gym = StealthNavEnv(generated['still'], track='sensed')
    agent = GeneralistAgent(policy, gym)
    observation, _ = gym.reset(seed=0)
    fields = set()
    for _ in range(30):
        grid, light, moves = agent.grid(observation), observation['light'], observation['moves']
        known = light != -1
        np.testing.assert_array_equal(grid[..., LIGHT][known], light[known])
        assert (grid[..., LIGHT][~known] == 0).all() and (~known).any()
        up = moves[0]
        sensed = up != -1
        np.testing.assert_array_equal(grid[..., MOVE_UP][sensed], up[sensed])
        row, col = np.argwhere(~sensed)[0]  # a move never sensed: its ends' larger estimate
        ends = grid[row, col, LIGHT], grid[row + 1, col, LIGHT]
        assert grid[row, col, MOVE_UP] == max(ends)
        fields.add(grid[..., LIGHT_CHANNELS].tobytes())
        observation, _, terminated, truncated, _ = gym.step(agent.act(observation))
        if terminated or truncated:
            break
    assert agent.value_maps == len(fields) > 1  # recomputed when, and only when, it changed


def test_an_unknown_rule_that_does_not_exist_is_refused(generated, policy):
    gym = StealthNavEnv(generated['still'], track='sensed')
    with pytest.raises(ValueError, match="unknown: expected one of dark, lit, got 'grey'"):
        GeneralistAgent(policy, gym, unknown='grey')
    for iterations in (0, MAX_ITERATIONS + 1):
        with pytest.raises(
            ValueError, match=f'iterations: expected 1..10000 .*, got {iterations}'
        ):
            load_policy(iterations=iterations)
