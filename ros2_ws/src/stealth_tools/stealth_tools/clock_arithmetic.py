"""Clock arithmetic for `topic hz` and `bag play`, free of ROS so it can be tested exactly."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math

DEFAULT_HZ_WINDOW = 10000  # ros2 topic hz's default window (messages)
NS = 10**9


@dataclass(frozen=True)
class RateStats:
    """What `ros2 topic hz` prints: mean rate and the spread of the intervals (s)."""

    rate: float
    min_delta: float
    max_delta: float
    std_dev: float
    window: int

    def text(self) -> str:
        return (
            f'average rate: {self.rate:.3f}\n'
            f'\tmin: {self.min_delta:.3f}s max: {self.max_delta:.3f}s '
            f'std dev: {self.std_dev:.5f}s window: {self.window}'
        )


class RateWindow:
    """Arrival intervals of the last `window` messages; a report at most once a second."""

    def __init__(self, window: int = DEFAULT_HZ_WINDOW):
        self.deltas: deque[int] = deque(maxlen=window)
        self.last_arrival: int | None = None
        self.last_report: int | None = None

    def add(self, arrival_ns: int) -> None:
        if self.last_arrival is not None:
            if arrival_ns < self.last_arrival:  # the clock jumped back (sim time reset)
                self.deltas.clear()
            else:
                self.deltas.append(arrival_ns - self.last_arrival)
        self.last_arrival = arrival_ns

    def report(self) -> RateStats | None:
        """Stats when a second of arrivals has passed since the last report, else None."""
        if not self.deltas:
            return None
        if self.last_report is None:
            self.last_report = self.last_arrival
            return None
        if self.last_arrival < self.last_report + NS:
            return None
        return self._stats()

    def final_report(self) -> RateStats | None:
        """Stats of what arrived since the last report, however short: the closing line of a
        command that ends (its --timeout) before the next second's report was due."""
        if not self.deltas or self.last_arrival == self.last_report:
            return None
        return self._stats()

    def _stats(self) -> RateStats:
        self.last_report = self.last_arrival
        count = len(self.deltas)
        mean = sum(self.deltas) / count
        std_dev = math.sqrt(sum((d - mean) ** 2 for d in self.deltas) / count)
        return RateStats(
            rate=NS / mean if mean > 0 else 0.0,
            min_delta=min(self.deltas) / NS,
            max_delta=max(self.deltas) / NS,
            std_dev=std_dev / NS,
            window=count,
        )


@dataclass(frozen=True)
class PlaybackTimeline:
    """Maps bag time (ns) to wall time (monotonic s) for playback at `rate` times real time."""

    bag_start_ns: int
    wall_start: float
    rate: float = 1.0

    def wall_time(self, bag_ns: int) -> float:
        """When (monotonic s) a message logged at bag_ns is due."""
        return self.wall_start + (bag_ns - self.bag_start_ns) / NS / self.rate

    def bag_time(self, wall: float) -> int:
        """The bag time (ns) playback has reached at monotonic time `wall` (for /clock)."""
        return self.bag_start_ns + round((wall - self.wall_start) * self.rate * NS)
