"""Lines of sight, compiled (numba, through ``stealth_core.jit``): ``lighting.line_of_sight``
walked line by line, as it walks one, stopping at the first block.

Why compiled: the light model's search asks a new lamp cell for a few hundred lines of sight
thousands of times an episode, and the lockstep numpy trace (``visibility``'s, one array pass
per Bresenham step of the longest line) cost about a millisecond a call however few the lines:
70 % of the search's time. ``visibility`` traces with ``occluded`` wherever numba imports (the
lockstep trace otherwise: the same answers); the bounce kernels call ``line_blocked``. Without
numba ``jit`` leaves both plain Python: the same answers, slowly.
"""

import numpy as np

from stealth_core.jit import jit
from stealth_core.lighting import bresenham_start, bresenham_step

_start = jit(bresenham_start)
_step = jit(bresenham_step)


@jit
def line_blocked(blocked, col0, row0, col1, row1):
    """``lighting.line_of_sight``'s answer negated: a blocking cell strictly between the two
    cells (the lamp's own never blocks), or a diagonal step squeezing between two."""
    line = _start(col0, row0, col1, row1)
    col, row = col0, row0
    while col != col1 or row != row1:
        if (col != col0 or row != row0) and blocked[row, col]:
            return True
        next_col, next_row, line = _step(col, row, line)
        diagonal = next_col != col and next_row != row
        if diagonal and blocked[row, next_col] and blocked[next_row, col]:
            return True
        col, row = next_col, next_row
    return False


@jit
def occluded(blocked, col0, row0, cols, rows):
    """For each target cell (cols[i], rows[i]), whether its line from (col0, row0) is blocked."""
    out = np.empty(cols.size, dtype=np.bool_)
    for i in range(cols.size):
        out[i] = line_blocked(blocked, col0, row0, cols[i], rows[i])
    return out
