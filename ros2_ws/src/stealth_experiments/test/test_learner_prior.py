"""The learners' prior in the harness: what a run starts its table from, and its one setting
(the prior itself: stealth_core/test/test_floor_plan_prior.py)."""

import pytest
from stealth_experiments.harness import RunSpec, configured, prior_of, run


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
