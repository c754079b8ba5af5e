"""The lights-known grid observation (grid_observation): its channels against the lattice model
and the sensing geometry it is laid on, the cell of a node's point, the phased grid of moving
lights, and the scenarios it is refused for (one line each). stealth_learn's equality with it:
stealth_learn/test."""

import numpy as np
import pytest
from stealth_core.grid_observation import (
    CHANNELS,
    PHASED_CHANNELS,
    FullTrackGrid,
    cell_of,
    layout_id,
    observed_grid,
)
from stealth_core.lattice_model import LatticeModel
from stealth_core.scenario import load_scenario
from stealth_core.sensing import NO_PLACE, UNKNOWN, PhasedMemory
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
    phased = observed_grid(moving, 'full', 'grid')
    assert phased.layout().startswith('stealth-phased-v1/full/8phases-1perstep/')
    assert phased.channels == PHASED_CHANNELS
    sensed = observed_grid(moving, 'sensed', 'grid')  # what was sensed at each layer
    assert sensed.layout().startswith('stealth-phased-v1/sensed/8phases-1perstep/')
    assert sensed.channels == PHASED_CHANNELS
    exposure = StealthTask(load_scenario('simple-maze-exposure'))
    for track in ('full', 'sensed'):  # no grid carries the heading
        with pytest.raises(ValueError, match=r"'simple-maze-exposure' weighs exposure"):
            observed_grid(exposure, track, 'grid')


def test_the_phased_grid_is_every_bins_grid_and_each_steps_light():
    """With moving lights the full track's grid is phased: layer k is the static grid of bin k,
    then the light the lattice model judges each step from there on (-2 where the step does not
    exist: a move the map blocks only waits); the message carries every layer."""
    task = StealthTask(load_scenario('simple-maze-moving'))
    model = LatticeModel.build(task)
    grid = observed_grid(task, 'full', 'grid', model)
    phased = grid.full()
    sensing, n = grid.sensing, grid.sensing.n
    rows, cols = sensing.grid_row, sensing.grid_col
    assert phased.shape == (8, *sensing.shape, 12) and phased.dtype == np.float32
    for layer in range(8):
        np.testing.assert_array_equal(phased[layer, ..., :7], grid.static(layer))
        places = slice(layer * n, (layer + 1) * n)
        steps = phased[layer, rows, cols, 7:]
        moved = model.successors[places, :4] % n != np.arange(n)[:, None]
        exists = np.concatenate([moved, np.ones((n, 1), bool)], 1)
        truth = model.step_visibility[places].astype(np.float32)
        np.testing.assert_array_equal(steps[exists], truth[exists])
        assert (steps[~exists] == NO_PLACE).all() and (~exists).any()
    assert (phased[:, ~grid.free, 7:] == NO_PLACE).all()
    message = grid_observation_msg(phased, grid.layout(), grid.geometry, 1.0, 0, 0, grid.channels)
    assert (message.layers, message.rows, message.cols, message.channels) == phased.shape
    assert list(message.channel_names) == list(PHASED_CHANNELS)
    back = np.frombuffer(message.data, dtype=np.float32).reshape(phased.shape)
    np.testing.assert_array_equal(back, phased)


def test_the_phased_sensed_grid_is_what_was_sensed_at_each_layer():
    """Sensed everywhere at every layer, the phased sensed grid is the phased grid but for the
    moves' steps: a move's step is the segment's light either way (at least the step's own
    light, the most of both directions exactly); the wait is the lattice's; never sensed, -1."""
    task = StealthTask(load_scenario('simple-maze-moving'))
    model = LatticeModel.build(task)
    grid = FullTrackGrid(model)
    sensing, n = grid.sensing, grid.sensing.n
    rows, cols = sensing.grid_row, sensing.grid_col
    memory = PhasedMemory.empty(sensing)
    empty = grid.phased_sensed(memory)
    assert (empty[:, rows, cols][..., [3, 4, 5, 7, 8, 9, 10, 11]] <= UNKNOWN).all()
    for layer in range(model.layers):
        everything = np.arange(n), np.arange(sensing.moves)
        node_values, move_values = sensing.truth(layer * n)
        waits = sensing.wait_truth(layer * n)
        memory.update(layer, everything[0], node_values, everything[1], move_values, waits)
    sensed, truth = grid.phased_sensed(memory), grid.phased()
    assert sensed.shape == truth.shape and sensed.dtype == np.float32
    np.testing.assert_array_equal(sensed[..., :7], truth[..., :7])
    steps, true_steps = sensed[..., 7:11], truth[..., 7:11]
    np.testing.assert_array_equal(steps == NO_PLACE, true_steps == NO_PLACE)
    exists = true_steps != NO_PLACE
    assert (steps[exists] >= true_steps[exists]).all()
    opposite = {0: 1, 1: 0, 2: 3, 3: 2}
    shift = {0: (1, 0), 1: (-1, 0), 2: (0, -1), 3: (0, 1)}
    for layer in range(0, model.layers, 3):
        for k in range(0, n, 5):
            r, c = rows[k], cols[k]
            for action in range(4):
                if true_steps[layer, r, c, action] == NO_PLACE:
                    continue
                dr, dc = shift[action]
                back = true_steps[layer, r + dr, c + dc, opposite[action]]
                expected = max(true_steps[layer, r, c, action], back)
                assert steps[layer, r, c, action] == expected
    np.testing.assert_array_equal(sensed[..., 11], truth[..., 11])  # the wait, as judged
    assert (sensed[:, ~grid.free, 7:] == NO_PLACE).all()


def test_the_message_carries_the_grid_row_major(maze):
    _, _, grid = maze
    static = grid.static()
    message = grid_observation_msg(static, grid.layout(), grid.geometry, 12.5)
    assert message.header.frame_id == 'map' and message.header.stamp.sec == 12
    assert (message.rows, message.cols, message.channels) == static.shape
    assert message.layers == 1
    assert list(message.channel_names) == list(CHANNELS)
    assert message.layout == grid.layout()
    assert (message.resolution, message.origin.x, message.origin.y) == pytest.approx(grid.geometry)
    back = np.frombuffer(message.data, dtype=np.float32).reshape(static.shape)
    np.testing.assert_array_equal(back, static)


def test_the_phased_sensed_grid_sent_marks_its_states_layer_and_cell():
    """Sent before each state, the phased sensed grid marks the robot at the state's (phase,
    cell) only, as the agent reads the state; a state off the grid or without a phase the grid
    has marks nothing (the agent then says what is wrong with the state)."""
    task = StealthTask(load_scenario('simple-maze-moving'))
    model = LatticeModel.build(task)
    grid = observed_grid(task, 'sensed', 'grid', model)
    sensing = grid.sensing
    memory = PhasedMemory.empty(sensing)
    node = sensing.n // 2
    x, y = sensing.points[node]
    marked = grid.with_robot(grid.phased_sensed(memory), [x, y, 3.0])
    assert marked[..., 1].sum() == 1.0
    assert marked[3, sensing.grid_row[node], sensing.grid_col[node], 1] == 1.0
    np.testing.assert_array_equal(marked[..., [0, *range(2, 12)]],
                                  grid.phased_sensed(memory)[..., [0, *range(2, 12)]])  # fmt: skip
    for state in ([x, y, 8.0], [x, y, 1.5], [x, y], [x - 1e3, y, 0.0]):
        assert not grid.with_robot(marked, state)[..., 1].any()
