"""The one-bounce light's compiled kernels (numba, through ``stealth_core.jit``):
``visibility.bounce_field`` and ``PointVisibility`` call them; imported only when a scenario
has a bounce.

They are ``stealth_core.bounce``'s reference, loop for loop: ``bounce.contribution`` itself
compiled, and each line walked as ``line_of_sight`` walks it (``sight_kernels.line_blocked``,
stopping at the first block). The sums run per cell (per point) in emitter order, as the
reference adds them, so the results are equal to the last bit. Without numba ``jit`` leaves
them plain Python: the same numbers, slowly (``test_bounce`` runs them both ways).
"""

import numpy as np

from stealth_core.bounce import Bounce, Emitters, contribution
from stealth_core.jit import jit
from stealth_core.sight_kernels import line_blocked as _line_blocked

_contribution = jit(contribution)


@jit
def field(blocked, emitters, received, x_of_col, y_of_row, reach, parameters):
    """The bounce field: emitter after emitter (in order), every cell of its window."""
    height, width = blocked.shape
    weight, range_squared, beta = parameters
    field = np.zeros((height, width))
    for e in range(received.size):
        if received[e] <= 0.0:
            continue
        col, row = int(emitters[0, e]), int(emitters[1, e])
        normal_x, normal_y = emitters[2, e], emitters[3, e]
        centre_x, centre_y = x_of_col[col], y_of_row[row]
        for r in range(max(row - reach, 0), min(row + reach + 1, height)):
            dy = y_of_row[r] - centre_y
            for c in range(max(col - reach, 0), min(col + reach + 1, width)):
                value = _contribution(
                    weight, received[e], normal_x, normal_y, x_of_col[c] - centre_x, dy,
                    range_squared, beta,
                )  # fmt: skip
                if value > 0.0 and not _line_blocked(blocked, col, row, c, r):
                    field[r, c] += value
    return field


@jit
def at_points(blocked, xs, ys, cols, rows, emitters, received, centres, parameters):
    """The bounce at points (xs, ys) in cells (cols, rows): emitters added up in order."""
    weight, range_squared, beta = parameters
    totals = np.zeros(xs.size)
    for p in range(xs.size):
        total = 0.0
        for e in range(received.size):
            value = _contribution(
                weight, received[e], emitters[2, e], emitters[3, e],
                xs[p] - centres[0, e], ys[p] - centres[1, e], range_squared, beta,
            )  # fmt: skip
            col, row = int(emitters[0, e]), int(emitters[1, e])
            if value > 0.0 and not _line_blocked(blocked, col, row, cols[p], rows[p]):
                total += value
        totals[p] = total
    return totals


def emitter_table(emitters: Emitters) -> np.ndarray:
    """(4, n) float64: cols, rows, normal_x, normal_y (one array for the kernels)."""
    return np.stack([emitters.cols, emitters.rows, emitters.normal_x, emitters.normal_y]).astype(
        np.float64
    )


def parameters(bounce: Bounce, resolution: float) -> np.ndarray:
    return np.array([bounce.weight(resolution), bounce.range * bounce.range, bounce.beta])
