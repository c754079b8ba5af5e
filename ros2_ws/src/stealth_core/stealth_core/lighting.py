"""The lighting model, one point at a time: the reference that ``visibility`` must match.

A light lights a point (x, y) with

    I = cone(angle) / (1 + beta * d^2)  if d <= range and nothing blocks the way, else 0,

with d the distance from the lamp, ``beta = (1 - delta)/(delta*range^2)`` (so I(0) = 1 and
I(range) = delta) and ``cone`` 1 inside the cone, 0 outside, with an optional soft rim where it
falls linearly to 0 (``Searchlight.soft_edge``, a fraction of the half-angle). Lights add up.

Occlusion works on the map's cells. Decisions:

- Blocking cells are the map's occupied *and unknown* cells, as in the original design: light
  is not assumed to cross space nobody has seen (``OccupancyMap.blocked``).
- The ray is the integer Bresenham line from the lamp's cell to the point's cell (any octant).
  Only the cells strictly between them can block: the lamp may be mounted on or in a wall, and
  whether a point is lit must not depend on its own cell, or a robot whose pose estimate
  strays into an unknown cell would become invisible.
- No leaks through corners: a diagonal step of the line is blocked when both cells beside it
  (the two 4-neighbours shared by the cells it joins) are blocking.

Bad input (a point or lamp outside the map, NaN or infinite coordinates, a map that is not a
boolean mask) raises ``ValueError`` with a message saying what was wrong, never a silent zero.

The per-point pieces (``light_intensity`` and what it calls) are numpy functions that also work
on whole arrays; ``visibility.visibility_field`` calls them too, so the field and this reference
agree to the last bit, and what the field computes independently is the occlusion.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import math

import numpy as np

from stealth_core.searchlight import Searchlight


@dataclass(frozen=True)
class GridFrame:
    """Where a (height, width) grid of cells of ``resolution`` metres lies in the map frame.

    ``origin`` is (x, y) or (x, y, yaw): the lower-left corner of cell (col 0, row 0), row 0
    being the bottom row (nav_msgs/OccupancyGrid order). The yaw is ignored, exactly as
    ``stealth_core.occupancy_map.OccupancyMap`` (and nav2) ignore it, so that a cell here is the
    map's cell; the arithmetic is the same as ``world_to_cell`` and ``cell_to_world``.
    """

    width: int
    height: int
    resolution: float
    origin_x: float
    origin_y: float

    @classmethod
    def of(cls, blocked: np.ndarray, resolution: float, origin: Sequence[float]) -> GridFrame:
        check_blocked(blocked)
        resolution = float(resolution)
        if not (math.isfinite(resolution) and resolution > 0.0):
            raise ValueError(f'resolution: expected a finite number > 0 (m), got {resolution}')
        if len(origin) not in (2, 3):
            raise ValueError(f'origin: expected (x, y) or (x, y, yaw), got {origin!r}')
        values = [float(value) for value in origin]
        if not all(math.isfinite(value) for value in values):
            raise ValueError(f'origin: expected finite numbers, got {origin!r}')
        height, width = blocked.shape
        return cls(width, height, resolution, values[0], values[1])

    def cell_centre(self, col, row):
        """Map-frame centre of cell(s) (col, row); works on arrays."""
        x = self.origin_x + (np.asarray(col, dtype=np.float64) + 0.5) * self.resolution
        y = self.origin_y + (np.asarray(row, dtype=np.float64) + 0.5) * self.resolution
        return x, y

    def cell_of(self, x: float, y: float, what: str = 'point') -> tuple[int, int]:
        """(col, row) of the cell holding (x, y); ValueError when not finite or off the map."""
        x, y = float(x), float(y)
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f'{what} ({x}, {y}): coordinates must be finite numbers')
        col = math.floor((x - self.origin_x) / self.resolution)
        row = math.floor((y - self.origin_y) / self.resolution)
        if not (0 <= col < self.width and 0 <= row < self.height):
            raise ValueError(
                f'{what} ({x:g}, {y:g}) is outside the map (cell ({col}, {row}) not in'
                f' {self.width} x {self.height} cells)'
            )
        return col, row


def check_blocked(blocked: np.ndarray) -> None:
    if not isinstance(blocked, np.ndarray) or blocked.dtype != np.bool_ or blocked.ndim != 2:
        raise ValueError(
            'blocked: expected a 2-D boolean array (height, width), e.g. OccupancyMap.blocked;'
            f' got {getattr(blocked, "dtype", type(blocked).__name__)}'
            f' {getattr(blocked, "shape", "")}'
        )
    if blocked.size == 0:
        raise ValueError('blocked: the map has no cells')


def intensity(distance, beta):
    """1/(1 + beta*d^2): 1 at the lamp, delta at the range (works on arrays)."""
    distance = np.asarray(distance, dtype=np.float64)
    return intensity_from_squared(distance * distance, beta)


def intensity_from_squared(distance_squared, beta):
    return 1.0 / (1.0 + beta * distance_squared)


def cone_factor(angle_off_axis, fov: float, soft_edge: float = 0.0):
    """1 inside the cone, 0 outside, linear over the outer soft_edge of the half-angle."""
    off = np.abs(angle_off_axis)
    half = fov / 2.0
    if soft_edge == 0.0:
        return np.where(off <= half, 1.0, 0.0)
    return np.clip((half - off) / (half * soft_edge), 0.0, 1.0)


def angle_off_axis(light: Searchlight, dx, dy, direction=None):
    """Angle (rad, in [-pi, pi]) between the beam axis and the lamp-to-point offset (dx, dy);
    ``direction`` (rad, an array like dx) where each point sees the beam aimed its own way (a
    moving light at many times), the light's own otherwise."""
    if direction is None:
        axis_x, axis_y = math.cos(light.direction), math.sin(light.direction)
    else:
        axis_x, axis_y = np.cos(direction), np.sin(direction)
    along = axis_x * dx + axis_y * dy
    across = axis_x * dy - axis_y * dx
    return np.arctan2(across, along)


