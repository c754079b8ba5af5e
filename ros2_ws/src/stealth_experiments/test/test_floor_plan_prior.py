"""The floor plan's prior: an upper bound on every true action value (admissible optimism),
what a harness run starts its table from, and its one setting."""

import numpy as np
import pytest
from stealth_env.gym_env import lattice_model
from stealth_env.planners import value_iteration
from stealth_experiments.floor_plan_prior import floor_plan_prior, floor_plan_values
from stealth_experiments.harness import RunSpec, configured, prior_of, run


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


def test_prioritized_sweeping_starts_from_the_floor_plan_unless_told_otherwise():
    assert prior_of('prioritized') == 'floor_plan' and prior_of('psweep') == 'floor_plan'
    assert {prior_of(name) for name in ('qlearning', 'sarsa', 'dyna')} == {'none'}
    assert prior_of('dyna', [('prior', 'floor_plan')]) == 'floor_plan'
    assert prior_of('prioritized', [('prior', 'none')]) == 'none'
    with pytest.raises(ValueError, match="prior: expected one of floor_plan, none, got 'dark'"):
        prior_of('prioritized', [('prior', 'dark')])
    # Not a learner setting: the learner's configuration is the same with it.
    assert configured('dyna', params=[('prior', 'floor_plan')]) == configured('dyna')


def test_the_floor_plan_spares_the_moves_that_lead_away_from_the_goal():
    """map1, seed 0: from the floor plan prioritized sweeping meets the criterion sooner than
    from the goal reward everywhere (bench_learners: 40 against 70 episodes), and on the
    same route."""
    informed = run(RunSpec('map1', 'prioritized', 0, episodes=120))
    constant = run(RunSpec('map1', 'prioritized', 0, episodes=120, params=(('prior', 'none'),)))
    assert informed.episodes_to_criterion is not None and constant.episodes_to_criterion
    assert informed.episodes_to_criterion < constant.episodes_to_criterion
    assert informed.final['steps'] == constant.final['steps']
