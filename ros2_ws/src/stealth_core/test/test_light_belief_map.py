"""The light model's belief as map-aligned grids (light_belief_map; no ROS)."""

import math

import numpy as np
import pytest
from stealth_core.light_belief_map import (
    BeliefArrayError,
    BeliefMapper,
    belief_rows,
    cell_factor,
)
from stealth_core.light_world import LightWorld
from stealth_core.scenario import load_scenario
from stealth_core.visibility import visibility_field


@pytest.fixture(scope='module')
def scenario():
    return load_scenario('simple-maze')


@pytest.fixture(scope='module')
def mapper(scenario):
    return BeliefMapper(LightWorld(scenario, 'easy'))


def test_the_grid_lies_on_the_map(scenario, mapper):
    grid = mapper.grid(belief_rows(scenario.lights), [1.0])
    occupancy = scenario.map
    assert mapper.factor == cell_factor(occupancy.resolution, scenario.step_distance) == 5
    assert grid.resolution == pytest.approx(0.25)
    assert grid.origin == tuple(occupancy.origin)
    assert (grid.height, grid.width) == (occupancy.height // 5, occupancy.width // 5)
    walls = occupancy.blocked.reshape(grid.height, 5, grid.width, 5).any(axis=(1, 3))
    assert np.array_equal(grid.likely == -1, walls)
    assert np.array_equal(grid.uncertain == -1, walls)


def test_the_likely_field_of_the_true_lights_is_the_true_field(scenario, mapper):
    """A belief sure of the scenario's own lights shows the environment's light, scaled so the
    detection threshold is 100, at each cell's centre."""
    grid = mapper.grid(belief_rows(scenario.lights), [1.0])
    occupancy = scenario.map
    truth, _ = visibility_field(occupancy.blocked, occupancy.resolution, occupancy.origin,
                                scenario.lights)  # fmt: skip
    centres = truth[2::5, 2::5][: grid.height, : grid.width]  # the map cell at each centre
    free = grid.likely >= 0
    threshold = scenario.detection_threshold
    np.testing.assert_allclose(grid.likely_field[free], centres[free], rtol=1e-9, atol=1e-12)
    expected = np.where(centres >= threshold, 100, np.floor(100 * centres / threshold))
    assert np.array_equal(grid.likely[free], expected[free].astype(np.int8))
    assert np.count_nonzero(grid.likely == 100) > 50  # the two wide lights are there
    assert np.all(grid.uncertain[free] == 0)  # one hypothesis: nothing in doubt


def test_the_uncertain_places_are_where_the_weight_splits(scenario, mapper):
    shortcut = [light for light in scenario.lights if light.name == 'shortcut']
    lights = belief_rows(shortcut, 1)  # particle 0 has no light at all
    even = mapper.grid(lights, [0.5, 0.5])
    lit = even.lit_probability == 0.5
    assert np.count_nonzero(lit) > 20
    assert np.all(even.uncertain[lit] == 100) and np.all(
        even.uncertain[~lit & (even.uncertain >= 0)] == 0
    )
    lopsided = mapper.grid(lights, [0.9, 0.1])
    assert np.all(lopsided.uncertain[lit] == 20)
    assert np.all(lopsided.likely[lit] < 100)  # the heavier particle is dark there
    assert np.all(mapper.grid(lights, [0.1, 0.9]).likely[lit] == 100)


@pytest.mark.parametrize(
    'lights, weights, part',
    [
        (np.zeros((2, 6)), [1.0], '(lights, 7)'),
        (np.zeros((1, 7)), [], 'one per particle'),
        (np.array([[3, 1, 1, 0, 1, 0.1, 5]]), [0.5, 0.5], 'particle'),
        (np.array([[0, math.nan, 1, 0, 1, 0.1, 5]]), [1.0], 'finite'),
        (np.zeros((1, 7)), [-1.0, 2.0], '>= 0'),
    ],
)
def test_arrays_that_are_no_belief_are_one_line(mapper, lights, weights, part):
    with pytest.raises(BeliefArrayError) as error:
        mapper.grid(lights, weights)
    assert part in str(error.value) and '\n' not in str(error.value)
