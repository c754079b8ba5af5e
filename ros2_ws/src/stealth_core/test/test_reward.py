"""Rewards: hand-computed values, outcomes, and the well-posedness guarantees."""

import dataclasses
import math
from pathlib import Path
import re

import numpy as np
import pytest
from stealth_core.reward import (
    EpisodeOutcome,
    RewardError,
    RewardWeights,
    check_well_posed,
    detection_probability,
    detection_reward,
    is_detected,
    step_outcome,
    step_reward,
    success_reward,
    undetected_visibility_bound,
)

WEIGHTS = RewardWeights(
    goal_reward=100.0,
    goal_distance_weight=20.0,
    detection_penalty=200.0,
    detection_distance_weight=5.0,
    visibility_weight=10.0,
    distance_weight=0.5,
    time_cost=1.0,
)
RULES = {'goal_radius': 0.5, 'detection_threshold': 0.6, 'weights': WEIGHTS}
MSG_DIR = Path(__file__).resolve().parents[2] / 'stealth_interfaces' / 'msg'


def test_outcomes_match_the_message_constants():
    text = (MSG_DIR / 'EpisodeSummary.msg').read_text()
    constants = dict(re.findall(r'^uint8 (\w+)=(\d+)', text, flags=re.MULTILINE))
    assert {name: int(value) for name, value in constants.items()} == {
        outcome.name: outcome.value for outcome in EpisodeOutcome
    }


# --- hand-computed values ---------------------------------------------------------------------


def test_an_ordinary_step_by_hand():
    # -(10*0.3 + 0.5*4 + 1) = -6
    assert step_outcome(0.3, 4.0, **RULES) == (-6.0, False, None)


def test_reaching_the_goal_by_hand():
    assert step_outcome(0.1, 0.2, **RULES) == (100.0 + 20.0 * 0.3, True, EpisodeOutcome.SUCCESS)
    assert step_outcome(0.0, 0.5, **RULES).reward == 100.0  # on the rim
    assert step_outcome(0.0, 0.0, **RULES).reward == 110.0  # on the point


def test_being_detected_by_hand():
    assert step_outcome(0.6, 3.0, **RULES) == (-(200.0 + 5.0 * 3.0), True, EpisodeOutcome.DETECTED)
    assert step_outcome(2.5, 0.0, **RULES).reward == -200.0


def test_detection_wins_over_the_goal_and_the_goal_over_the_time_limit():
    assert step_outcome(0.9, 0.1, **RULES).outcome == EpisodeOutcome.DETECTED
    assert step_outcome(0.1, 0.1, **RULES, timed_out=True).outcome == EpisodeOutcome.SUCCESS
    timeout = step_outcome(0.3, 4.0, **RULES, timed_out=True)
    assert timeout == (-6.0, True, EpisodeOutcome.TIMEOUT)


def test_the_original_formula_paid_for_being_caught_near_the_goal_and_this_one_does_not():
    original = -100 * 0.7 + 50 / 0.5  # detected with v = 0.7 at 0.5 m: +30
    assert original > 0
    assert step_outcome(0.7, 0.5, **{**RULES, 'goal_radius': 0.1}).reward < 0


def test_default_weights():
    weights = RewardWeights()
    assert all(getattr(weights, f.name) >= 0 for f in dataclasses.fields(weights))
    assert weights.time_cost == 0.0  # the optional time cost is off by default


# --- probabilistic detection ------------------------------------------------------------------


def test_detection_probability_by_hand():
    assert detection_probability(0.0, 0.5) == 0.0
    assert detection_probability(0.5, 0.5) == pytest.approx(0.5)
    assert detection_probability(1.0, 0.5) == pytest.approx(0.75)
    values = [detection_probability(v, 0.5) for v in np.linspace(0, 5, 51)]
    assert all(b > a for a, b in zip(values, values[1:], strict=False)) and values[-1] < 1.0


def test_probabilistic_detection_draws_from_the_generator():
    rng = np.random.default_rng(7)
    seen = [is_detected(0.5, 0.5, 'probabilistic', rng) for _ in range(4000)]
    assert np.mean(seen) == pytest.approx(0.5, abs=0.03)
    assert not any(is_detected(0.0, 0.5, 'probabilistic', rng) for _ in range(100))
    first = [is_detected(0.3, 0.5, 'probabilistic', np.random.default_rng(1)) for _ in range(5)]
    again = [is_detected(0.3, 0.5, 'probabilistic', np.random.default_rng(1)) for _ in range(5)]
    assert first == again
    result = step_outcome(
        5.0, 3.0, **RULES, detection_mode='probabilistic', rng=np.random.default_rng(0)
    )
    assert result.outcome == EpisodeOutcome.DETECTED  # p = 1 - 2**(-5/0.6) > 0.99


def test_probabilistic_detection_needs_a_generator_and_modes_are_checked():
    with pytest.raises(RewardError, match='Generator'):
        step_outcome(0.1, 3.0, **RULES, detection_mode='probabilistic')
    with pytest.raises(RewardError, match='detection_mode'):
        step_outcome(0.1, 3.0, **RULES, detection_mode='sometimes')


# --- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ('changes', 'message'),
    [
        ({'visibility': math.nan}, 'visibility'),
        ({'visibility': -0.1}, 'visibility'),
        ({'distance': math.inf}, 'distance'),
        ({'goal_radius': 0.0}, 'goal_radius'),
        ({'detection_threshold': math.nan}, 'detection_threshold'),
    ],
)
def test_bad_step_inputs_are_errors(changes, message):
    arguments = {'visibility': 0.1, 'distance': 2.0, **RULES, **changes}
    visibility, distance = arguments.pop('visibility'), arguments.pop('distance')
    with pytest.raises(RewardError, match=message):
        step_outcome(visibility, distance, **arguments)


