"""The lights-known grid observation (grid_observation): its channels against the lattice model
and the sensing geometry it is laid on, the cell of a node's point, and the scenarios it is
refused for (one line each). stealth_learn's equality with it: stealth_learn/test."""

import numpy as np
import pytest
from stealth_core.grid_observation import (
    CHANNELS,
    FullTrackGrid,
    cell_of,
    layout_id,
    observed_grid,
)
from stealth_core.lattice_model import LatticeModel
from stealth_core.scenario import load_scenario
from stealth_core.sensing import NO_PLACE
from stealth_core.task import StealthTask
from stealth_env.env_messages import grid_observation_msg
from stealth_env.sensed_track import SensedTrack


@pytest.fixture(scope='module')
def maze():
    task = StealthTask(load_scenario('simple-maze'), 'easy')
    model = LatticeModel.build(task)
    return task, model, FullTrackGrid(model)


def test_channels_are_the_lattice_models(maze):
    task, model, grid = maze
    static = grid.static()
    sensing = grid.sensing
    rows, cols, n = sensing.grid_row, sensing.grid_col, sensing.n
    assert static.shape == (*sensing.shape, len(CHANNELS)) and static.dtype == np.float32
    assert static[..., 0].sum() == n and static[rows, cols, 0].all()
    assert not static[..., 1].any() and not static[..., 6].any()  # robot, age
    np.testing.assert_array_equal(static[rows, cols, 2], model.goal[:n])
    np.testing.assert_array_equal(static[rows, cols, 3], model.visibility[:n].astype(np.float32))
    assert (static[..., 3][static[..., 0] == 0] == NO_PLACE).all()
    # A move up from a node is lit as the most of both directions' step visibility.
    for k in range(0, sensing.moves, max(sensing.moves // 40, 1)):
        a, b = sensing.move_from[k], sensing.move_to[k]
        channel = 4 if sensing.move_direction[k] == 0 else 5
        forward = model.step_visibility[a, sensing.move_direction[k]]
        back = model.step_visibility[b, 1 if channel == 4 else 2]
        assert static[rows[a], cols[a], channel] == np.float32(max(forward, back))
    assert grid.layout() == layout_id('full', *sensing.shape)
    assert grid.layout().startswith('stealth-grid-v1/full/')


def test_every_nodes_point_falls_in_its_cell(maze):
    task, model, grid = maze
    sensing = grid.sensing
    for k in range(sensing.n):
        x, y = sensing.points[k]
        assert grid.cell_of(x, y) == (sensing.grid_row[k], sensing.grid_col[k])
    # The sensed track's sensed_light grid lies on the same cells.
    assert SensedTrack(task, model).grid_geometry() == grid.geometry
    resolution, x0, y0 = grid.geometry
    assert cell_of(grid.geometry, x0 - 0.01, y0) == (0, -1)
    assert resolution == task.scenario.step_distance


def test_observed_grid_only_where_one_grid_serves_a_run(maze):
    task, model, _ = maze
    assert observed_grid(task, 'full', 'off') is None
    assert isinstance(observed_grid(task, 'full', 'grid', model), FullTrackGrid)
    assert (
        observed_grid(task, 'sensed', 'grid', model).layout().startswith('stealth-grid-v1/sensed/')
    )
    with pytest.raises(ValueError, match="on track 'full' or 'sensed', not 'seen'"):
        observed_grid(task, 'seen', 'grid', model)
    with pytest.raises(ValueError, match="expected 'off' or 'grid', got 'pixels'"):
        observed_grid(task, 'full', 'pixels', model)
    moving = StealthTask(load_scenario('simple-maze-moving'))
    for track in ('full', 'sensed'):  # static lights only
        with pytest.raises(ValueError, match=r"'simple-maze-moving' has \d+ layers"):
            observed_grid(moving, track, 'grid')


def test_the_message_carries_the_grid_row_major(maze):
    _, _, grid = maze
    static = grid.static()
    message = grid_observation_msg(static, grid.layout(), grid.geometry, 12.5)
    assert message.header.frame_id == 'map' and message.header.stamp.sec == 12
    assert (message.rows, message.cols, message.channels) == static.shape
    assert list(message.channel_names) == list(CHANNELS)
    assert message.layout == grid.layout()
    assert (message.resolution, message.origin.x, message.origin.y) == pytest.approx(grid.geometry)
    back = np.frombuffer(message.data, dtype=np.float32).reshape(static.shape)
    np.testing.assert_array_equal(back, static)
