"""A run's figures from what orchestrating it found out (RunFacts; no ROS), and what it says of
its greedy episodes against the optimum."""

import io
from types import SimpleNamespace

from stealth_bringup import run_report
from stealth_bringup.episode_tracker import EpisodeRecord
from stealth_bringup.run_report import RunFacts, RunReport, criterion_line, path_label
from stealth_core.path_scores import Criterion


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


def scored(meets=True, lattice_steps=38):
    return EpisodeRecord(
        12, 'SUCCESS', 38, 1035.0, 0.1, 0.4, 19.3, 0.1, True, 0.0, 0.0, 10, 100, 50, 3.0,
        lattice_outcome='SUCCESS', lattice_steps=lattice_steps, lattice_path_length=19.0,
        lattice_peak_visibility=0.1, lattice_accumulated_visibility=0.4, path_over_optimum=1.027,
        exposure_over_optimum=0.02, true_path_over_optimum=1.043, estimated_path_length=19.1,
        meets_criterion=meets,
    )  # fmt: skip


def test_the_learned_path_is_labelled_with_its_scores_against_the_optimum():
    """path.png's legend: the true pose's figures, then the lattice path's ratio and excess
    over the optimum's and the verdict, not a return that looks better than the optimum's."""
    assert path_label(scored(), Criterion()) == (
        'learned: greedy episode 12, true pose (success, 38 steps, 19.3 m);\n'
        'on the lattice: 19.0 m (1.03x), exposure 0.40 (+0.02): meets the criterion '
        '(path <= 1.1x, exposure <= opt + 0.1)'
    )
    assert 'does not meet the criterion' in path_label(scored(meets=False), Criterion())
    assert path_label(scored(lattice_steps=-1), Criterion()).endswith('lattice scores unknown')
    assert criterion_line(scored(), Criterion(1.2, 0.5)) == (
        "on the lattice: path 1.03x the optimum's, exposure +0.020 against it (true pose's path "
        '1.04x): meets the criterion (path <= 1.2x, exposure <= opt + 0.5)'
    )


def test_a_long_path_gif_says_how_far_it_is(monkeypatch):
    # animate_scenario's progress: frames drawn at 0, 2, ..., 18 s of a fake clock.
    clock = iter([100.0, *(100.0 + 2 * k for k in range(10))])
    monkeypatch.setattr(run_report.time, 'monotonic', lambda: next(clock))
    said = []
    report = RunReport(SimpleNamespace(mode='train'), None, RunFacts(0.0), said.append)
    progress = report._frames_said(every=5.0)
    for done in range(1, 11):
        progress(done, 10)
    assert said == [
        'stealth train: path.gif: 4/10 frames in 6 s',
        'stealth train: path.gif: 7/10 frames in 12 s',
        'stealth train: path.gif: 10/10 frames in 18 s',
    ]


def test_a_short_path_gif_says_nothing(monkeypatch):
    clock = iter([100.0, 100.5, 101.0])
    monkeypatch.setattr(run_report.time, 'monotonic', lambda: next(clock))
    said = []
    report = RunReport(SimpleNamespace(mode='train'), None, RunFacts(0.0), said.append)
    progress = report._frames_said(every=5.0)
    progress(1, 2)
    progress(2, 2)
    assert said == []


def test_a_rollout_s_closing_line_names_stealth_rollout(tmp_path, monkeypatch):
    """It said `stealth eval: done ...`, the mode's name, not the command's."""
    monkeypatch.setattr(run_report.time, 'monotonic', lambda: 12.5)
    facts = RunFacts(started=0.0)
    facts.status, facts.message = 'success', '3 greedy episodes: 3 reached the goal'
    plan = SimpleNamespace(mode='eval', directory=tmp_path, continued=None)
    out = io.StringIO()
    RunReport(plan, SimpleNamespace(records=[]), facts, print).print_closing({}, out)
    assert out.getvalue().splitlines()[0] == (
        'stealth rollout: done after 12.5 s: 3 greedy episodes: 3 reached the goal'
    )
