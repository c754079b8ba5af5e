"""One-bounce light, one point at a time: the reference that ``visibility.bounce_field`` must
match. Walls reflect the searchlights' light diffusely; the bounced light adds to the direct.

The model, precisely (``Bounce`` holds its two numbers, ``albedo`` and ``range``):

- **Emitters** are the blocking cells (occupied or unknown: the cells that stop light,
  ``OccupancyMap.blocked``) with at least one free 4-neighbour; cells off the map are not free.
- **Normal**: the normalised sum of the unit directions to the free 4-neighbours, e.g. (1, 0)
  for a cell open to the east, (1, 1)/sqrt(2) for a corner open east and north. A cell open on
  two opposite sides only (a wall one cell thick) or on all four (a lone pixel) has a zero sum:
  no normal, and it emits nothing (the grid cannot tell which face the light fell on).
- **Received light** R of an emitter: the direct visibility (``lighting.point_visibility``, all
  lights) at the wall cell's centre. A point's own cell never blocks its light, so this is the
  light arriving at the wall cell's lit face; it is exactly the direct field on that cell.
- **Re-emission**: an emitter at its cell's centre c, with normal n, lights a point p with

      albedo * (resolution / 1 m) * R * max(0, cos a) / (1 + beta * d^2)

  where d = |p - c|, cos a = n . (p - c) / d (Lambertian at the wall) and, as for a searchlight
  of range ``range`` and delta 0.1, beta = (1 - 0.1) / (0.1 * range^2): the bounced light falls
  as a lamp's does and stops at ``range`` where it has dropped to a tenth. The factor
  ``resolution / 1 m`` is the cell's length of wall: the albedo is the share of the received
  light that one metre of wall sends back, so the bounce does not grow when the map's cells
  shrink (per cell, a 0.05 m map would otherwise count twenty emitters per metre of wall).
  Nothing is emitted when R = 0, d = 0, d > range (tested as d^2 > range^2) or cos a <= 0.
- **Occlusion**: as a searchlight's, the Bresenham line from the emitter's cell to the point's
  cell with ``lighting.line_of_sight``'s rules; the emitter's own cell never occludes (it is
  the line's first cell, like a lamp's), nor does the point's.
- **Sum**: the contributions add up in emitter order (row-major order of the map, bottom row
  first), and the bounce adds to the direct light: total = direct + bounce.

Moving lights: the received light would change with time, and the bounce with it; computing
it per time is not done, so a scenario with both is refused (``check_static``).

Everything here is plain Python per point (slow, simple): the definition the fast paths in
``stealth_core.visibility`` are tested against.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import math
from typing import NamedTuple

import numpy as np

from stealth_core.lighting import (
    GridFrame,
    intensity_from_squared,
    line_of_sight,
    point_visibility,
)
from stealth_core.searchlight import Searchlight

BOUNCE_DELTA = 0.1  # bounced intensity at the bounce range, as a lamp's default delta
WALL_LENGTH_UNIT = 1.0  # m: the albedo is per metre of wall
DEFAULT_RANGE = 3.0  # m
FOUR_NEIGHBOURS = ((1, 0), (-1, 0), (0, 1), (0, -1))  # (column step, row step)


@dataclass(frozen=True)
class Bounce:
    """The one-bounce light of a scenario: albedo in [0, 1), range (m) > 0."""

    albedo: float
    range: float = DEFAULT_RANGE

    def __post_init__(self):
        albedo, reach = float(self.albedo), float(self.range)
        if not (math.isfinite(albedo) and 0.0 <= albedo < 1.0):
            raise ValueError(f'albedo: expected a number in [0, 1), got {self.albedo!r}')
        if not (math.isfinite(reach) and reach > 0.0):
            raise ValueError(f'range: expected a number > 0 (m), got {self.range!r}')
        object.__setattr__(self, 'albedo', albedo)
        object.__setattr__(self, 'range', reach)

    @property
    def beta(self) -> float:
        return (1.0 - BOUNCE_DELTA) / (BOUNCE_DELTA * self.range * self.range)

    def weight(self, resolution: float) -> float:
        """albedo times one cell's length of wall (in metres of wall)."""
        return self.albedo * (float(resolution) / WALL_LENGTH_UNIT)


class Emitters(NamedTuple):
    """The wall cells that re-emit light, in row-major order, and their unit normals."""

    cols: np.ndarray  # int64
    rows: np.ndarray
    normal_x: np.ndarray  # float64, unit length
    normal_y: np.ndarray


