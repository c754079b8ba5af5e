"""A wall-clock throttle for log lines that may repeat at every message."""

from __future__ import annotations

import math
import time


class Throttle:
    """True at most once per ``period`` s of wall time: checked before calling the logger,
    because rclpy's own ``throttle_duration_sec`` first finds the caller by reading source
    (inspect), ~2 ms per call even when it then drops the line."""

    def __init__(self, period: float):
        self.period = period
        self._next = -math.inf

    def __call__(self) -> bool:
        now = time.monotonic()
        if now < self._next:
            return False
        self._next = now + self.period
        return True
