"""What the simulator node does with the wall time between moves: plain Python, no rclpy.

Simulated time between moves is the only place where wall time could reach the simulation: the
node's idle timer ticks every ``idle_period`` of wall time and steps the physics up to where the
real-time factor says simulated time should be. That is what a robot driven over ``cmd_vel``
needs (teleoperation, the environment's ``topics`` interface), but training over the move
service must not depend on it: every physics step may draw odometry noise or update the filter,
and simulated time is when the searchlights are judged, so a step taken because the machine was
slow to send the next move would make the episode depend on the load.

So with ``real_time_factor`` 0 (training), time stands still between moves unless something
outside moves the robot: a fresh ``cmd_vel``, or a robot still coasting after one; then it
flows in lockstep with whoever commands it (:mod:`stealth_sim.lockstep`: a control period per
answer on ``cmd_vel``, at most a period of wall time each). A robot that a move or a reset left
in place is *held*, even when the move's final braking stopped it within the controller's
``stopped_speed`` rather than at exactly zero (a residual of < 1e-3 m/s that the next move's
first step then takes up, identically in every run). With a real-time factor > 0 (``--watch``)
simulated time follows wall time by design and a run is not repeatable step for step.
"""

from __future__ import annotations

import time
from typing import NamedTuple

MAX_CATCH_UP = 0.25  # s of simulated time an idle tick may run before the clock is re-anchored


class IdleTick(NamedTuple):
    """What one idle tick does: step the physics until simulated time ``until`` (no step when
    it is not one physics step ahead), after re-anchoring the real-time pacer at the current
    simulated time when ``anchor``; with ``lockstep``, time flows in lockstep with the
    commands instead (``until`` is then the current time: the tick only lets a period whose
    answer is overdue go by, :class:`stealth_sim.lockstep.Lockstep`)."""

    until: float
    anchor: bool
    lockstep: bool = False


def idle_tick(
    sim_time: float,
    due: float,
    *,
    real_time_factor: float,
    commanded: bool,
    moving: bool,
    held: bool,
    idle_period: float,
    max_catch_up: float = MAX_CATCH_UP,
) -> IdleTick:
    """The idle tick at simulated time ``sim_time`` when the pacer says simulated time should
    be ``due`` by now (at the real-time factor; not used when it is 0).

    commanded: a cmd_vel command is fresh; moving: the robot's velocities are not both exactly
    zero; held: no cmd_vel came since the last move or reset left the robot in place.
    """
    if real_time_factor == 0.0:
        if not commanded and (held or not moving):
            return IdleTick(sim_time, True)  # training: time stands still between moves
        return IdleTick(sim_time, True, lockstep=True)  # as fast as the commands come
    if due - sim_time > max_catch_up:  # fell behind (a busy machine): do not race
        return IdleTick(sim_time + idle_period * real_time_factor, True)
    return IdleTick(due, False)


class RealTimePacer:
    """Holds simulated time to ``factor`` times wall time from an anchor (0: never holds)."""

    def __init__(self, sim_time: float):
        self.anchor(sim_time)

    def anchor(self, sim_time: float) -> None:
        self.wall_start, self.sim_start = time.monotonic(), sim_time

    def due(self, factor: float) -> float:
        """The simulated time that should have been reached by now."""
        return self.sim_start + (time.monotonic() - self.wall_start) * factor

    def wait(self, sim_time: float, factor: float) -> None:
        if factor > 0:
            ahead = (sim_time - self.sim_start) / factor - (time.monotonic() - self.wall_start)
            if ahead > 1e-3:
                time.sleep(ahead)
