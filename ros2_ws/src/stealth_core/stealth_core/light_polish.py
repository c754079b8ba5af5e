"""The moves of the belief's polish (``LightBelief.polish``), one hypothesised light at a time: a
parameter stepped (``stepped``), and a cone edge set where the evidence asks for it
(``edge_steps``, ``edge_moved``). Plain numpy, no rclpy.

**Why edges are placed, not stepped.** A step's light changes where a sample crosses one of the
cone's edges, so along one edge the energy is flat between the samples' angles and jumps at
them. Stepping the direction or the opening by halving steps (4, 2, 1, 0.5, 0.25 degrees) lands
between those angles only by chance, and each moves both edges or neither alone. Where the
truth's edge lies in a narrow window (floorplan-moving's rail lamp, 2026-12-08: a detection
0.35 degrees inside its edge, steps read dark a degree outside it), no step lowered the energy:
the best hypothesis stayed at 395 against the truth's 12, and at 288 with its edges placed on
the same evidence (in training that seed then met the criterion, docs: the light model). The
edge moves try exactly the angles that matter: each edge opened just past a sample the
hypothesis leaves too dark, or closed just short of one it leaves too bright (the nearest
``EDGE_CANDIDATES`` on each side), the other edge kept where it is.
"""

from __future__ import annotations

import math

import numpy as np

from stealth_core.light_motion import RAIL_STRETCH, RAIL_X, RAIL_Y, motion_valid, rail_stepped
from stealth_core.light_world import PATROL
from stealth_core.lighting import angle_off_axis
from stealth_core.searchlight import Searchlight, poses_at

MIN_FOV = math.radians(5.0)  # the narrowest cone a hypothesis may have
SLIDE = -1  # the polish's slide along the beam, as a parameter number
# The pattern search's first steps, (parameter, step): x, y (m), direction, fov (rad), log beta,
# range (m), and a slide along the beam (m) that keeps the light at the reach of intensity 0.3
# (x and beta alone trade off: a lamp farther back with a smaller beta lights a far patch
# alike). A moving light adds its motion's: a sweep's span and offset (rad), a patrol's far end
# (m) and offset (m): light_motion.MOTION_POLISH_STEPS.
POLISH_STEPS = (
    (0, 0.2), (1, 0.2), (2, math.radians(4.0)), (3, math.radians(4.0)), (4, 0.2), (5, 0.5),
    (SLIDE, 0.4),
)  # fmt: skip
POLISH_HALVINGS = 5
# The edge moves: how far an edge may move at once, how far past (or short of) a sample's
# angle it is set (0.01 degrees was measured and not kept), how many samples' angles each edge
# tries each way, and the rounds of them.
EDGE_REACH = math.radians(12.0)
EDGE_CLEARANCE = math.radians(0.1)
EDGE_CANDIDATES = 6
EDGE_ROUNDS = 3
UPPER, LOWER = 1.0, -1.0  # the edge at direction + fov/2, and at direction - fov/2


def stepped(params: tuple, parameter: int, step: float) -> tuple | None:
    """params with one parameter moved by ``step`` (beta by a factor exp(step); ``SLIDE``
    along the beam); None when that leaves its range."""
    moved = list(params)
    if parameter == 4:
        moved[4] = params[4] * math.exp(step)
    elif parameter in (RAIL_X, RAIL_Y, RAIL_STRETCH):
        return rail_stepped(params, parameter, step)
    elif parameter == SLIDE:  # slide along the beam, beta keeping the light where it is dim
        x, y, direction, _, beta, _ = params[:6]
        reach = math.sqrt((1.0 / 0.3 - 1.0) / beta)
        if reach - step <= 0.1:
            return None
        dx, dy = step * math.cos(direction), step * math.sin(direction)
        moved[0], moved[1] = x + dx, y + dy
        if len(params) > 6 and int(params[6]) == PATROL:  # the rail slides with its lamp
            moved[7], moved[8] = params[7] + dx, params[8] + dy
        moved[4] = beta * (reach / (reach - step)) ** 2
        moved[5] = params[5] - step
    else:
        moved[parameter] = params[parameter] + step
    return checked(moved)


def checked(params) -> tuple | None:
    """params as a tuple, or None where the cone, the range or the motion left its range."""
    if not (MIN_FOV <= params[3] <= 2 * math.pi) or params[5] <= 0.2:
        return None
    if not motion_valid(params):
        return None
    return tuple(params)


def edge_moved(params: tuple, edge: float, delta: float) -> tuple | None:
    """params with one cone edge (``UPPER`` or ``LOWER``) moved outwards by ``delta`` rad (in,
    where negative), the other kept; None where the cone leaves its range."""
    moved = list(params)
    moved[2] = params[2] + edge * delta / 2.0
    moved[3] = params[3] + delta
    return checked(moved)


def edge_steps(light: Searchlight, params: tuple, too_dark, too_bright) -> list[tuple]:
    """(edge, delta) moves of a light's cone edges (``edge_moved``), the nearest first on each
    side: opened just past a sample of a step left too dark (one lit sample lights it), closed
    just short of a sample of a step left too bright (a sample at a time: closing short of
    every in-cone sample of the step was measured and not kept, docs: the light model).
    ``too_dark`` and ``too_bright`` are the steps' sample points (x, y, t: (steps, samples)
    arrays, t None where lights do not move); ``light`` is the hypothesis' Searchlight,
    ``params`` its parameters."""
    half = params[3] / 2.0
    moves = []
    for points, opening in ((too_dark, True), (too_bright, False)):
        if points[0].size == 0:
            continue
        bearing = _bearings(light, params[5], *points)
        for edge in (UPPER, LOWER):
            off_axis = edge * bearing
            if opening:
                outside = (off_axis > half) & (off_axis <= half + EDGE_REACH)
                deltas = off_axis[outside] - half + EDGE_CLEARANCE
            else:
                inside = (off_axis <= half) & (off_axis >= half - EDGE_REACH)
                deltas = off_axis[inside] - half - EDGE_CLEARANCE
            deltas = np.unique(np.round(deltas, 4))  # 0.1 mrad apart: the same move
            nearest = deltas[np.argsort(np.abs(deltas))][:EDGE_CANDIDATES]
            moves.extend((edge, float(delta)) for delta in nearest)
    return moves


def _bearings(light: Searchlight, reach: float, x, y, t) -> np.ndarray:
    """Each sample's angle off the light's axis at the sample's time (rad, the law's own:
    ``lighting.angle_off_axis``), NaN beyond the light's range."""
    if t is None:
        lamp_x, lamp_y, direction = light.x, light.y, None
    else:
        lamp_x, lamp_y, direction = poses_at(light, t)
    bearing = angle_off_axis(light, x - lamp_x, y - lamp_y, direction)
    return np.where(np.hypot(x - lamp_x, y - lamp_y) <= reach, bearing, np.nan)
