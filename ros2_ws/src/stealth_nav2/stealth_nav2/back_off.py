"""Backing a blocked robot off what blocks it before it replans, as Nav2's BackUp behaviour
does: drive straight backwards ``distance`` at ``speed`` (measured on odometry, smooth where
the localisation may jump), then plan again from where it stands. Plain Python, no rclpy: the
navigator feeds it odometry and sends the commands it gives.

A robot whose move ended BUMPED (the scan showed a wall within ``bump_distance`` ahead, or it
made no progress while told to drive) stands against what stopped it: a new plan from there
starts with the disc touching the wall, and with a localisation that has drifted towards the
wall the same leg blocks again. Backing off first gives the replan room. Strays and timeouts
replan at once (the robot is not against anything).

The back-off ends when it has covered ``distance``, when the robot makes no progress for
``stall_time`` (something behind it too: replan from there), or after its time limit.

**Away from the nearest obstacle** (``turn_to_nearest``): straight back moves the robot away
from what is dead ahead only; a robot that met a jut of wall at its front corner, or runs along
a wall its estimate has drifted towards, backs up along the wall and meets it again. So it
first turns in place (a disc turns freely) until the nearest return of the scan is dead ahead
(:func:`nearest_bearing`), then backs straight away from it: sideways off a wall beside it.
The turn also gives the localisation a new look (AMCL updates after ``update_min_a``, 0.2 rad).
"""

from __future__ import annotations

from collections.abc import Sequence
import dataclasses
import math
from typing import NamedTuple

import numpy as np
from stealth_core.kinematics import wrap_angle
from stealth_env.topic_moves import Command, Pose

from stealth_nav2.path_following import Replan


@dataclasses.dataclass(frozen=True)
class BackOffSettings:
    distance: float = 0.2  # m driven backwards (0: no back-off, replan at once)
    speed: float = 0.1  # m/s backwards (Nav2's BackUp default is 0.025 m/s; the sim is coarse)
    stall_time: float = 1.0  # s of the robot's clock without progress: something behind too
    progress: float = 0.005  # m: less than this over stall_time is no progress
    margin: float = 3.0  # s beyond distance / speed before it gives up
    turn_speed: float = 0.5  # rad/s at most while turning to face the nearest obstacle
    turn_tolerance: float = 0.05  # rad: facing it this closely is facing it
    min_turn: float = 0.1  # rad: an obstacle this close to dead ahead needs no turn
    turn_to_nearest: bool = True  # face the scan's nearest return first (False: Nav2's BackUp)


def nearest_bearing(
    ranges: Sequence[float] | np.ndarray,
    angle_min: float,
    angle_increment: float,
    range_min: float = 0.0,
    range_max: float = math.inf,
) -> float | None:
    """The bearing (rad, the scan's frame: 0 dead ahead, counter-clockwise) of the scan's
    nearest return; None when it has none (readings outside [range_min, range_max] or not
    finite are no returns)."""
    ranges = np.asarray(ranges, dtype=float)
    with np.errstate(invalid='ignore'):
        valid = np.isfinite(ranges) & (ranges >= range_min) & (ranges <= range_max)
    if not valid.any():
        return None
    index = int(np.argmin(np.where(valid, ranges, np.inf)))
    return wrap_angle(angle_min + angle_increment * index)


def backs_off(replan: Replan, settings: BackOffSettings) -> bool:
    """Whether the robot backs off before this replan: it was blocked (a recovery)."""
    return replan.blocked and replan.recovery and settings.distance > 0


class BackedOff(NamedTuple):
    """The back-off is over: how far the robot went (m) and, when short of the distance, why."""

    travelled: float
    short: str = ''


class BackOff:
    """One back-off from odometry pose ``start`` at the robot's clock ``t``: ``update`` with
    each odometry pose gives the command to send, or :class:`BackedOff` (then send a stop).
    ``turn`` (rad, counter-clockwise): first turn that much in place (to face the nearest
    obstacle, ``nearest_bearing``), then back straight off."""

    def __init__(self, start: Pose, t: float, settings: BackOffSettings, turn: float = 0.0):
        self.start = start
        self.settings = settings
        self.started = t
        turn = wrap_angle(turn)
        self.turn = turn if abs(turn) > settings.min_turn else 0.0
        self._heading = wrap_angle(start.yaw + self.turn)  # to face, before backing off
        self._turning = self.turn != 0.0
        self.time_limit = (settings.distance / settings.speed + settings.margin
                           + abs(self.turn) / settings.turn_speed)  # fmt: skip
        self._mark = (t, start)  # the last time it made progress, and where

    def travelled(self, pose: Pose) -> float:
        return 0.0 if self._turning else math.dist(self.start[:2], pose[:2])

    def update(self, t: float, pose: Pose) -> Command | BackedOff:
        settings = self.settings
        if t - self.started > self.time_limit:
            return BackedOff(self.travelled(pose), f'time limit {self.time_limit:.1f} s')
        if self._turning:
            error = wrap_angle(self._heading - pose.yaw)
            if abs(error) > settings.turn_tolerance:
                rate = min(settings.turn_speed, max(0.2, 2.0 * abs(error)))
                return Command(0.0, math.copysign(rate, error))
            self._turning = False  # facing it: back off from here
            self.start = pose
            self._mark = (t, pose)
        travelled = self.travelled(pose)
        if travelled >= settings.distance:
            return BackedOff(travelled)
        if math.dist(self._mark[1][:2], pose[:2]) >= settings.progress:
            self._mark = (t, pose)
        elif t - self._mark[0] >= settings.stall_time:
            return BackedOff(travelled, f'no progress for {settings.stall_time:g} s')
        # Slow down for the last few centimetres so the stop lands near the distance.
        left = settings.distance - travelled
        return Command(-min(settings.speed, max(0.02, 2.0 * left)), 0.0)
