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
