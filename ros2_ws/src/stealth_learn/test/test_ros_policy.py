"""The generalist through ROS: the grid stealth_learn trains on is the one the environment node
sends (stealth_core.grid_observation), the agent's policy plugin is registered and found, and
its cached plan gives GeneralistPolicy.act's move at every cell."""

from importlib import metadata

import numpy as np
import pytest
from stealth_core.grid_observation import ROBOT, FullTrackGrid
from stealth_learn import generalist_data as data
from stealth_learn import ros_policy
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import DEFAULT_POLICY
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
