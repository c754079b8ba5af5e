"""When the environment gives up on a robot it drives over topics, and on which clock: plain
Python, no rclpy (``topic_robot`` feeds it).

Under ``use_sim_time`` everything that measures the robot is in the robot's own time, the
simulated time of ``/clock``: a move's time limit and stall time (message stamps), and the
odometry watchdog (no ``odom`` for ``move_timeout`` seconds of simulated time while the robot
has something to do), so a simulator running 50x faster than the wall, or slower on a loaded
machine, gets the same allowance. Only the clock itself is watched in wall time: a ``/clock``
that does not advance for ``clock_timeout`` wall seconds while the robot has something to do
(a simulator that died, hangs or was paused) fails what it was doing, where waiting on
simulated time would wait for ever. Time that stands still while the robot has nothing to do is
no silence: a simulator in lockstep with its controller holds its clock between moves.

Without ``use_sim_time`` the robot's time is the wall clock, and the odometry watchdog uses it.
"""

from __future__ import annotations

import math


class Silence:
    """How long something has been silent while the robot had something to do (s of one
    clock): silence counts only from when the robot was last given something to do."""

    def __init__(self):
        self._since = -math.inf  # the latest sign of life or start of a wait

    def heard(self, now: float) -> None:
        """A sign of life (a message, an advancing clock), or the start of a wait."""
        self._since = now

    def silent_for(self, now: float) -> float:
        return now - self._since


class ClockWatch:
    """Whether ``/clock`` advances: its latest value, and silence in wall time while waited on."""

    def __init__(self):
        self._value: int | None = None
        self.silence = Silence()

    def observe(self, clock_ns: int, wall: float, waiting: bool) -> None:
        """The clock's value at wall time ``wall``; ``waiting``: the robot has something to do
        (otherwise a clock that stands still is no silence)."""
        if clock_ns != self._value or not waiting:
            self.silence.heard(wall)
        self._value = clock_ns


def silence_reason(
    *,
    sim_time: bool,
    clock_silent: float,
    clock_timeout: float,
    odom_silent: float,
    move_timeout: float,
    clock_topic: str = '/clock',
    odom_topic: str = 'odom',
) -> str:
    """Why the robot's current task fails for silence ('' while it may go on).

    ``clock_silent``: wall s without an advancing /clock (used under ``sim_time``);
    ``odom_silent``: s of the robot's clock (simulated under ``sim_time``, else wall) without
    odometry.
    """
    if sim_time and clock_silent > clock_timeout:
        return (
            f'{clock_topic} has not advanced for {clock_silent:.1f} s of wall time '
            f'(clock_timeout {clock_timeout:g} s: is the simulator running, or paused?)'
        )
    if odom_silent > move_timeout:
        unit = 's of simulated time' if sim_time else 's'
        return f'no {odom_topic} for move_timeout {move_timeout:g} {unit} (is the robot running?)'
    return ''
