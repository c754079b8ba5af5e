"""When the simulator at ``real_time_factor`` 0 lets the next control period of a robot driven
over ``cmd_vel`` go by: plain Python, no rclpy.

"As fast as its subscribers keep up": the simulator steps the physics one control period (one
period of its periodic topics, ``1 / publish_rate`` of simulated time), publishes odometry,
scan and ``/clock``, and steps the next period as soon as the command that answers that
odometry arrives on ``cmd_vel`` (a controller that decides on every odometry message, as the
environment's ``topics`` interface and nav2's controllers do). A subscriber that does not
answer (a teleop tool, a viewer, a controller between its moves, a node that died) stalls
little: after one period of wall time without an answer the period goes by anyway, so time
runs at real time. A controller that answered the last period is waited for longer
(``PATIENCE``): it is slow, not gone. On a busy machine it may be off a core for a few hundred
milliseconds, and a period gone by under its last command drove the robot on past where the
controller meant to stop it (a move ended on the next node).

A controller that falls behind (its answer comes after that wait) would otherwise answer every
later period one period late, the simulator taking its answer to the previous odometry as the
answer to the latest one. So a period that went by unanswered right after an answered one owes
the controller that late answer: the next command is taken as it (it still drives the robot)
and does not let a period go by. A controller that was silent for several periods (between its
moves) owes nothing, and at most one command is ever taken as late.
"""

from __future__ import annotations

PATIENCE = 1.0  # wall s a period waits for the answer of a controller that answered the last


class Lockstep:
    """The answers a simulator in lockstep waits for: one command per odometry it published.

    Times are the caller's wall clock (s, e.g. time.monotonic()); ``max_wait`` is how long a
    period waits for its answer (the control period, in wall seconds: 1x once nobody answers),
    ``patience`` how long when the last period was answered (at least ``max_wait``).
    """

    def __init__(self, max_wait: float, patience: float = PATIENCE):
        self.max_wait = max_wait
        self.patience = patience
        self.restart()

    def restart(self) -> None:
        """Nothing awaited (time stood still, or a move or reset placed the robot): the next
        command lets a period go by at once."""
        self._sent_at: float | None = None  # when the odometry awaiting an answer went out
        self._answered = False  # the command for it has come
        self._last_answered = True  # the previous period went by on an answer
        self.owed = 0  # late answers still to come for periods that went by without them

    def sent(self, now: float) -> None:
        """The odometry of a new period went out at ``now``: its answer is awaited."""
        self._sent_at, self._answered = now, False

    def command(self) -> bool:
        """A command arrived: whether it lets the next period go by now."""
        if self.owed:
            self.owed -= 1  # the late answer to a period that went by without it
            return False
        if self._sent_at is not None and self._answered:
            return False  # a second command for one odometry (two publishers): nothing more
        self._answered = True
        self._last_answered = True
        return True

    def waited_out(self, now: float) -> bool:
        """Whether the awaited answer is overdue, so the next period goes by without it (it
        may still come: a late answer is owed when the previous period was answered)."""
        wait = max(self.max_wait, self.patience) if self._last_answered else self.max_wait
        if self._sent_at is None or self._answered or now - self._sent_at < wait:
            return False
        if self._last_answered:
            self.owed = 1
        self._last_answered = False
        self._answered = True  # this period's wait is over
        return True
