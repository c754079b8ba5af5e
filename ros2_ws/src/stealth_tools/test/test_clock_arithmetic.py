"""Rate statistics of `topic hz` and the playback timeline of `bag play`."""

import pytest
from stealth_tools.clock_arithmetic import NS, PlaybackTimeline, RateWindow


def test_rate_is_reported_once_a_second_over_the_window():
    window = RateWindow(window=5)
    times = [0, 100, 200, 300, 400, 500, 600, 700, 800, 900, 1000, 1100, 1200]  # ms
    reports = []
    for t in times:
        window.add(t * 1_000_000)
        reports.append(window.report())
    # The second message arms the one-second cadence (as ros2 topic hz); a second later, stats.
    stats = reports[-2]
    assert reports[:-2] + reports[-1:] == [None] * (len(times) - 1)
    assert stats.rate == pytest.approx(10.0)
    assert (stats.min_delta, stats.max_delta, stats.std_dev, stats.window) == (0.1, 0.1, 0, 5)
    assert stats.text() == (
        'average rate: 10.000\n\tmin: 0.100s max: 0.100s std dev: 0.00000s window: 5'
    )


def test_a_command_ending_before_the_next_report_closes_with_what_came_since():
    window = RateWindow(window=20)
    assert window.final_report() is None  # nothing yet
    window.add(0)
    assert window.final_report() is None  # one arrival: no interval
    for t in (50, 100, 150, 200, 250):  # ms: 20 Hz for a quarter of a second, no report due
        window.add(t * 1_000_000)
        assert window.report() is None
    stats = window.final_report()
    assert stats.rate == pytest.approx(20.0) and stats.window == 5
    assert window.final_report() is None  # nothing new since that line


def test_spread_of_intervals():
    window = RateWindow()
    for t in (0, 100, 300, 400, 600, 700, 900, 1000, 1200):
        window.add(t * 1_000_000)
        stats = window.report()
    assert stats.min_delta == 0.1 and stats.max_delta == 0.2
    assert stats.std_dev == pytest.approx(0.05)
    assert stats.rate == pytest.approx(1 / 0.15)


def test_a_clock_jumping_back_restarts_the_window():
    window = RateWindow()
    window.add(5 * NS)
    window.add(6 * NS)
    window.add(1 * NS)
    assert not window.deltas


def test_timeline_maps_bag_time_to_wall_time_at_a_rate():
    timeline = PlaybackTimeline(bag_start_ns=10 * NS, wall_start=100.0, rate=2.0)
    assert timeline.wall_time(10 * NS) == 100.0
    assert timeline.wall_time(12 * NS) == 101.0
    assert timeline.bag_time(101.0) == 12 * NS
    assert timeline.bag_time(timeline.wall_time(13 * NS + 5)) == 13 * NS + 5
