"""Epsilon and alpha schedules: pure functions of the episode number."""

import math

import pytest
from stealth_agent.learners import LearnerConfig, QLearning
from stealth_agent.schedules import Schedule, constant, exponential, linear, schedule_value


def test_constant():
    assert constant(0.3, 0) == 0.3 == constant(0.3, 10**6)
    assert Schedule.fixed(0.3)(12345) == 0.3


def test_linear_reaches_final_then_stays():
    assert linear(1.0, 0.1, 100, 0) == 1.0
    assert linear(1.0, 0.1, 100, 50) == pytest.approx(0.55)
    assert linear(1.0, 0.1, 100, 100) == pytest.approx(0.1)
    assert linear(1.0, 0.1, 100, 10_000) == pytest.approx(0.1)
    assert linear(1.0, 0.1, 100, -5) == 1.0  # before the first episode: the start


def test_exponential_time_constant_and_limit():
    assert exponential(1.0, 0.0, 50, 0) == 1.0
    assert exponential(1.0, 0.0, 50, 50) == pytest.approx(math.exp(-1))
    assert exponential(0.5, 0.1, 50, 50) == pytest.approx(0.1 + 0.4 * math.exp(-1))
    assert exponential(1.0, 0.05, 10, 10_000) == pytest.approx(0.05)
    values = [exponential(1.0, 0.0, 20, t) for t in range(100)]
    assert all(a > b for a, b in zip(values, values[1:], strict=False))


def test_schedules_are_pure():
    schedule = Schedule('exponential', 0.9, 0.05, 30.0)
    assert [schedule(t) for t in range(50)] == [schedule_value(schedule, t) for t in range(50)]
    assert Schedule.from_dict(schedule.to_dict()) == schedule


@pytest.mark.parametrize(
    ('args', 'message'),
    [
        (('cosine', 0.1, 0.0, 10.0), 'unknown schedule kind'),
        (('linear', 0.1, 0.0, 0.0), 'decay must be > 0'),
        (('linear', float('nan'), 0.0, 10.0), 'finite'),
    ],
)
def test_bad_schedules_are_rejected(args, message):
    with pytest.raises(ValueError, match=message):
        Schedule(*args)


def test_learner_rates_follow_the_schedules_per_episode():
    config = LearnerConfig(
        alpha=Schedule('linear', 0.5, 0.1, 4), epsilon=Schedule('exponential', 1.0, 0.0, 2)
    )
    learner = QLearning(2, config)
    seen = []
    for _ in range(6):
        seen.append((learner.alpha, learner.epsilon))
        learner.end_episode()
    assert [a for a, _ in seen] == pytest.approx([0.5, 0.4, 0.3, 0.2, 0.1, 0.1])
    assert [e for _, e in seen] == pytest.approx([math.exp(-t / 2) for t in range(6)])


def test_rates_outside_zero_one_are_rejected():
    with pytest.raises(ValueError, match='epsilon must stay in'):
        LearnerConfig(epsilon=Schedule('linear', 1.5, 0.0, 10))
    with pytest.raises(ValueError, match='gamma'):
        LearnerConfig(gamma=1.2)
