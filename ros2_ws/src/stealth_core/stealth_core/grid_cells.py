"""Which cell of the grid observation (stealth_interfaces/GridObservation) a map point falls in.

The grid's geometry is (resolution, origin x, origin y): m, map frame, row 0 the southernmost.
The environment, which sends the grid (``stealth_core.grid_observation``), and the agent, which
reads it (``stealth_agent.grid_agent``), place a point by this one rule. No rclpy.
"""

from __future__ import annotations

import math


def cell_of(geometry, x: float, y: float) -> tuple[int, int]:
    """(row, col) of point (x, y) (m, map) on a grid of (resolution, origin x, origin y); it
    may lie outside the grid (a negative index or one past its size)."""
    resolution, x0, y0 = geometry
    return math.floor((y - y0) / resolution), math.floor((x - x0) / resolution)
