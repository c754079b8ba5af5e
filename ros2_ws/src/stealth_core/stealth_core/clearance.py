"""How far a drive keeps the robot's disc off the walls, and the least sideways shift that keeps
it further: what Nav2's controllers get from the costmap's inflation. Plain Python + numpy, no
rclpy.

The lattice's moves may pass a few centimetres beyond the robot's radius from a wall (a
generated building's door: 0.05 m; lgfloor's jut of wall at (-0.75, 5.0): 0.05 m), while the
localisation estimate the moves are driven on is off the truth by several centimetres. Two
users shift a drive sideways, off the walls beside it: the navigator's legs
(``stealth_nav2.leg_clearance``) and the environment's retry of a lattice move that bumped
(``stealth_core.bump_recovery``).
"""

from __future__ import annotations

import dataclasses
import math

from stealth_core.kinematics import DiscFootprint
from stealth_core.occupancy_map import OccupancyMap

LEVELS = 4  # clearance levels between the bare radius and radius + margin


@dataclasses.dataclass(frozen=True)
class ClearanceSettings:
    robot_radius: float = 0.2  # m
    margin: float = 0.15  # m wanted between the disc and a wall (0: no shifting)
    max_shift: float = 0.15  # m a drive may move sideways (under half a lattice step)
    shift_step: float = 0.025  # m between the shifts tried


class Clearance:
    """The map's footprints for discs from ``robot_radius`` to ``robot_radius + margin``."""

    def __init__(self, occupancy_map: OccupancyMap, settings: ClearanceSettings):
        self.settings = settings
        radius, margin = settings.robot_radius, settings.margin
        # Widest first: level LEVELS is the full margin, level 0 the bare disc.
        self._footprints = [
            DiscFootprint(occupancy_map, radius + margin * k / LEVELS)
            for k in range(LEVELS, -1, -1)
        ]

    def level(self, x0: float, y0: float, x1: float, y1: float) -> int:
        """How much clearance the disc swept along the segment keeps: LEVELS for the whole
        margin, 0 for only the bare radius, -1 when it touches a wall."""
        for index, footprint in enumerate(self._footprints):
            if footprint.sweep_is_free(x0, y0, x1, y1):
                return LEVELS - index
        return -1

    def shift(self, x0: float, y0: float, x1: float, y1: float) -> float:
        """The least sideways shift (m, to the left of the drive from (x0, y0) to (x1, y1);
        within ``max_shift``) that gives the drive the most clearance beside it (its ends
        trimmed by the margin: what stands across a corner is the next drive's business)."""
        settings = self.settings
        length = math.dist((x0, y0), (x1, y1))
        if settings.margin <= 0 or settings.max_shift <= 0 or length == 0:
            return 0.0
        ux, uy = (x1 - x0) / length, (y1 - y0) / length
        trim = min(settings.margin, length / 2)
        x0, y0, x1, y1 = x0 + trim * ux, y0 + trim * uy, x1 - trim * ux, y1 - trim * uy
        nx, ny = -uy, ux
        best, best_level = 0.0, self.level(x0, y0, x1, y1)
        steps = int(math.floor(settings.max_shift / settings.shift_step + 1e-9))
        for k in range(1, steps + 1):
            if best_level == LEVELS:
                break
            for s in (k * settings.shift_step, -k * settings.shift_step):
                level = self.level(x0 + s * nx, y0 + s * ny, x1 + s * nx, y1 + s * ny)
                if level > best_level:
                    best, best_level = s, level
        return best
