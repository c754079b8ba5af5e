"""The generalist through ROS: the grid stealth_learn trains on is the one the environment node
sends (stealth_core.grid_observation), the agent's policy plugin is registered and found, and
its cached plan gives GeneralistPolicy.act's move at every cell; with moving lights, the
time-aware weights on the phased grid decide as the benchmark's agent does."""

from importlib import metadata
from pathlib import Path

import numpy as np
import pytest
from stealth_core.grid_observation import ROBOT, FullTrackGrid, observed_grid
from stealth_core.gym_env import StealthNavEnv
from stealth_core.scenario import load_scenario
from stealth_core.task import WAIT
from stealth_learn import generalist_data as data
from stealth_learn import ros_policy
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import DEFAULT_POLICY
from stealth_learn.generalist_agent import GeneralistAgent
from stealth_learn.obs_layout import LayoutError


def _both(scenario, goal=None):
    """(stealth_learn's grid of the scenario, the environment node's)."""
    arrays = TaskArrays(scenario, goal)
    return data.grid_of(arrays.tables()), FullTrackGrid(arrays.model, arrays.sensing)


@pytest.mark.parametrize(('name', 'goal'), [('simple-maze', 'easy'), ('lgfloor', None)])
def test_the_trained_grid_is_the_one_the_environment_sends(name, goal):
    trained, sent = _both(name, goal)
    np.testing.assert_array_equal(trained, sent.static())


def test_the_same_grid_on_a_generated_building(generated):
    trained, sent = _both(generated['still'])
    np.testing.assert_array_equal(trained, sent.static())


def test_the_plugin_is_registered_for_the_agent():
    (entry,) = [e for e in metadata.entry_points(group='stealth_agent.policies')
                if e.name == 'generalist']  # fmt: skip
    assert entry.load() is ros_policy.load
    policy = entry.load()('')
    assert policy.path == DEFAULT_POLICY and policy.layout == 'stealth-grid-v1/full'


def test_the_cached_plan_is_act_at_every_cell(generated):
    policy = ros_policy.load(str(DEFAULT_POLICY))
    _, sent = _both(generated['still'])
    grid = sent.static()
    cells = list(zip(*np.nonzero(grid[..., 0]), strict=True))
    for row, col in cells[:: max(len(cells) // 25, 1)]:
        grid[row, col, ROBOT] = 1.0
        assert policy(grid) == policy.policy.act(grid), (row, col)
        grid[row, col, ROBOT] = 0.0
    assert len(policy.plans) == 1  # one plan for every robot cell of one building
    other = grid.copy()
    other[..., 3] += 0.01
    policy.plan(other)
    assert len(policy.plans) == 2


def test_refusals_name_the_path_or_both_layouts(tmp_path):
    policy = ros_policy.load('')
    policy.check('stealth-grid-v1/full/12x30')
    policy.check('stealth-grid-v1/sensed/40x40')  # the same weights on the belief grid
    with pytest.raises(LayoutError) as refused:
        policy.check('stealth-vector-v1/full')
    assert "'stealth-grid-v1/full'" in str(refused.value)
    assert "'stealth-vector-v1/full'" in str(refused.value)
    missing = tmp_path / 'none.npz'
    with pytest.raises(ValueError, match=f'{missing}: no such policy file'):
        ros_policy.load(str(missing))
    corrupt = tmp_path / 'corrupt.npz'
    corrupt.write_bytes(b'not a zip')
    with pytest.raises(ValueError, match=f'{corrupt}: not an npz archive'):
        ros_policy.load(str(corrupt))
    empty = tmp_path / 'empty.npz'  # issue 40: an EOFError, and through stealth rollout no path
    empty.write_bytes(b'')
    with pytest.raises(ValueError, match=rf'{empty}: empty file \(0 bytes\)'):
        ros_policy.load(str(empty))


MOVING_WEIGHTS = Path(DEFAULT_POLICY).with_name('generalist-moving.npz')


def test_the_time_aware_plugin_decides_as_the_benchmarks_agent():
    """Moving lights: on the phased grid the environment node sends (``observed_grid``: layout
    and data), the plugin's action with the robot at (the state's phase, the cell of its x, y)
    is ``GeneralistAgent``'s at that place (phase and node), waits included, along a greedy
    episode and at every 7th place of every layer; one plan for all."""
    policy = ros_policy.load(str(MOVING_WEIGHTS))
    env = StealthNavEnv(load_scenario('simple-maze-moving'))
    agent = GeneralistAgent(policy.policy, env)
    sent = observed_grid(env.task, 'full', 'grid', env.model)
    policy.check(sent.layout())
    grid = sent.full()

    def plugin_action(state) -> int:
        phase, cell = int(state[2]), sent.cell_of(float(state[0]), float(state[1]))
        grid[(phase, *cell, ROBOT)] = 1.0
        try:
            return policy(grid)
        finally:
            grid[(phase, *cell, ROBOT)] = 0.0

    observation, _ = env.reset(seed=0)
    actions, done = [], False
    while not done:
        action = agent.act(observation)
        assert plugin_action(observation) == action, observation
        actions.append(action)
        observation, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    assert info['outcome'] == 'SUCCESS' and WAIT in actions
    phases = set()
    for place in range(0, env.model.size, 7):
        env._node = place  # the agent reads the robot's place there
        state = env.model.states[place]
        assert plugin_action(state) == agent.act(state), state
        phases.add(int(state[2]))
    assert phases == set(range(8)) and len(policy.plans) == 1


def test_time_aware_and_static_weights_refuse_each_others_grids():
    """The static weights refuse the phased grid, the time-aware ones the static and the
    belief grid and another cycle, each in one line naming both layouts; a phased grid whose
    data has other layers than its layout is refused too."""
    static, timed = ros_policy.load(''), ros_policy.load(str(MOVING_WEIGHTS))
    with pytest.raises(LayoutError) as refused:
        static.check('stealth-phased-v1/full/8phases-1perstep/30x30')
    assert "'stealth-grid-v1/full'" in str(refused.value)
    assert "'stealth-phased-v1/full/8phases-1perstep'" in str(refused.value)
    timed.check('stealth-phased-v1/full/8phases-1perstep/12x30')
    for layout in (
        'stealth-grid-v1/full/30x30',
        'stealth-grid-v1/sensed/30x30',
        'stealth-phased-v1/full/4phases-1perstep/30x30',
    ):
        with pytest.raises(LayoutError) as refused:
            timed.check(layout)
        message = str(refused.value)
        assert "'stealth-phased-v1/full/8phases-1perstep'" in message and '\n' not in message
        assert repr(layout.rsplit('/', 1)[0]) in message and str(MOVING_WEIGHTS) in message
    with pytest.raises(ValueError, match=r'shape \(4, 5, 6, 12\), expected \(8, 5, 6, 12\)'):
        timed.plan(np.zeros((4, 5, 6, 12), np.float32))
