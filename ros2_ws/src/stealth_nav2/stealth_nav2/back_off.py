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
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

from stealth_env.topic_moves import Command, Pose

from stealth_nav2.path_following import Replan


@dataclasses.dataclass(frozen=True)
class BackOffSettings:
    distance: float = 0.2  # m driven backwards (0: no back-off, replan at once)
    speed: float = 0.1  # m/s backwards (Nav2's BackUp default is 0.025 m/s; the sim is coarse)
    stall_time: float = 1.0  # s of the robot's clock without progress: something behind too
    progress: float = 0.005  # m: less than this over stall_time is no progress
    margin: float = 3.0  # s beyond distance / speed before it gives up


def backs_off(replan: Replan, settings: BackOffSettings) -> bool:
    """Whether the robot backs off before this replan: it was blocked (a recovery)."""
    return replan.blocked and replan.recovery and settings.distance > 0


class BackedOff(NamedTuple):
    """The back-off is over: how far the robot went (m) and, when short of the distance, why."""

    travelled: float
    short: str = ''


class BackOff:
    """One back-off from odometry pose ``start`` at the robot's clock ``t``: ``update`` with
    each odometry pose gives the command to send, or :class:`BackedOff` (then send a stop)."""

    def __init__(self, start: Pose, t: float, settings: BackOffSettings):
        self.start = start
        self.settings = settings
        self.started = t
        self.time_limit = settings.distance / settings.speed + settings.margin
        self._mark = (t, start)  # the last time it made progress, and where

    def travelled(self, pose: Pose) -> float:
        return math.dist(self.start[:2], pose[:2])

    def update(self, t: float, pose: Pose) -> Command | BackedOff:
        settings = self.settings
        travelled = self.travelled(pose)
        if travelled >= settings.distance:
            return BackedOff(travelled)
        if math.dist(self._mark[1][:2], pose[:2]) >= settings.progress:
            self._mark = (t, pose)
        elif t - self._mark[0] >= settings.stall_time:
            return BackedOff(travelled, f'no progress for {settings.stall_time:g} s')
        if t - self.started > self.time_limit:
            return BackedOff(travelled, f'time limit {self.time_limit:.1f} s')
        # Slow down for the last few centimetres so the stop lands near the distance.
        left = settings.distance - travelled
        return Command(-min(settings.speed, max(0.02, 2.0 * left)), 0.0)
