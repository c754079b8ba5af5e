"""What a lattice move that bumped does before its step is judged: back off to where it started
and try once more, on its lattice line moved off the walls. Plain Python, no rclpy.

Why: every action is a drive to the next lattice node, steered on the localisation estimate,
which is off the truth by ~5 cm at times. A generated door is 1.0 m wide with two lattice lines
0.25 m from its jambs: 0.05 m of clearance for the 0.2 m robot. A true pose that far off the line
meets the jamb, and the move ends BUMPED with the robot touching it. Before, that was the step's
end: the state rounds to the same node, a deterministic policy asks for the same move, and that
move starts at the contact, with an estimate that barely changed (the robot did not move the
filter's update distance), and bumps at once again, until the step limit.

The recovery, for a drive between two different nodes that ended BUMPED, once per step:

1. **Back off** to the start node, moved sideways as in 2 (``go_to``): the robot turns away
   from what it touched (about half a turn: the filter updates after ``update_min_a``, 0.2 rad),
   drives back and turns again to go on, so the retry starts from a fresh estimate, off the
   contact.
2. **Retry** the drive to the target node. Both points are moved sideways, as one line, by the
   least shift (at most ``max_shift``) that gives the middle of the drive the most clearance up
   to ``margin`` beyond the robot's radius (:class:`stealth_core.clearance.Clearance`, as the
   navigator's legs are moved): through a generated door, 0.1 m towards its middle, which leaves
   the disc 0.15 m from the nearer jamb instead of 0.05 m. ``max_shift`` stays under half a
   lattice step, so the robot never leaves the cells of the two nodes: the states, and the
   lattice exposure the step is judged on, are the ones planned.

The step is judged where the retry ends (its outcome is the step's). A retry that bumps too is a
BUMPED step: the agent decides again, and an action asked again backs off and retries again, each
time from a fresh estimate.
"""

from __future__ import annotations

import math

from stealth_core.clearance import Clearance, ClearanceSettings
from stealth_core.occupancy_map import OccupancyMap

MARGIN = 0.15  # m wanted between the robot's disc and a wall on the retry
SHIFT_SHARE = 0.3  # the retry's line moves at most this share of the lattice step sideways
MAX_SHIFT = 0.15  # m, and at most this far

Point = tuple[float, float]


class BumpRecovery:
    """The back-off and retry points of bumped lattice drives on one map."""

    def __init__(self, occupancy_map: OccupancyMap, robot_radius: float, step: float):
        max_shift = min(MAX_SHIFT, SHIFT_SHARE * step)
        settings = ClearanceSettings(robot_radius, MARGIN, max_shift)
        self._clearance = Clearance(occupancy_map, settings)

    def points(self, start: Point, target: Point) -> tuple[Point, Point]:
        """(back-off point, retry point) of the drive from node ``start`` to node ``target``:
        both nodes moved sideways by :meth:`Clearance.shift` of the drive."""
        length = math.dist(start, target)
        if length == 0:
            return start, target
        shift = self._clearance.shift(*start, *target)
        nx, ny = -(target[1] - start[1]) / length, (target[0] - start[0]) / length  # its left
        return (
            (start[0] + shift * nx, start[1] + shift * ny),
            (target[0] + shift * nx, target[1] + shift * ny),
        )
