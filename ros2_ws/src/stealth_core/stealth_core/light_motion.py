"""How the light belief's search sets a hypothesised light moving, stops it and moves its
motion, where the world's lights move (its timing). No rclpy.

A moving hypothesis is the parameters of ``light_world.hypothesis_light``: a static light's six,
then ``kind, a, b, period_bins, offset``. Each proposal keeps the light where the evidence saw
it: ``when`` is the time of the evidence sample it lights most, and a light set moving stands
then as it stood still, a stopped one as it stood then. ``free_rail(start, end)`` says whether
a patrol may run between two places (the belief knows the map).
"""

from __future__ import annotations

from collections.abc import Callable
import math

import numpy as np

from stealth_core.light_cycle import Timing
from stealth_core.light_world import PATROL, STATIC, SWEEP, hypothesis_light

MIN_SPAN = math.radians(5.0)  # the narrowest sweep searched
STILL_TAIL = (float(STATIC), 0.0, 0.0, 0.0, 0.0)  # a static light's motion in a timed world
# A patrol's rail moved whole, as polish parameter numbers (``rail_stepped``): along x, along y,
# and stretched about its middle.
RAIL_X, RAIL_Y, RAIL_STRETCH = -2, -3, -4
# The polish's first steps (parameter, step) of a motion: a sweep's span and offset (rad), a
# patrol's far end (m) and offset (m), and its rail moved whole (m).
MOTION_POLISH_STEPS = {
    SWEEP: ((7, math.radians(8.0)), (10, math.radians(8.0))),
    PATROL: ((7, 0.2), (8, 0.2), (10, 0.3), (RAIL_X, 0.3), (RAIL_Y, 0.3), (RAIL_STRETCH, 0.3)),
}

RailCheck = Callable[[np.ndarray, np.ndarray], bool]


def periods(timing: Timing) -> list[int]:
    """The periods (bins) a moving light may have: the divisors of the cycle's bins (every
    moving light's period divides the joint cycle), a single bin only where it is all."""
    bins = timing.cycle_bins
    return [d for d in range(2, bins + 1) if bins % d == 0] or [bins]


def animated(
    rng: np.random.Generator, params: tuple, when: float, timing: Timing, free_rail: RailCheck
) -> tuple | None:
    """A static light set sweeping or patrolling with a random span or rail and period, placed
    so that at time ``when`` it is as it is now; None when that cannot be (a rail into a wall,
    a sweep that would start turning down)."""
    x, y, direction, fov, beta, light_range = params[:6]
    period = int(rng.choice(periods(timing)))
    seconds = period * timing.bin_seconds
    if rng.random() < 0.5:  # a sweep: the phase at that time drawn, the start solved for
        span = float(rng.uniform(math.radians(20.0), math.pi))
        travelled = float(rng.uniform(0.0, 2.0 * span))
        along = travelled if travelled <= span else 2.0 * span - travelled
        low = direction - along
        start = (travelled - 2.0 * span * when / seconds) % (2.0 * span)
        if start > span:  # turning down at time 0: the same beam at `when` turning up
            start = (2.0 * span - travelled - 2.0 * span * when / seconds) % (2.0 * span)
            if start > span:
                return None
        return (x, y, low, fov, beta, light_range, float(SWEEP), span, 0.0, period, start)
    # A patrol: a rail across the beam (a lit band that travels) or along it (a lamp down a
    # corridor), as the shipped and generated rails run, now and then any way.
    axis = direction + float(rng.choice([0.0, 0.5, 1.0, 1.5])) * math.pi
    if rng.random() < 0.2:
        axis = float(rng.uniform(0.0, 2.0 * math.pi))
    length = float(rng.uniform(1.0, 8.0))
    unit = np.array([math.cos(axis), math.sin(axis)])
    travelled = float(rng.uniform(0.0, 2.0 * length))
    here = np.array([x, y])
    if travelled <= length:
        start = here - travelled * unit
    else:
        start = here + (travelled - length) * unit - length * unit
    end = start + length * unit
    if not free_rail(start, end):
        return None
    offset = (travelled - 2.0 * length * when / seconds) % (2.0 * length)
    return (
        float(start[0]), float(start[1]), direction, fov, beta, light_range,
        float(PATROL), float(end[0]), float(end[1]), period, offset,
    )  # fmt: skip


def stilled(params: tuple, when: float, timing: Timing) -> tuple:
    """A moving light stopped where it stands at time ``when``."""
    still = hypothesis_light('h', params, timing).at(when)
    return (still.x, still.y, still.direction, *params[3:6], *STILL_TAIL)


def motion_perturbed(
    rng: np.random.Generator, params: tuple, timing: Timing, free_rail: RailCheck
) -> tuple | None:
    """A moving light's motion moved at a random scale: its span or rail end, its offset, or
    its period; None for a rail into a wall."""
    moved = list(params)
    scale = 10.0 ** rng.uniform(-1.5, 0.0)
    which = int(rng.integers(3))
    if which == 2:
        moved[9] = float(rng.choice(periods(timing)))
    elif int(params[6]) == SWEEP:
        if which == 0:
            span = params[7] * math.exp(rng.normal(0, 0.3 * scale))
            moved[7] = float(np.clip(span, MIN_SPAN, math.pi * 2))
        moved[10] = float(
            np.clip(params[10] + rng.normal(0, math.radians(20.0) * scale), 0.0, moved[7])
        )
    else:
        if which == 0:
            moved[7] += rng.normal(0, 0.5 * scale)
            moved[8] += rng.normal(0, 0.5 * scale)
            if not free_rail(np.array(moved[:2]), np.array(moved[7:9])):
                return None
        length = math.hypot(moved[7] - moved[0], moved[8] - moved[1])
        moved[10] = float((params[10] + rng.normal(0, 0.5 * scale)) % max(2 * length, 1e-9))
    return tuple(moved)


def rail_stepped(params: tuple, parameter: int, step: float) -> tuple | None:
    """A patrol with its rail moved whole by ``step`` m: along x (``RAIL_X``) or y
    (``RAIL_Y``), or stretched at both ends (``RAIL_STRETCH``, the offset scaled with the loop so
    the lamp keeps its phase); None for a rail shorter than 0.5 m.

    Stepping one end alone moves where the lamp is at every time but that end's: a rail found
    a quarter of a metre short of both ends (floorplan-moving's, 2026-12-08) stayed there, where
    these steps took it to the truth's within 0.1 m."""
    moved = list(params)
    if parameter == RAIL_X:
        moved[0], moved[7] = params[0] + step, params[7] + step
    elif parameter == RAIL_Y:
        moved[1], moved[8] = params[1] + step, params[8] + step
    else:
        dx, dy = params[7] - params[0], params[8] - params[1]
        length = math.hypot(dx, dy)
        if length <= 0.0 or length + 2.0 * step < 0.5:
            return None
        ux, uy = dx / length, dy / length
        moved[0], moved[1] = params[0] - step * ux, params[1] - step * uy
        moved[7], moved[8] = params[7] + step * ux, params[8] + step * uy
        moved[10] = params[10] * (length + 2.0 * step) / length
    return tuple(moved)


def motion_valid(params: tuple) -> bool:
    """Whether a stepped sweep still has a span and its offset inside it (a polish's step)."""
    if len(params) <= 6 or int(params[6]) != SWEEP:
        return True
    return MIN_SPAN <= params[7] <= 2 * math.pi and 0.0 <= params[10] <= params[7]
