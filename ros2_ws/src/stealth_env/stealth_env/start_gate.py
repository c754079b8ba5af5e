"""When the environment node may start an episode: everything it needs (the robot, an agent,
the readers of its steps) is there and has been for ``start_delay``, and a failed reset's retry
time has come; while something is missing, a line every WAITING_LOG_PERIOD says what. No rclpy:
times are the caller's wall clock (s, e.g. time.monotonic())."""

from __future__ import annotations

WAITING_LOG_PERIOD = 10.0  # s of wall time between 'still waiting' lines


class StartGate:
    """The start decision, asked at every housekeeping tick (``check``)."""

    def __init__(self, now: float):
        self._ready_since: float | None = None  # when everything was last found there
        self._retry_at = 0.0  # no start before this (a failed reset's retry)
        self._waiting_logged = now  # the first line comes a period after the node started

    def retry_at(self, when: float) -> None:
        """A reset failed: the next start no earlier than ``when``."""
        self._retry_at = when

    def check(
        self, now: float, needs: dict[str, bool], start_delay: float
    ) -> tuple[bool, str | None]:
        """(whether to start the episode now, a line to log or None). ``needs`` maps what an
        episode needs, described, to whether it is there; all of it must have been there for
        ``start_delay`` s (a missing one starts the wait again)."""
        missing = [what for what, there in needs.items() if not there]
        if missing:
            self._ready_since = None
            if now - self._waiting_logged < WAITING_LOG_PERIOD:
                return False, None
            self._waiting_logged = now
            return False, f'still waiting for {" and ".join(missing)}'
        if self._ready_since is None:
            self._ready_since = now
        return now - self._ready_since >= start_delay and now >= self._retry_at, None
