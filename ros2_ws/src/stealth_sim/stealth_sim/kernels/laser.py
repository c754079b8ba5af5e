"""The laser as a kernel: ``RayCaster.cast`` from a free start (``RayCaster._trace``), and
:func:`cast`, the caster's own ranges computed by it."""

import math

import numpy as np
from stealth_core.jit import jit

from stealth_sim.kernels.layout import CASTER_RES, CASTER_X, CASTER_Y, PARAMS_SIZE, RANGE_MAX


@jit
def cast_from_free(p, free_samples, row_stride, steps, x, y, yaw, bearings):
    """``RayCaster.cast`` from a free start (the robot's always is): ``RayCaster._trace``."""
    scale, res, range_max = 4, p[CASTER_RES], p[RANGE_MAX]
    origin_x, origin_y = p[CASTER_X], p[CASTER_Y]
    start_col = ((x - origin_x) / res + 1.0) * scale
    start_row = ((y - origin_y) / res + 1.0) * scale
    ranges = np.empty(bearings.size)
    for beam in range(bearings.size):
        angle = yaw + bearings[beam]
        cos_b, sin_b = math.cos(angle), math.sin(angle)
        cos_s, sin_s = cos_b * scale, sin_b * scale
        k, hit, col, row = 0, False, 0, 0
        while k < steps.size:
            col = int(start_col + cos_s * steps[k])
            row = int(start_row + sin_s * steps[k])
            free_after = free_samples[row * row_stride + col]
            if free_after == 0:
                hit = True
                break
            k += free_after
        if not hit:
            ranges[beam] = np.inf
            continue
        left = origin_x + (col // scale - 1) * res
        bottom = origin_y + (row // scale - 1) * res
        t_x = min((left - x) / cos_b, (left + res - x) / cos_b) if cos_b != 0.0 else -np.inf
        t_y = min((bottom - y) / sin_b, (bottom + res - y) / sin_b) if sin_b != 0.0 else -np.inf
        entry = max(t_x, t_y, 0.0)
        ranges[beam] = entry if entry <= range_max else np.inf
    return ranges


def cast(caster, x: float, y: float, yaw: float, bearings: np.ndarray) -> np.ndarray:
    """``caster.cast`` (a ``RayCaster``) on the kernel: the same ranges (noise-free, m; +inf =
    no return). The kernel traces from a free start, as the robot's always is; from anywhere
    else (only a caller's pose could be) the caster's own march runs."""
    if not caster._starts_free(x, y):
        return caster.cast(x, y, yaw, bearings)
    arrays = getattr(caster, '_compiled_arrays', None)
    if arrays is None:
        params = np.zeros(PARAMS_SIZE)
        params[[CASTER_RES, CASTER_X, CASTER_Y, RANGE_MAX]] = (
            caster.resolution,
            caster.origin_x,
            caster.origin_y,
            caster.range_max,
        )
        arrays = caster._compiled_arrays = (
            params,
            np.frombuffer(caster._free_samples, dtype=np.uint8),
            caster.blocked.shape[1] * 4,
            np.asarray(caster._steps, dtype=np.float64),
        )
    bearings = np.ascontiguousarray(bearings, dtype=np.float64)
    return cast_from_free(*arrays, float(x), float(y), float(yaw), bearings)
