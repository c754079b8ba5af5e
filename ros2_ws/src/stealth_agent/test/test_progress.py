"""The agent's log lines about its run (progress windows, out-of-range states, totals)."""

from stealth_agent.progress import (
    ProgressLog,
    evaluation_line,
    format_progress,
    outcome_mix,
    totals_line,
)
from stealth_agent.protocol import EpisodeResult


def test_progress_line_reports_return_steps_outcomes_and_epsilon():
    results = [
        EpisodeResult(0, 0, 5.0, 10, 10.0, 0.1),
        EpisodeResult(1, 1, -20.0, 4, -10.0, 0.1),
        EpisodeResult(2, 2, -3.0, 100, -1.0, 0.05),
    ]
    line = format_progress(results, table_rows=42)
    for part in (
        'episodes 0-2 (learner total 3)',
        'return mean -6.000 [min -20.000, max 5.000], last -3.000',
        'steps mean 38.0, last 100',
        'outcomes: negative end 2, positive end 1',
        'epsilon 0.0500',
        'table 42 states',
    ):
        assert part in line
    assert 'outcomes: detected 1, success 2' in format_progress(
        results, table_rows=1, named_outcomes={'success': 2, 'detected': 1}
    )
    assert outcome_mix([EpisodeResult(0, 0, 0.0, 0, None, 0.0, aborted=True)]) == {'aborted': 1}


def test_a_window_of_log_every_episodes_makes_one_line_then_starts_afresh():
    log = ProgressLog()
    log.outcome('success')
    assert log.episode(EpisodeResult(0, 0, 1.0, 3, 1.0, 0.1), table_rows=5, log_every=2) is None
    log.outcome('detected')
    line = log.episode(EpisodeResult(1, 1, -1.0, 4, -1.0, 0.1), table_rows=6, log_every=2)
    assert line.startswith('episodes 0-1 (learner total 2)')
    assert 'outcomes: detected 1, success 1' in line and line.endswith('table 6 states')
    # The next window has its own outcomes: none named, so told by the terminal rewards.
    assert log.episode(EpisodeResult(2, 2, 2.0, 5, 2.0, 0.1), table_rows=6, log_every=2) is None
    line = log.episode(EpisodeResult(3, 3, 2.0, 5, 0.0, 0.1), table_rows=7, log_every=2)
    assert line.startswith('episodes 2-3') and 'outcomes: positive end 1, zero end 1' in line


def test_log_every_zero_never_logs_progress():
    log = ProgressLog()
    lines = [
        log.episode(EpisodeResult(e, e, 0.0, 1, 0.0, 0.1), table_rows=1, log_every=0)
        for e in range(50)
    ]
    assert lines == [None] * 50


def test_out_of_range_states_are_told_five_times_then_every_thousandth():
    log = ProgressLog()
    told = [n for n in range(1, 2501) if log.out_of_range('state [9.0] lies outside') is not None]
    assert told == [1, 2, 3, 4, 5, 1000, 2000]
    assert ProgressLog().out_of_range('state [9.0] lies outside') == (
        'state [9.0] lies outside (1 so far); it gets its own table row'
    )


def test_evaluation_and_totals_lines():
    result = EpisodeResult(9, 7, -3.25, 12, -1.0, 0.0, learning=False)
    assert evaluation_line(result, -3.25, 7) == (
        'greedy evaluation, episode 9 (after 7 learning episodes): return -3.250 in 12 steps'
    )
    assert totals_line(120, 110) == 'totals: 120 states received, 110 actions sent'


def test_totals_give_the_decision_times_when_kept():
    assert totals_line(3, 2) == 'totals: 3 states received, 2 actions sent'
    line = totals_line(3, 2, [0.001, 0.003], [0.0005, 0.0005])
    assert 'decision time per action: mean 2.000 ms, median 2.000 ms' in line
    assert 'max 3.000 ms (CPU mean 0.500 ms, p95 0.500 ms)' in line