def light_intensity(light: Searchlight, dx, dy, direction=None):
    """Unoccluded intensity of a static light at offset (dx, dy) m from its lamp (arrays too;
    ``direction`` as ``angle_off_axis``'s).

    In range means d <= range, tested as d^2 <= range^2 so no square root is needed.
    """
    dx = np.asarray(dx, dtype=np.float64)
    dy = np.asarray(dy, dtype=np.float64)
    distance_squared = dx * dx + dy * dy
    lit = cone_factor(angle_off_axis(light, dx, dy, direction), light.fov, light.soft_edge)
    lit = lit * intensity_from_squared(distance_squared, light.beta)
    return np.where(distance_squared <= light.range * light.range, lit, 0.0)


def bresenham_line(col0: int, row0: int, col1: int, row1: int) -> list[tuple[int, int]]:
    """Cells of the integer Bresenham line from (col0, row0) to (col1, row1), both included.

    The all-octant form with one error term: each step moves along the major axis and,
    when the error says so, along the minor one too (a diagonal step).
    """
    line = bresenham_start(col0, row0, col1, row1)
    col, row = col0, row0
    cells = [(col, row)]
    while (col, row) != (col1, row1):
        col, row, line = bresenham_step(col, row, line)
        cells.append((col, row))
    return cells


def bresenham_start(col0: int, row0: int, col1: int, row1: int):
    """The line's constants and first error term: (d_col, d_row, step_col, step_row, error)."""
    d_col, d_row = abs(col1 - col0), -abs(row1 - row0)
    step_col = 1 if col1 > col0 else -1
    step_row = 1 if row1 > row0 else -1
    return (d_col, d_row, step_col, step_row, d_col + d_row)


def bresenham_step(col: int, row: int, line):
    """One step of the line from (col, row): the next cell and the line's new state (the
    compiled bounce kernels run this very function)."""
    d_col, d_row, step_col, step_row, error = line
    doubled = 2 * error
    if doubled >= d_row:
        error += d_row
        col += step_col
    if doubled <= d_col:
        error += d_col
        row += step_row
    return col, row, (d_col, d_row, step_col, step_row, error)


def line_of_sight(blocked: np.ndarray, lamp_cell, target_cell) -> bool:
    """True when no blocking cell strictly between the two cells, nor a corner, stops the ray."""
    cells = bresenham_line(*lamp_cell, *target_cell)
    for (col, row), (next_col, next_row) in zip(cells, cells[1:], strict=False):
        if (col, row) != tuple(lamp_cell) and blocked[row, col]:
            return False
        diagonal = next_col != col and next_row != row
        if diagonal and blocked[row, next_col] and blocked[next_row, col]:
            return False
    return True


def lights_at(lights: Iterable[Searchlight], t: float) -> list[Searchlight]:
    """Every light as it stands at time t (s)."""
    return [light.at(t) for light in lights]


def point_light_visibilities(
    blocked: np.ndarray,
    resolution: float,
    origin: Sequence[float],
    lights: Iterable[Searchlight],
    x: float,
    y: float,
    t: float = 0.0,
) -> list[float]:
    """Each light's visibility at point (x, y) m at time t s: the per-point reference."""
    frame = GridFrame.of(blocked, resolution, origin)
    target = frame.cell_of(x, y)
    values = []
    for light in lights_at(lights, t):
        lamp = frame.cell_of(light.x, light.y, what=f'searchlight {light.name!r}')
        value = float(light_intensity(light, x - light.x, y - light.y))
        if value > 0.0 and not line_of_sight(blocked, lamp, target):
            value = 0.0
        values.append(value)
    return values


def point_visibility(
    blocked: np.ndarray,
    resolution: float,
    origin: Sequence[float],
    lights: Iterable[Searchlight],
    x: float,
    y: float,
    t: float = 0.0,
) -> float:
    """Total visibility at (x, y) at time t: the sum over lights, added in the lights' order."""
    total = 0.0
    for value in point_light_visibilities(blocked, resolution, origin, lights, x, y, t):
        total += value
    return total
