"""The move controller's speed law, one source for every path that drives a move: the
simulator's reference (``move_executor``), its compiled kernels (``kernels.move_loop``, where
numba compiles these same functions in) and the moves over topics (``stealth_env.topic_moves``).

Speeds follow the discrete-time braking curve of a control period ``dt``: the robot can always
stop within its deceleration and, near the end, covers the rest in one period (no slow
proportional tail).
"""

import math

from stealth_core.jit import jitable


@jitable
def approach_speed(distance: float, max_speed: float, decel: float, dt: float) -> float:
    """The fastest speed (<= max_speed) from which, after ``dt`` at it, the robot can still
    brake to rest within ``distance`` at ``decel``.

    It solves ``v dt + v^2 / 2a = d``: ``sqrt(2 a d)`` far out, ``d / dt`` (deadbeat) near
    the end, 0 when already there or past; following it never asks to slow by more than
    ``a dt`` per period.
    """
    if distance <= 0:
        return 0.0
    return min(decel * (math.sqrt(dt * dt + 2.0 * distance / decel) - dt), max_speed)


@jitable
def signed_approach_speed(offset: float, max_speed: float, decel: float, dt: float) -> float:
    """:func:`approach_speed` towards an ``offset`` of either sign (a heading error, a
    distance left that may lie behind), with the offset's sign."""
    return math.copysign(approach_speed(abs(offset), max_speed, decel, dt), offset)