@pytest.mark.parametrize(
    ('field', 'value'),
    [
        ('goal_reward', 0.0),
        ('detection_penalty', 0.0),
        ('visibility_weight', -1.0),
        ('distance_weight', math.nan),
        ('time_cost', math.inf),
        ('goal_distance_weight', '1'),
        ('detection_distance_weight', True),
    ],
)
def test_bad_weights_are_refused(field, value):
    with pytest.raises(RewardError, match=field):
        RewardWeights(**{field: value})


# --- well-posedness ---------------------------------------------------------------------------

DISTANCES = np.linspace(0.0, 30.0, 61)


def random_well_posed_weights(rng, max_distance, max_visibility, max_steps=None):
    """Random weights, kept only when check_well_posed accepts them."""
    while True:
        weights = RewardWeights(
            *(float(rng.choice([0.0, 10 ** rng.uniform(-2, 3)])) + 0.001 for _ in range(7))
        )
        try:
            check_well_posed(
                weights,
                max_distance=max_distance,
                max_visibility=max_visibility,
                max_steps=max_steps,
            )
        except RewardError:
            continue
        return weights


@pytest.mark.parametrize('mode', ['threshold', 'probabilistic'])
def test_being_detected_is_always_worse_than_any_step_from_the_same_place(mode):
    rng = np.random.default_rng(11)
    threshold, n_lights = 0.6, 4
    bound = undetected_visibility_bound(mode, threshold, n_lights)
    visibilities = np.linspace(0.0, bound, 25)
    if mode == 'threshold':
        visibilities = visibilities[visibilities < threshold]  # undetected means below it
    for weights in [WEIGHTS] + [
        random_well_posed_weights(rng, DISTANCES[-1], bound) for _ in range(30)
    ]:
        for d in DISTANCES:
            caught = detection_reward(d, weights)
            for v in visibilities:
                assert caught < step_reward(v, d, weights)


def test_reaching_the_goal_is_always_the_best():
    rng = np.random.default_rng(12)
    for weights in [WEIGHTS, RewardWeights()] + [
        random_well_posed_weights(rng, 30.0, 4.0) for _ in range(30)
    ]:
        worst_success = min(success_reward(d, 0.5, weights) for d in np.linspace(0, 0.5, 11))
        best_other = max(
            max(step_reward(v, d, weights), detection_reward(d, weights))
            for d in DISTANCES
            for v in np.linspace(0.0, 4.0, 9)
        )
        assert worst_success > best_other
        assert worst_success >= weights.goal_reward > 0.0


def test_closer_to_the_goal_point_pays_more():
    rewards = [success_reward(d, 0.5, WEIGHTS) for d in np.linspace(0.0, 0.5, 11)]
    assert all(a > b for a, b in zip(rewards, rewards[1:], strict=False))


def test_check_well_posed_refuses_a_cheap_detection():
    cheap = dataclasses.replace(WEIGHTS, detection_penalty=1.0, detection_distance_weight=0.0)
    with pytest.raises(RewardError, match='detected at distance 0'):
        check_well_posed(cheap, max_distance=30.0, max_visibility=0.6)
    # a detection cost that does not grow with distance while the step cost does
    flat = dataclasses.replace(WEIGHTS, detection_distance_weight=0.0, distance_weight=10.0)
    with pytest.raises(RewardError, match='detected at distance 30'):
        check_well_posed(flat, max_distance=30.0, max_visibility=0.6)
    check_well_posed(WEIGHTS, max_distance=30.0, max_visibility=0.6)


def test_check_well_posed_refuses_episodes_that_cost_more_than_getting_caught():
    # one step costs at most 10*0.6 + 0.5*30 + 1 = 22, so 100 steps up to 2200 > 200
    with pytest.raises(RewardError, match='episode of 100 steps can cost up to 2200'):
        check_well_posed(WEIGHTS, max_distance=30.0, max_visibility=0.6, max_steps=100)
    enough = dataclasses.replace(WEIGHTS, detection_penalty=2200.001)
    check_well_posed(enough, max_distance=30.0, max_visibility=0.6, max_steps=100)
    with pytest.raises(RewardError, match='max_steps'):
        check_well_posed(enough, max_distance=30.0, max_visibility=0.6, max_steps=0)


def test_with_the_episode_check_every_caught_episode_is_worse_than_every_other_one():
    rng = np.random.default_rng(5)
    max_steps, threshold, max_distance = 40, 0.6, 12.0
    for _ in range(20):
        weights = random_well_posed_weights(rng, max_distance, threshold, max_steps)
        worst_undetected, best_caught = math.inf, -math.inf
        for _ in range(200):
            length = int(rng.integers(1, max_steps + 1))
            distances = rng.uniform(0.0, max_distance, length)
            visibilities = rng.uniform(0.0, threshold * 0.999, length)
            steps = [
                step_reward(v, d, weights) for v, d in zip(visibilities, distances, strict=True)
            ]
            # the same prefix either times out / goes on, or ends in detection at its last step
            caught = sum(steps[:-1]) + detection_reward(distances[-1], weights)
            timed_out = sum(steps) + sum(
                step_reward(threshold * 0.999, max_distance, weights)
                for _ in range(max_steps - length)
            )
            worst_undetected = min(worst_undetected, timed_out)
            best_caught = max(best_caught, caught)
        assert best_caught < worst_undetected


def test_visibility_bound_per_mode():
    assert undetected_visibility_bound('threshold', 0.6, 4) == 0.6
    assert undetected_visibility_bound('probabilistic', 0.6, 4) == 4.0
    with pytest.raises(RewardError):
        undetected_visibility_bound('never', 0.6, 4)
