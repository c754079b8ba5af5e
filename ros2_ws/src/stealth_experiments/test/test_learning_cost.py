"""Episodes to the criterion, 3 in a row (issue 41's measure), and what learning cost until
then: the pure functions, and one short run that stops there."""

import numpy as np
import pytest
from stealth_core.reward import EpisodeOutcome
from stealth_experiments.harness import (
    STREAK,
    LearningCost,
    RunSpec,
    first_streak,
    learning_cost,
    run,
    settled,
)

AT = [10, 20, 30, 40, 50, 60]
S, D, T = (int(EpisodeOutcome[name]) for name in ('SUCCESS', 'DETECTED', 'TIMEOUT'))


def test_the_streak_starts_at_its_first_evaluation():
    assert STREAK == 3
    assert first_streak(AT, [False, True, True, True, False, False]) == 20


def test_a_streak_broken_by_a_failure_does_not_count():
    assert first_streak(AT, [True, True, False, True, True, True]) == 40
    assert first_streak(AT, [True, True, False, True, True, False]) is None


def test_a_streak_completed_by_the_last_evaluation_counts_one_cut_short_by_the_end_does_not():
    assert first_streak(AT, [False, False, False, True, True, True]) == 40
    assert first_streak(AT, [False, False, False, False, True, True]) is None


def test_never_and_no_evaluations():
    assert first_streak(AT, [False] * 6) is None
    assert first_streak([], []) is None


def test_it_is_not_settling():
    """A later failure does not undo a streak (settled, the older measure, is undone by it)."""
    passed = [True, True, True, False, True, False]
    assert first_streak(AT, passed) == 10
    assert settled(AT, passed) is None


def test_other_streak_lengths_and_a_bad_one():
    assert first_streak(AT, [False, True, False, True, True, False], streak=1) == 20
    assert first_streak(AT, [False, True, False, True, True, False], streak=2) == 40
    with pytest.raises(ValueError, match='streak must be at least 1'):
        first_streak(AT, [True], streak=0)


def test_the_cost_counts_the_episodes_up_to_and_including_the_one_it_met_at():
    outcomes = np.array([D, T, D, S, D, S], dtype=np.int8)
    steps = np.array([3, 40, 5, 12, 7, 12])
    seconds = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    cost = learning_cost(3, outcomes, steps, seconds)
    assert (cost.episodes, cost.detections, cost.steps) == (3, 2, 48)
    assert cost.seconds == pytest.approx(0.6) and cost.met
    assert learning_cost(6, outcomes, steps, seconds).detections == 3
    assert learning_cost(None, outcomes, steps, seconds) == LearningCost(None, None, None, None)
    assert not learning_cost(None, outcomes, steps, seconds).met
    with pytest.raises(ValueError, match='7 episodes asked for, 6 trained'):
        learning_cost(7, outcomes, steps, seconds)


def test_a_run_evaluated_after_every_episode_stops_at_its_streak():
    """Prioritized sweeping on simple-maze meets the criterion within tens of episodes: the run
    stops STREAK - 1 episodes after the first of its streak, its figures agree with its
    per-episode records."""
    result = run(RunSpec('simple-maze', 'prioritized', 0, 300, eval_every=1, stop_at_streak=True))
    first = result.episodes_to_streak
    assert first is not None and len(result.train_outcomes) == first + STREAK - 1 < 300
    assert list(result.eval_at) == list(range(1, first + STREAK))
    assert result.eval_met[-STREAK:].all() and (first == 1 or not result.eval_met[first - 2])
    cost = result.cost
    assert cost.episodes == first
    assert cost.detections == int(np.count_nonzero(result.train_outcomes[:first] == D))
    assert cost.detections == result.detections[first - 1]
    assert cost.steps == int(result.train_steps[:first].sum()) <= result.env_steps
    assert 0 < cost.seconds < result.seconds
    assert result.env_steps == int(result.train_steps.sum())
