"""The generalist as an agent of the Gym env: on the full track its grid is the JAX env's
observation (the lights as they stand now, moving ones too) with one value map per light layer,
or the most light over the cycle with one map per episode; on the sensed track the belief,
unknown dark, with a value map per sensed field."""

import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv
from stealth_learn.generalist_agent import GeneralistAgent, load_policy
from stealth_learn.jax_deps import jax
from stealth_learn.jax_env import build
from stealth_learn.obs_layout import CHANNELS
from stealth_learn.policy_file import MAX_ITERATIONS

LIGHT, MOVE_UP, MOVE_RIGHT = (CHANNELS.index(c) for c in ('light', 'move_up', 'move_right'))
LIGHT_CHANNELS = slice(LIGHT, MOVE_RIGHT + 1)  # what the value map depends on


@pytest.fixture(scope='module')
def policy():
    return load_policy(iterations=120)


def test_full_track_grid_is_the_jax_envs_with_a_value_map_per_layer(generated, policy):
    scenario = generated['moving']
    gym = StealthNavEnv(scenario)
    agent = GeneralistAgent(policy, gym, lights='now')
    env, params = build([scenario], track='full')
    one = env.scenario(params, 0)
    observation, _ = gym.reset(seed=0)
    ours, state = env.reset(jax.random.key(0), one)
    step = jax.jit(env.step)
    rows, cols = agent.tables.free.shape
    layers = set()
    for t in range(60):
        grid = np.asarray(ours.grid)[:rows, :cols, LIGHT_CHANNELS]
        np.testing.assert_array_equal(agent.grid(observation)[..., LIGHT_CHANNELS], grid)
        layers.add(gym.node // agent.nodes)
        action = agent.act(observation)
        assert 0 <= action < 4
        observation, _, terminated, truncated, _ = gym.step(action)
        ours, state, _, done, _ = step(jax.random.key(t), state, action, one)
        if terminated or truncated:
            break
    assert len(layers) > 1  # the lights moved under it
    assert agent.value_maps == len(layers)


def test_full_track_cycle_is_the_most_light_over_the_bins_one_map_an_episode(generated, policy):
    gym = StealthNavEnv(generated['moving'])
    agent = GeneralistAgent(policy, gym)
    assert agent.lights == 'cycle' and agent.bins > 1
    observation, _ = gym.reset(seed=0)
    grid = agent.grid(observation)
    tables = agent.tables
    np.testing.assert_array_equal(grid[..., LIGHT], tables.node_light[: agent.bins].max(axis=0))
    assert (grid[..., LIGHT] >= tables.node_light[: agent.bins]).all()
    for _ in range(40):
        observation, _, terminated, truncated, _ = gym.step(agent.act(observation))
        np.testing.assert_array_equal(agent.grid(observation), grid)
        if terminated or truncated:
            break
    assert agent.value_maps == 1


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
    with pytest.raises(ValueError, match="lights: expected one of cycle, now, got 'then'"):
        GeneralistAgent(policy, gym, lights='then')
    for iterations in (0, MAX_ITERATIONS + 1):
        with pytest.raises(
            ValueError, match=f'iterations: expected 1..10000 .*, got {iterations}'
        ):
            load_policy(iterations=iterations)
