"""The generalist's belief on the lights-sensed track, one function for the benchmark's agent
(GeneralistAgent, from the Gym env's observation) and the agent node's plugin (ros_policy, from
the environment node's sensed GridObservation): unknown nodes dark, an unknown move its ends'
larger light, and both give the same grid and the same move along an episode."""

import numpy as np
import pytest
from stealth_core.grid_observation import (
    AGE,
    LIGHT,
    MOVE_RIGHT,
    MOVE_UP,
    ROBOT,
    FullTrackGrid,
    step_grids,
)
from stealth_core.gym_env import StealthNavEnv
from stealth_learn import policy_file, ros_policy
from stealth_learn.belief import believed, believed_grid, believed_phased
from stealth_learn.generalist import robot_cell
from stealth_learn.generalist_agent import GeneralistAgent
from stealth_learn.policy_file import SHIPPED

LIGHTS = slice(LIGHT, MOVE_RIGHT + 1)


def test_unknown_nodes_enter_dark_and_unknown_moves_as_their_larger_end():
    light = np.array([[0.1, -1.0], [-1.0, -2.0]], np.float32)  # row 0 the southernmost
    up = np.array([[-1.0, 0.7], [-2.0, -2.0]], np.float32)
    right = np.array([[-1.0, -2.0], [-2.0, -2.0]], np.float32)
    node, moves = believed(light, np.stack([up, right]))
    np.testing.assert_array_equal(node, np.array([[0.1, 0.0], [0.0, -2.0]], np.float32))
    assert moves[0, 0, 0] == np.float32(0.1)  # up from (0, 0) to (1, 0), never sensed
    assert moves[1, 0, 0] == np.float32(0.1)  # right from (0, 0) to (0, 1), never sensed
    assert moves[0, 0, 1] == np.float32(0.7)  # sensed: as sensed
    assert (moves[:, 1] == -2).all()  # no move: as it was
    lit, _ = believed(light, np.stack([up, right]), assumed=np.full((2, 2), 0.3, np.float32))
    np.testing.assert_array_equal(lit, np.array([[0.1, 0.3], [0.3, -2.0]], np.float32))
    grid = np.zeros((2, 2, 7), np.float32)
    grid[..., LIGHT], grid[..., MOVE_UP], grid[..., MOVE_RIGHT] = light, up, right
    read = believed_grid(grid)
    np.testing.assert_array_equal(read[..., LIGHT], node)
    np.testing.assert_array_equal(np.moveaxis(read[..., MOVE_UP : MOVE_RIGHT + 1], -1, 0), moves)
    assert (grid[..., LIGHT] == light).all()  # a new array: the one sent stays as it was


def test_a_layer_never_sensed_reads_the_brightest_known_else_dark():
    """Phased: a node (move, wait) unknown at a layer but sensed at others reads the most light
    sensed there (a beam seen once may be back), unknown everywhere reads dark; steps are the
    believed moves, a wait never sensed the more light of this layer's node and the next's."""
    free = np.ones((2, 2), bool)
    grid = np.zeros((3, 2, 2, 12), np.float32)
    grid[..., 0] = 1.0
    grid[..., LIGHT] = -1.0
    grid[..., MOVE_UP] = [[-1.0, -1.0], [-2.0, -2.0]]
    grid[..., MOVE_RIGHT] = [[-1.0, -2.0], [-1.0, -2.0]]
    grid[0, 0, 0, LIGHT] = 0.5  # node (0, 0) lit at layer 0
    grid[1, 0, 0, LIGHT] = 0.1  # and dim at layer 1
    grid[2, 0, 1, LIGHT] = 0.2  # node (0, 1) known at layer 2 only
    grid[1, 0, 0, MOVE_RIGHT] = 0.05  # the move right from (0, 0), sensed at layer 1
    moves = np.stack([grid[0, ..., MOVE_UP], grid[0, ..., MOVE_RIGHT]])
    grid[..., 7:] = step_grids(moves, free, np.full((2, 2), -1.0, np.float32))
    grid[2, 1, 1, 11] = 0.4  # a wait from (1, 1) sensed at layer 2 only
    read = believed_phased(grid, advance=1)
    np.testing.assert_array_equal(read[:, 0, 0, LIGHT], np.float32([0.5, 0.1, 0.5]))
    np.testing.assert_array_equal(read[:, 0, 1, LIGHT], np.float32([0.2, 0.2, 0.2]))
    assert (read[:, 1, :, LIGHT] == 0.0).all()  # never sensed anywhere: dark
    np.testing.assert_array_equal(read[:, 0, 0, MOVE_RIGHT], np.float32([0.05, 0.05, 0.05]))
    np.testing.assert_array_equal(read[:, 0, 0, 7 + 3], read[:, 0, 0, MOVE_RIGHT])  # step right
    np.testing.assert_array_equal(read[:, 0, 1, 7 + 2], read[:, 0, 0, MOVE_RIGHT])  # step left
    np.testing.assert_array_equal(read[:, 0, 0, 7], np.float32([0.5, 0.1, 0.5]))  # up: ends
    assert (read[:, 1, :, 7] == -2).all() and (read[:, 0, :, 8] == -2).all()  # off the grid
    np.testing.assert_array_equal(read[:, 0, 0, 11], np.float32([0.5, 0.5, 0.5]))  # wait: ends
    np.testing.assert_array_equal(read[:, 1, 1, 11], np.float32([0.4, 0.4, 0.4]))  # as sensed
    np.testing.assert_array_equal(read[:, 0, 0, AGE], np.float32([0, 0, 1]))  # never sensed
    np.testing.assert_array_equal(read[:, 0, 1, AGE], np.float32([1, 1, 0]))
    assert (grid[1, 0, 1, LIGHT] == -1).all()  # a new array


