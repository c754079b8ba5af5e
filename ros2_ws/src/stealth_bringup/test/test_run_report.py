"""A run's figures from what orchestrating it found out (RunFacts; no ROS)."""

from stealth_bringup.run_report import RunFacts


class Episode:
    def __init__(self, episode, steps):
        self.episode, self.steps = episode, steps


def test_steps_per_second_come_from_when_the_episodes_ended():
    # `stealth train --episodes 3`: three episodes of 300 steps ended at 11, 12 and 13 s, while
    # the orchestrator was still checking the nodes' parameters; it took their reports in from
    # 20.0 and stopped the nodes at 20.015 (once reported as 900 steps at 59748/s).
    facts = RunFacts(started=0.0, training_started=20.0, stopped_at=20.015)
    facts.episode_ends = {0: 11.0, 1: 12.0, 2: 13.0}
    episodes = [Episode(0, 300), Episode(1, 300), Episode(2, 300)]
    assert facts.steps_per_second(episodes) == 300.0
    facts.released = 10.0  # the environment was not held
    assert facts.stepping_seconds() == 3.0


def test_without_the_ends_the_rate_is_over_the_time_followed():
    facts = RunFacts(started=0.0, training_started=5.0, stopped_at=9.0)
    assert facts.stepping_seconds() == 4.0
    assert facts.steps_per_second([Episode(0, 100), Episode(1, 300)]) == 100.0
    facts.episode_ends = {1: 8.0}  # one end known: no interval between two
    assert facts.stepping_seconds() == 3.0
    assert facts.steps_per_second([Episode(0, 100), Episode(1, 300)]) == 400 / 3
    assert RunFacts(started=0.0).steps_per_second([]) is None  # never got to the episodes
