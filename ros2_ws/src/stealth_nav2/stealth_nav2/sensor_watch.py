"""Noticing a robot whose ``odom`` or ``amcl_pose`` has gone silent, so a navigation aborts with
a line saying which instead of waiting for ever. Plain Python: times are wall-clock seconds
(the robot's own clock stops with it), given by the caller.

Odometry comes steadily: silent after ``timeout`` without a message. A localisation such as
AMCL publishes only after the robot has moved (its ``update_min_d``: a displacement from where it
last updated, not a distance driven), so ``amcl_pose`` is silent only once the odometry has
carried the robot ``travel`` metres away from where it was at the last one *and* ``timeout`` has
passed: a robot holding still for a moving light, or going back and forth by a wall (backing
off and meeting it again), is not mistaken for a dead localisation.
"""

from __future__ import annotations

import math

from stealth_core.kinematics import Pose


class SensorWatch:
    def __init__(self, timeout: float, travel: float):
        self.timeout = timeout
        self.travel = travel
        self._odom: tuple[float, Pose] | None = None  # (wall time, pose) of the latest
        self._estimate_wall: float | None = None
        self._origin: Pose | None = None  # the odometry pose at the latest estimate
        self._travelled = 0.0  # m: the furthest the odometry got from there since
        self._started = -math.inf  # wall time the watched navigation started

    def restart(self, now: float) -> None:
        """A navigation starts: silence counts from ``now``."""
        if self._odom is not None:
            self._odom = (max(self._odom[0], now), self._odom[1])
        if self._estimate_wall is not None:
            self._estimate_wall = max(self._estimate_wall, now)
        self._started = now

    def odom(self, now: float, pose: Pose) -> None:
        if self._origin is None:
            self._origin = pose
        self._travelled = max(self._travelled, math.dist(self._origin[:2], pose[:2]))
        self._odom = (now, pose)

    def estimate(self, now: float) -> None:
        self._estimate_wall = now
        self._origin = self._odom[1] if self._odom is not None else None
        self._travelled = 0.0

    def silent(self, now: float, odom_topic: str = 'odom', estimate_topic: str = 'amcl_pose'):
        """What has gone silent, in a line ('' when nothing has)."""
        started = self._started
        last_odom = self._odom[0] if self._odom is not None else started
        if now - last_odom > self.timeout:
            return f'no {odom_topic} for {self.timeout:g} s (is the robot running?)'
        if self._estimate_wall is None:
            if now - started > self.timeout:
                return f'no {estimate_topic} for {self.timeout:g} s (is the localisation running?)'
            return ''
        if now - self._estimate_wall > self.timeout and self._travelled > self.travel:
            return (
                f'no {estimate_topic} for {now - self._estimate_wall:.1f} s while the robot drove '
                f'{self._travelled:.1f} m on {odom_topic} (is the localisation running?)'
            )
        return ''
