"""A brute-force reference of the move lattice's validity: exact distances from cell squares to
points and segments, cell by cell (test_move_lattice checks MoveLattice against it; so does
bench/bench_lattice.py, which times both)."""

import math


def square_to_segment(occupancy, col, row, p, q) -> float:
    """Distance from cell (col, row)'s square to the axis-aligned segment p-q (or point p = q)."""
    x0 = occupancy.origin[0] + col * occupancy.resolution
    y0 = occupancy.origin[1] + row * occupancy.resolution
    x1, y1 = x0 + occupancy.resolution, y0 + occupancy.resolution
    sx0, sx1 = sorted((p[0], q[0]))
    sy0, sy1 = sorted((p[1], q[1]))
    dx = max(0.0, x0 - sx1, sx0 - x1)
    dy = max(0.0, y0 - sy1, sy0 - y1)
    return math.hypot(dx, dy)


def reference_clear(occupancy, p, q, radius) -> bool:
    """No blocked or off-map cell nearer than radius to p-q (or touching it)."""
    reach = int(radius / occupancy.resolution) + 3
    col0, row0 = occupancy.world_to_cell(min(p[0], q[0]), min(p[1], q[1]))
    col1, row1 = occupancy.world_to_cell(max(p[0], q[0]), max(p[1], q[1]))
    for col in range(col0 - reach, col1 + reach + 1):
        for row in range(row0 - reach, row1 + reach + 1):
            distance = square_to_segment(occupancy, col, row, p, q)
            touched = distance < radius or distance == 0.0
            blocked = not occupancy.contains_cell(col, row) or occupancy.blocked[row, col]
            if touched and blocked:
                return False
    return True