def wall_emitters(blocked: np.ndarray) -> Emitters:
    """Blocking cells with a free 4-neighbour and a defined normal (see the module)."""
    free = np.pad(~blocked, 1, constant_values=False)
    height, width = blocked.shape
    sum_x = np.zeros(blocked.shape)
    sum_y = np.zeros(blocked.shape)
    for col_step, row_step in FOUR_NEIGHBOURS:
        neighbour = free[1 + row_step : height + 1 + row_step, 1 + col_step : width + 1 + col_step]
        sum_x += col_step * neighbour
        sum_y += row_step * neighbour
    length = np.hypot(sum_x, sum_y)
    rows, cols = np.nonzero(blocked & (length > 0.0))
    norm = length[rows, cols]
    return Emitters(
        cols.astype(np.int64),
        rows.astype(np.int64),
        sum_x[rows, cols] / norm,
        sum_y[rows, cols] / norm,
    )


def check_static(lights: Iterable[Searchlight]) -> None:
    """ValueError when a light moves: the bounce is computed for static lights only."""
    moving = [light.name for light in lights if light.is_moving]
    if moving:
        raise ValueError(
            f'one-bounce light is computed for static lights only; {", ".join(moving)} move'
        )


def received_light(
    blocked: np.ndarray,
    resolution: float,
    origin: Sequence[float],
    lights: Sequence[Searchlight],
    emitters: Emitters,
) -> list[float]:
    """Each emitter's received light: the direct visibility at its cell's centre (reference)."""
    frame = GridFrame.of(blocked, resolution, origin)
    x, y = frame.cell_centre(emitters.cols, emitters.rows)
    return [
        point_visibility(blocked, resolution, origin, lights, float(px), float(py))
        for px, py in zip(x, y, strict=True)
    ]


def contribution(weight, received, normal_x, normal_y, dx, dy, range_squared, beta) -> float:
    """One emitter's light at offset (dx, dy) m from its cell's centre: weight (albedo times
    the cell's length of wall) * R * cos / (1 + beta d^2), 0 where d = 0, d^2 > range^2 or
    cos <= 0. Plain arithmetic: ``visibility`` compiles this very function for its kernels, so
    the field and this reference compute every contribution in the same float operations."""
    distance_squared = dx * dx + dy * dy
    if distance_squared == 0.0 or distance_squared > range_squared:
        return 0.0
    along = normal_x * dx + normal_y * dy
    if along <= 0.0:
        return 0.0
    cosine = along / math.sqrt(distance_squared)
    return weight * received * cosine * (1.0 / (1.0 + beta * distance_squared))  # 1/(1+b d^2)


def point_bounce(
    blocked: np.ndarray,
    resolution: float,
    origin: Sequence[float],
    emitters: Emitters,
    received: Sequence[float],
    bounce: Bounce,
    x: float,
    y: float,
) -> float:
    """The bounced light at (x, y) m: every emitter, one after the other (the reference)."""
    frame = GridFrame.of(blocked, resolution, origin)
    target = frame.cell_of(x, y)
    weight, range_squared = bounce.weight(resolution), bounce.range * bounce.range
    total = 0.0
    for i, strength in enumerate(received):
        if strength <= 0.0:
            continue
        col, row = int(emitters.cols[i]), int(emitters.rows[i])
        centre_x, centre_y = (float(v) for v in frame.cell_centre(col, row))
        normal = float(emitters.normal_x[i]), float(emitters.normal_y[i])
        value = contribution(
            weight, strength, *normal, x - centre_x, y - centre_y, range_squared, bounce.beta
        )
        if value > 0.0 and line_of_sight(blocked, (col, row), target):
            total += value
    return total


def point_total_visibility(
    blocked: np.ndarray,
    resolution: float,
    origin: Sequence[float],
    lights: Sequence[Searchlight],
    x: float,
    y: float,
    t: float = 0.0,
    bounce: Bounce | None = None,
) -> float:
    """Direct plus bounced light at (x, y) at time t: ``lighting.point_visibility`` when
    bounce is None or its albedo is 0. Slow: it finds the emitters and their light each call."""
    direct = point_visibility(blocked, resolution, origin, lights, x, y, t)
    if bounce is None or bounce.albedo == 0.0:
        return direct
    check_static(lights)
    emitters = wall_emitters(blocked)
    received = received_light(blocked, resolution, origin, lights, emitters)
    return direct + point_bounce(blocked, resolution, origin, emitters, received, bounce, x, y)


def bounce_bound(bounce: Bounce | None, resolution: float, n_lights: int) -> float:
    """An upper bound of the bounced light anywhere (for the reward's well-posedness check):
    every cell within range an emitter lit by every light at 1, with cos a = 1."""
    if bounce is None or bounce.albedo == 0.0:
        return 0.0
    reach = int(math.ceil(bounce.range / resolution))
    offsets = np.arange(-reach, reach + 1) * float(resolution)
    squared = offsets[:, None] ** 2 + offsets[None, :] ** 2
    inside = squared <= bounce.range * bounce.range
    falloff = intensity_from_squared(squared[inside], bounce.beta)
    return float(bounce.weight(resolution) * n_lights * falloff.sum())
