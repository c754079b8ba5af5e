"""The kernels' arithmetic that must equal Python's and NumPy's to the last bit: CPython's
``math.remainder``, NumPy's rounding wrap and its pairwise summation (numba has the first
nowhere and sums in plain order)."""

import math

import numpy as np
from stealth_core.jit import jit

TWO_PI = 2.0 * math.pi


@jit
def remainder(x, y):
    """CPython's ``math.remainder`` (exact, for finite x and y > 0): numba has none."""
    absx = abs(x)
    if absx < 0.5 * y:  # already in range (exact: fl(y - absx) >= y / 2 > absx)
        return x
    m = np.fmod(absx, y)
    c = y - m
    if m < c:
        r = m
    elif m > c:
        r = -c
    else:
        r = m - 2.0 * np.fmod(0.5 * (absx - m), y)
    return math.copysign(1.0, x) * r


@jit
def wrap_array_value(angle):
    """``kinematics.wrap_angle`` of an array element (round half to even, not remainder)."""
    return angle - TWO_PI * np.rint(angle / TWO_PI)


@jit
def _pairwise_block(values, start, count):
    """NumPy's pairwise summation of up to 128 contiguous float64: eight running sums."""
    if count < 8:
        total = 0.0
        for i in range(start, start + count):
            total += values[i]
        return total
    r0, r1, r2, r3 = values[start], values[start + 1], values[start + 2], values[start + 3]
    r4, r5, r6, r7 = values[start + 4], values[start + 5], values[start + 6], values[start + 7]
    whole = count - count % 8
    for i in range(start + 8, start + whole, 8):
        r0 += values[i]
        r1 += values[i + 1]
        r2 += values[i + 2]
        r3 += values[i + 3]
        r4 += values[i + 4]
        r5 += values[i + 5]
        r6 += values[i + 6]
        r7 += values[i + 7]
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for i in range(start + whole, start + count):
        total += values[i]
    return total


@jit
def pairwise_sum(values, count):
    """NumPy's pairwise summation (what ``ndarray.sum`` does): halves (multiples of 8) until
    blocks of 128, here without recursion (which numba's cache cannot hold)."""
    if count <= 128:
        return _pairwise_block(values, 0, count)
    starts = np.empty(64, np.int64)
    counts = np.empty(64, np.int64)
    stages = np.empty(64, np.int64)
    lefts = np.empty(64)
    depth, starts[0], counts[0], stages[0] = 0, 0, count, 0
    total = 0.0
    while depth >= 0:
        n = counts[depth]
        if n <= 128:
            total = _pairwise_block(values, starts[depth], n)
            depth -= 1
            continue
        half = n // 2
        half -= half % 8
        if stages[depth] == 2:
            total = lefts[depth] + total
            depth -= 1
            continue
        if stages[depth] == 1:
            lefts[depth] = total
        stages[depth] += 1
        first = stages[depth] == 1
        starts[depth + 1] = starts[depth] if first else starts[depth] + half
        counts[depth + 1] = half if first else n - half
        stages[depth + 1] = 0
        depth += 1
    return total
