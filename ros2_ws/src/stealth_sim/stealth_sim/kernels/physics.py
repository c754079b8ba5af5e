"""The robot's physics step as a kernel: ``kinematics.step_robot`` (velocity limits, exact arc
integration) and ``DiscFootprint``'s swept-disc collision with its bisected contact point."""

import math

from stealth_core.jit import jit

from stealth_sim.kernels.layout import (
    ANGULAR,
    ANGULAR_ACCEL,
    DT,
    FOOTPRINT_RES,
    FOOTPRINT_X,
    FOOTPRINT_Y,
    LINEAR,
    LINEAR_ACCEL,
    MAX_ANGULAR,
    MAX_LINEAR,
    RADIUS,
    YAW,
    X,
    Y,
)
from stealth_sim.kernels.numeric import TWO_PI, remainder

_SINC_SERIES = 1e-4  # kinematics.integrate's switch to the series form of sinc
_CONTACT_BISECTIONS = 12  # kinematics' bisection steps for a bump's contact point


@jit
def _sweep_touches_blocked(p, blocked, x0, y0, x1, y1):
    """``DiscFootprint._sweep_touches_blocked``: segment-to-square distances, exactly."""
    res, radius = p[FOOTPRINT_RES], p[RADIUS]
    origin_x, origin_y = p[FOOTPRINT_X], p[FOOTPRINT_Y]
    rows, cols = blocked.shape
    col_lo = max(math.floor((min(x0, x1) - radius - origin_x) / res), 0)
    col_hi = min(math.floor((max(x0, x1) + radius - origin_x) / res), cols - 1)
    row_lo = max(math.floor((min(y0, y1) - radius - origin_y) / res), 0)
    row_hi = min(math.floor((max(y0, y1) + radius - origin_y) / res), rows - 1)
    dx, dy = x1 - x0, y1 - y0
    length_sq = dx * dx + dy * dy
    radius_sq = radius * radius
    for row in range(row_lo, row_hi + 1):
        for col in range(col_lo, col_hi + 1):
            if not blocked[row, col]:
                continue
            left = origin_x + col * res
            bottom = origin_y + row * res
            right, top = left + res, bottom + res
            ex = max(max(left - x0, x0 - right), 0.0)
            ey = max(max(bottom - y0, y0 - top), 0.0)
            nearest = ex * ex + ey * ey
            ex = max(max(left - x1, x1 - right), 0.0)
            ey = max(max(bottom - y1, y1 - top), 0.0)
            nearest = min(nearest, ex * ex + ey * ey)
            if length_sq != 0.0:
                for corner in range(4):
                    corner_x = right if corner & 1 else left
                    corner_y = top if corner & 2 else bottom
                    t = ((corner_x - x0) * dx + (corner_y - y0) * dy) / length_sq
                    t = min(max(t, 0.0), 1.0)
                    ex, ey = x0 + t * dx - corner_x, y0 + t * dy - corner_y
                    nearest = min(nearest, ex * ex + ey * ey)
            if nearest < radius_sq:
                return True
            # segment_crosses_squares: the slab test, boundaries included.
            t_enter, t_exit = 0.0, 1.0
            for axis in range(2):
                start, delta, low = (x0, dx, left) if axis == 0 else (y0, dy, bottom)
                if delta == 0.0:
                    if not (low <= start and start <= low + res):
                        t_exit = -1.0
                    continue
                t_a, t_b = (low - start) / delta, (low + res - start) / delta
                t_enter = max(t_enter, min(t_a, t_b))
                t_exit = min(t_exit, max(t_a, t_b))
            if t_enter <= t_exit:
                return True
    return False


@jit
def _sweep_is_free(p, blocked, lower_bound, x0, y0, x1, y1):
    """``DiscFootprint.sweep_is_free``."""
    res, origin_x, origin_y = p[FOOTPRINT_RES], p[FOOTPRINT_X], p[FOOTPRINT_Y]
    rows, cols = blocked.shape
    col = math.floor((x0 - origin_x) / res)
    row = math.floor((y0 - origin_y) / res)
    end_col = math.floor((x1 - origin_x) / res)
    end_row = math.floor((y1 - origin_y) / res)
    if not (0 <= row < rows and 0 <= col < cols and 0 <= end_row < rows and 0 <= end_col < cols):
        return False
    if lower_bound[row, col] - math.hypot(x1 - x0, y1 - y0) >= p[RADIUS]:
        return True
    return not _sweep_touches_blocked(p, blocked, x0, y0, x1, y1)


@jit
def _limited(current, command, max_speed, max_accel, dt):
    """``kinematics.limited_velocity``."""
    target = min(max(command, -max_speed), max_speed)
    change = min(max(target - current, -max_accel * dt), max_accel * dt)
    return current + change


@jit
def physics_step(s, p, blocked, lower_bound, linear_command, angular_command):
    """``kinematics.step_robot`` on the state; True when the robot bumped."""
    dt = p[DT]
    linear = _limited(s[LINEAR], linear_command, p[MAX_LINEAR], p[LINEAR_ACCEL], dt)
    angular = _limited(s[ANGULAR], angular_command, p[MAX_ANGULAR], p[ANGULAR_ACCEL], dt)
    x0, y0, yaw0 = s[X], s[Y], s[YAW]
    half_turn = 0.5 * angular * dt
    if abs(half_turn) < _SINC_SERIES:
        sinc = 1.0 - half_turn * half_turn / 6.0
    else:
        sinc = math.sin(half_turn) / half_turn
    chord = linear * dt * sinc
    heading = yaw0 + half_turn
    x = x0 + chord * math.cos(heading)
    y = y0 + chord * math.sin(heading)
    yaw = remainder(yaw0 + angular * dt, TWO_PI)
    bumped = not _sweep_is_free(p, blocked, lower_bound, x0, y0, x, y)
    if bumped:
        low, high = 0.0, 1.0
        for _ in range(_CONTACT_BISECTIONS):
            middle = 0.5 * (low + high)
            free = _sweep_is_free(
                p, blocked, lower_bound, x0, y0, x0 + middle * (x - x0), y0 + middle * (y - y0)
            )
            if free:
                low = middle
            else:
                high = middle
        x, y = x0 + low * (x - x0), y0 + low * (y - y0)
        linear = angular = 0.0
    s[X], s[Y], s[YAW], s[LINEAR], s[ANGULAR] = x, y, yaw, linear, angular
    return bumped
