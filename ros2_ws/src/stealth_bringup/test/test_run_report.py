"""A run's figures from what orchestrating it found out (RunFacts; no ROS)."""

from stealth_bringup.run_report import RunFacts


def test_steps_per_second_count_from_the_first_step():
    # `stealth train --episodes 3`: the three episodes (900 steps) ran from 10 s to 13 s, while
    # the orchestrator was still checking the nodes' parameters; it began following them at
    # 20.0 and stopped the nodes at 20.015 (once reported as 900 steps at 59748/s).
    facts = RunFacts(started=0.0, training_started=20.0, stopped_at=20.015)
    facts.first_step, facts.last_episode = 10.0, 13.0
    assert facts.stepping_seconds() == 3.0
    assert 900 / facts.stepping_seconds() == 300.0


def test_without_a_step_report_the_run_counts_from_the_following():
    facts = RunFacts(started=0.0, training_started=5.0, stopped_at=9.0)
    assert facts.stepping_seconds() == 4.0  # no episode completed: up to the stop
    facts.last_episode = 8.0
    assert facts.stepping_seconds() == 3.0
    assert RunFacts(started=0.0).stepping_seconds() == 0.0  # never got to the episodes
