"""The floor plan's prior: an upper bound on every true action value (admissible optimism)."""

import numpy as np
import pytest
from stealth_core.floor_plan_prior import floor_plan_prior, floor_plan_values
from stealth_core.gym_env import lattice_model
from stealth_core.planners import value_iteration


@pytest.mark.parametrize(
    'scenario', ['map1', 'simple-maze-exposure', 'lgfloor-bounce', 'simple-maze-moving']
)
def test_the_dark_floor_plan_is_worth_at_least_the_lit_one_everywhere(scenario):
    model = lattice_model(scenario)
    dark, lit = floor_plan_values(model), value_iteration(model).q
    assert dark.shape == lit.shape
    assert np.all(dark >= lit - 1e-9)
    assert np.any(dark > lit + 1.0)  # the lights cost something somewhere


def test_the_prior_of_a_state_is_its_place_values_and_none_off_the_model():
    model = lattice_model('map1')
    prior, values = floor_plan_prior(model), floor_plan_values(model)
    np.testing.assert_array_equal(prior(model.states[model.start]), values[model.start])
    assert prior(np.full(model.states.shape[1], -99.0, dtype=np.float32)) is None