def test_the_plugin_on_the_sent_belief_is_the_benchmarks_agent(generated):
    gym = StealthNavEnv(generated['still'], track='sensed')
    plugin = ros_policy.load('')
    agent = GeneralistAgent(plugin.policy, gym)
    sent = FullTrackGrid(gym.model, track='sensed')
    plugin.check(sent.layout())
    assert sent.layout().startswith('stealth-grid-v1/sensed/')
    observation, _ = gym.reset(seed=0)
    sent_beliefs, beliefs = set(), set()
    for _ in range(40):
        grid = sent.belief(observation['light'], observation['moves'])
        assert (grid[..., LIGHT] == -1).any()  # what it never sensed goes out as such
        ours = agent.grid(observation)
        np.testing.assert_array_equal(believed_grid(grid)[..., LIGHTS], ours[..., LIGHTS])
        node = int(gym.node) % agent.nodes
        grid[agent.row[node], agent.col[node], ROBOT] = 1.0
        action = agent.act(observation)
        assert plugin(grid) == action
        sent_beliefs.add(grid[..., LIGHTS].tobytes())
        beliefs.add(ours[..., LIGHTS].tobytes())
        observation, _, terminated, truncated, _ = gym.step(action)
        if terminated or truncated:
            break
    # One plan per belief read, fewer than the grids sent (a dark node sensed reads as before).
    assert plugin.plans.computed == agent.value_maps == len(beliefs) > 1
    assert len(beliefs) < len(sent_beliefs)


def test_the_plugin_on_the_sent_phased_sensed_grid_is_the_benchmarks_agent(generated):
    """Moving lights, sensed: the shipped time-aware weights read the phased grid of what was
    sensed, as the environment sends it before each state (robot marked at the state's layer and
    cell), and decide as GeneralistAgent does on the sensed Gym env at every step of an
    episode, waits included; a plan per distinct belief, not per grid sent."""
    gym = StealthNavEnv(generated['moving'], track='sensed')
    plugin = ros_policy.load(str(SHIPPED.with_name('generalist-moving.npz')))
    agent = GeneralistAgent(plugin.policy, gym)
    sent = FullTrackGrid(gym.model, track='sensed')
    layout = sent.layout()
    assert layout.startswith('stealth-phased-v1/sensed/8phases-1perstep/')
    plugin.check(layout)
    observation, _ = gym.reset(seed=0)
    actions, beliefs, sent_grids = [], set(), 0
    while True:
        grid = sent.with_robot(sent.phased_sensed(gym.sensor.phased), observation['state'])
        sent_grids += 1
        assert (grid[..., LIGHT] == -1).any()  # what it never sensed goes out as such
        layer, node = divmod(int(gym.node), agent.nodes)
        assert robot_cell(grid) == (layer, agent.row[node], agent.col[node])
        ours = agent.grid(observation)
        read = believed_phased(grid, 1)
        read[..., ROBOT] = 0.0
        np.testing.assert_array_equal(read, ours)
        actions.append(agent.act(observation))
        assert plugin(grid) == actions[-1]
        beliefs.add(ours.tobytes())
        observation, _, terminated, truncated, _ = gym.step(actions[-1])
        if terminated or truncated:
            break
    assert len(actions) > 10 and 4 in actions  # a whole episode, the wait among its actions
    assert plugin.plans.computed == len(beliefs) <= sent_grids  # one plan per belief


def test_weights_and_a_sensed_grid_of_the_other_kind_are_refused_naming_both():
    """Static weights given the phased sensed grid, time-aware weights given the static sensed
    belief: refused, one line naming both layouts."""
    static = ros_policy.load('')
    timed = ros_policy.load(str(SHIPPED.with_name('generalist-moving.npz')))
    static.check('stealth-grid-v1/sensed/30x30')
    timed.check('stealth-phased-v1/sensed/8phases-1perstep/30x30')
    for plugin, layout in (
        (static, 'stealth-phased-v1/sensed/8phases-1perstep/30x30'),
        (timed, 'stealth-grid-v1/sensed/30x30'),
        (timed, 'stealth-phased-v1/sensed/4phases-1perstep/30x30'),
    ):
        with pytest.raises(ValueError) as refused:
            plugin.check(layout)
        message = str(refused.value)
        assert repr(plugin.layout) in message and '\n' not in message
        assert repr(policy_file.without_size(layout)) in message
