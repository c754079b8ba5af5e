"""Keeping the legs the navigator drives off walls, as Nav2's controllers do with the costmap's
inflation. Plain Python + numpy, no rclpy: the navigator gives it the map (its ``map`` topic)
and the legs of a path (``path_following.legs_of``).

The covert planner's path runs through lattice nodes, and a node may lie a few centimetres
beyond the robot's radius from a wall (lgfloor's east corridor: 0.15 m; a jut of wall at
(-0.75, 5.0): 0.05 m). The controller steers the localisation estimate onto the path, and the
estimate is off the truth by 0.1-0.18 m at times at the simulator's default odometry noise
(measured on lgfloor), so the real robot meets such walls and stops (blocked). Each straight
run of drives is therefore moved sideways, as a whole, by the least shift (at most
``max_shift``) that keeps the disc ``robot_radius + margin`` from every blocked cell beside it,
or, where no shift within ``max_shift`` does, by the shift that keeps it furthest (in
``LEVELS`` steps of the margin): ``stealth_core.clearance.Clearance.shift``, which the
environment's retry of a bumped lattice move uses too. A shift is at most ``max_shift``
across the drive, so with ``max_shift`` under half the lattice step each corner stays in its
lattice node's cell; the drives' ends move with them (two perpendicular drives meet where their
shifted lines cross), but the path's last pose moves only towards the goal (the planner put it
within the goal's radius). A shift never makes a drive worse than it was: a straight run whose
shifted drives, corners included, keep less clearance than planned is driven as planned.

The light is the planner's business: shifts are small and away from walls. The package's tests
walk the shifted legs of the shipped scenarios' covert paths in the light model.
"""

from __future__ import annotations

from collections.abc import Sequence
import math

from stealth_core.clearance import Clearance

from stealth_nav2.path_following import Leg, LegKind

PARALLEL = 0.1  # |sin| of the angle between drives below which their lines do not cross


def keep_clear(
    legs: Sequence[Leg], clearance: Clearance | None, goal: tuple[float, float] | None = None
) -> list[Leg]:
    """The legs with each straight run of drives shifted off the walls (``Clearance.shift``),
    the places of turns and waits moved with the drive that ends there. The last drive's end
    moves with it only towards ``goal`` (the navigation's goal point), else it stays where the
    path ends. A run whose shifted drives, corners included, keep less clearance than planned is
    driven as planned (and then its neighbours, when that is not enough)."""
    legs = list(legs)
    if clearance is None:
        return legs
    drives = [k for k, leg in enumerate(legs) if leg.kind is LegKind.DRIVE]
    runs = _straight_runs(legs, drives)
    run_of = {k: index for index, run in enumerate(runs) for k in run}
    run_shifts = [
        clearance.shift(legs[run[0]].x0, legs[run[0]].y0, legs[run[-1]].x, legs[run[-1]].y)
        for run in runs
    ]
    planned = {k: clearance.level(legs[k].x0, legs[k].y0, legs[k].x, legs[k].y) for k in drives}
    while True:
        shifts = {k: run_shifts[run_of[k]] for k in drives}
        shifted = _shifted(legs, drives, shifts, goal)
        worse = [
            k for k in drives
            if clearance.level(shifted[k].x0, shifted[k].y0, shifted[k].x, shifted[k].y)
            < planned[k]
        ]  # fmt: skip
        if not worse:
            return shifted
        index = run_of[worse[0]]
        if run_shifts[index]:
            run_shifts[index] = 0.0
        elif index > 0 and run_shifts[index - 1]:
            run_shifts[index - 1] = 0.0  # its corner with the run before
        elif index + 1 < len(runs) and run_shifts[index + 1]:
            run_shifts[index + 1] = 0.0
        else:
            return shifted  # as planned around it: nothing left to undo


def _straight_runs(legs: list[Leg], drives: list[int]) -> list[list[int]]:
    """The drives grouped into straight runs: one after the other along one line (split by a
    change of pace or a wait on a timed path)."""
    runs: list[list[int]] = []
    for k in drives:
        if runs:
            previous = legs[runs[-1][-1]]
            leg = legs[k]
            same_line = abs(math.remainder(leg.heading - previous.heading, math.tau)) < 1e-3
            if same_line and math.dist((previous.x, previous.y), (leg.x0, leg.y0)) < 1e-6:
                runs[-1].append(k)
                continue
        runs.append([k])
    return runs


def _shifted(legs: list[Leg], drives: list[int], shifts: dict[int, float], goal) -> list[Leg]:
    ends = {}  # index of a drive: where it ends now
    for position, k in enumerate(drives):
        if position + 1 < len(drives):
            following = drives[position + 1]
            ends[k] = _corner(legs[k], shifts[k], legs[following], shifts[following])
        else:
            ends[k] = _last_end(legs[k], shifts[k], goal)
    result = []
    here = None  # where the previous leg ended (None: where the legs begin)
    for k, leg in enumerate(legs):
        if leg.kind is LegKind.DRIVE:
            x0, y0 = here if here is not None else (leg.x0, leg.y0)
            x, y = ends[k]
            result.append(leg._replace(x0=x0, y0=y0, x=x, y=y))
            here = (x, y)
        elif here is not None:
            result.append(leg._replace(x0=here[0], y0=here[1], x=here[0], y=here[1]))
        else:
            result.append(leg)
    return result


def _last_end(leg: Leg, shift: float, goal) -> tuple[float, float]:
    """Where the last drive ends: shifted when that is no further from the goal."""
    nx, ny = _left(leg)
    x, y = leg.x + shift * nx, leg.y + shift * ny
    if goal is not None and math.dist((x, y), goal) <= math.dist((leg.x, leg.y), goal):
        return x, y
    return leg.x, leg.y


def _corner(leg: Leg, shift: float, following: Leg, next_shift: float) -> tuple[float, float]:
    """Where a shifted drive ends: where its line crosses the next drive's shifted line (a
    corner of the path), on its own line when the next one runs parallel."""
    nx, ny = _left(leg)
    mx, my = _left(following)
    px, py = leg.x + shift * nx, leg.y + shift * ny  # on this drive's shifted line
    ux, uy = -ny, nx  # this drive's direction
    vx, vy = -my, mx
    cross = ux * vy - uy * vx
    if abs(cross) < PARALLEL:
        return px, py
    # The next line: through the corner shifted by next_shift along its normal, direction v.
    qx, qy = leg.x + next_shift * mx, leg.y + next_shift * my
    t = ((qx - px) * vy - (qy - py) * vx) / cross
    return px + t * ux, py + t * uy


def _left(leg: Leg) -> tuple[float, float]:
    """The unit normal to the drive's left."""
    return -math.sin(leg.heading), math.cos(leg.heading)
