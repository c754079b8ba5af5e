"""When a report was published, from its DDS source timestamp (run_monitor.sent_at)."""

import time

from stealth_bringup.run_monitor import PLAUSIBLE_DELAY, sent_at


def test_a_report_that_waited_in_its_queue_counts_from_when_it_was_sent():
    now = 1000.0
    sent = sent_at({'source_timestamp': time.time_ns() - 7 * 10**9}, now)
    assert 992.9 < sent < 993.1


def test_without_a_plausible_source_timestamp_it_counts_from_now():
    now = 1000.0
    assert sent_at({}, now) == now
    assert sent_at({'source_timestamp': 0}, now) == now
    assert sent_at({'source_timestamp': time.time_ns() + 5 * 10**9}, now) == now  # clock ahead
    late = time.time_ns() - int((PLAUSIBLE_DELAY + 60) * 1e9)
    assert sent_at({'source_timestamp': late}, now) == now


def _reports_of_three_fast_episodes_in_one_spin(budget: int):
    """The handlers of the monitor, fed what one spin can take in: three episodes' reports."""
    import types

    from stealth_bringup.episode_tracker import Tracker
    from stealth_bringup.run_monitor import Monitor
    from stealth_interfaces.msg import AgentEpisodeInfo, EpisodeSummary

    counted = []
    monitor = types.SimpleNamespace(
        frozen=False, late=[], ended={}, last_activity=0.0, tracker=Tracker(budget=budget)
    )
    monitor.on_record = counted.append
    monitor._elapsed = lambda: 1.0
    monitor._ended = lambda: Monitor._ended(monitor)
    for episode in range(3):
        Monitor._on_summary(
            monitor, EpisodeSummary(episode=episode, outcome=EpisodeSummary.TIMEOUT), {}
        )
        Monitor._on_agent_info(monitor, AgentEpisodeInfo(episode=episode))
    return counted, monitor.late


def test_reports_after_the_budget_are_not_the_runs_even_within_one_spin():
    counted, late = _reports_of_three_fast_episodes_in_one_spin(budget=2)
    assert [record.episode for record in counted] == [0, 1]
    assert [summary['episode'] for summary in late] == [2]  # summary.json's not_counted
    counted, late = _reports_of_three_fast_episodes_in_one_spin(budget=5)
    assert [record.episode for record in counted] == [0, 1, 2] and late == []


def test_step_reports_give_each_episode_its_lattice_scores_and_the_progress_line_its_verdict():
    """StepInfo's action and estimate reach the tracker (episode_scores); a greedy episode's
    progress line says whether it meets the criterion. Here map1: two steps up from the start
    (the episode's summary first, its StepInfo after)."""
    import io
    import types

    from stealth_bringup.episode_scores import EpisodeScorer
    from stealth_bringup.episode_tracker import Tracker
    from stealth_bringup.run_monitor import Monitor, Progress
    from stealth_core.scenario import load_scenario
    from stealth_interfaces.msg import AgentEpisodeInfo, EpisodeSummary, StepInfo

    scorer = EpisodeScorer(load_scenario('map1'), None)
    tracker = Tracker(budget=5, scorer=scorer)
    counted = []
    monitor = types.SimpleNamespace(
        frozen=False, late=[], ended={}, last_activity=0.0, tracker=tracker, paths={}, steps={}
    )
    monitor.on_record = counted.append
    monitor._elapsed = lambda: 1.0
    monitor._ended = lambda: Monitor._ended(monitor)
    Monitor._on_summary(
        monitor, EpisodeSummary(episode=0, outcome=EpisodeSummary.TIMEOUT, steps=2), {}
    )
    Monitor._on_agent_info(monitor, AgentEpisodeInfo(episode=0, greedy=True))
    assert counted == []  # waiting for its steps
    model, place = scorer.model, scorer.model.start
    for step in (1, 2):
        place = int(model.successors[place, 0])
        x, y = model.points[place]
        info = StepInfo(episode=0, step=step, action=0)
        info.estimated_pose.x, info.estimated_pose.y = float(x), float(y)
        Monitor._on_step(monitor, info)
    (record,) = counted
    assert record.lattice_steps == 2 and record.lattice_path_length == 2 * 0.5
    assert not record.meets_criterion  # a timeout
    err = io.StringIO()
    progress = Progress(tracker, err)
    progress.start(5)
    progress.on_record(record)
    progress.close()
    assert (
        'episode 0 (greedy evaluation): timeout in 2 steps, return 0.0, misses the criterion'
        in (err.getvalue())
    )
