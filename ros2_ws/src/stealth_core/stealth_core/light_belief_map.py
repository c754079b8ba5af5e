"""The light model's belief as two map-aligned grids, for a viewer and the run's pictures: the
most likely light field and the places the belief is unsure of. No rclpy.

The belief is the arrays ``LightModelLearner.belief_arrays`` gives and a saved light-model
policy holds (``belief_lights``: one row per hypothesised light, particle, x, y, direction (rad),
fov (rad), beta (1/m^2), range (m), and where lights move five more columns, the motion of
``light_world.hypothesis_light``; ``belief_weights``: one weight per particle). Moving lights
are drawn where they are at the start of the cycle (time 0), as the true field beside them is.
Each particle's field is its lights' summed light at the grid's cell centres, by the law the
environment judges a robot by without a heading (``LightWorld.see``: occlusion, the one-bounce
light where the scenario has it; a heading can only lower a light). The grids
(``BeliefGrid``) are:

- ``likely``: the highest-weight particle's field, 100 where it reaches the detection threshold
  (nav_msgs/OccupancyGrid's lethal value), ``floor(100 * v / threshold)`` below it (0..99):
  the most likely field;
- ``uncertain``: ``round(200 * min(p, 1 - p))``, p the particles' weight that says the cell is
  lit (at or above the threshold): 0 where they all agree (lit or dark), 100 where the weight
  is split evenly; the places the robot has still to find out about.

Cells holding a blocked map cell (walls, unknown) are -1 in both (OccupancyGrid's unknown):
light is not judged where a robot cannot stand. The grid is in the map's frame from the map's
origin, rows from the bottom (as nav2_map_server's), each cell ``factor`` map cells on a side:
about half the lattice step, so a belief stays cheap to draw after every episode on a large map
(the map's own 5 cm cells would cost ~100x the sight lines) while still showing a cone between
two lattice nodes.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from stealth_core.light_world import STATIC, LightWorld, hypothesis_light

LIGHT_COLUMNS = 7  # particle, x, y, direction, fov, beta, range
MOVING_LIGHT_COLUMNS = 12  # and kind, a, b, period_bins, offset (light_world.hypothesis_light)
UNKNOWN = -1
LETHAL = 100


class BeliefArrayError(ValueError):
    """Belief arrays that are not a belief (shape, particle numbers, values); one line."""


@dataclasses.dataclass(frozen=True)
class BeliefGrid:
    """The belief on a map-aligned grid (module docstring); arrays (height, width), row 0 the
    bottom row."""

    resolution: float  # m per cell
    origin: tuple[float, float, float]  # the map's origin (x, y, yaw) of cell (0, 0)'s corner
    likely: np.ndarray  # int8 levels of the most likely field
    uncertain: np.ndarray  # int8 disagreement levels
    likely_field: np.ndarray  # float light of the most likely particle (nan on blocked cells)
    lit_probability: np.ndarray  # float weight of the particles that light the cell (nan)

    @property
    def height(self) -> int:
        return int(self.likely.shape[0])

    @property
    def width(self) -> int:
        return int(self.likely.shape[1])


def check_belief_arrays(lights, weights) -> tuple[np.ndarray, np.ndarray]:
    """(lights (k, 7), weights (particles,)) as float arrays; BeliefArrayError naming what is
    wrong (a saved policy's arrays are read through this too)."""
    lights = np.asarray(lights, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    if lights.ndim != 2 or lights.shape[1] not in (LIGHT_COLUMNS, MOVING_LIGHT_COLUMNS):
        raise BeliefArrayError(
            f'belief lights: expected (lights, {LIGHT_COLUMNS}) rows of particle, x, y, '
            f'direction, fov, beta, range (or {MOVING_LIGHT_COLUMNS}, with kind, a, b, '
            f'period_bins, offset); got shape {lights.shape}'
        )
    if weights.ndim != 1 or weights.size == 0:
        raise BeliefArrayError(f'belief weights: expected one per particle, got {weights.shape}')
    if not (np.all(np.isfinite(lights)) and np.all(np.isfinite(weights))):
        raise BeliefArrayError('belief arrays: expected finite numbers')
    if np.any(weights < 0) or weights.sum() <= 0:
        raise BeliefArrayError('belief weights: expected numbers >= 0 with a positive sum')
    particles = lights[:, 0]
    if np.any((particles < 0) | (particles >= weights.size) | (particles != np.round(particles))):
        raise BeliefArrayError(
            f'belief lights: column particle must number one of the {weights.size} particles'
        )
    return lights, weights / weights.sum()


def belief_rows(lights, particle: int = 0) -> np.ndarray:
    """(lights, 7) belief rows of static Searchlights as one particle: what a belief sure of
    them holds (to draw the true field on the belief's grid)."""
    rows = [
        (particle, s.x, s.y, s.direction, s.fov, (1.0 / s.delta - 1.0) / s.range**2, s.range)
        for s in lights
    ]
    return np.array(rows, dtype=np.float64).reshape(-1, LIGHT_COLUMNS)


def cell_factor(map_resolution: float, step_distance: float) -> int:
    """Map cells per belief cell on a side: the most that keeps a cell within half the
    lattice step (at least 1)."""
    return max(1, math.floor(0.5 * step_distance / map_resolution + 1e-9))


class BeliefMapper:
    """The belief's grids on one ``LightWorld``'s map (the lines of sight traced for a lamp's
    cell are kept between calls, so an episode's belief costs what its new lamps cost)."""

    def __init__(self, world: LightWorld, factor: int | None = None):
        self.world = world
        scenario = world.scenario
        grid = scenario.map
        self.factor = factor or cell_factor(grid.resolution, scenario.step_distance)
        self.resolution = grid.resolution * self.factor
        self.origin = tuple(float(v) for v in grid.origin)
        height, width = grid.height // self.factor, grid.width // self.factor
        rows, cols = np.mgrid[0:height, 0:width]
        centre_rows = rows * self.factor + self.factor // 2
        centre_cols = cols * self.factor + self.factor // 2
        # A belief cell with any blocked map cell is blocked: a thin wall stays drawn, and a
        # robot (its radius) never stands on a cell that touches a wall anyway.
        cells = grid.blocked[: height * self.factor, : width * self.factor]
        self.blocked = cells.reshape(height, self.factor, width, self.factor).any(axis=(1, 3))
        xs = self.origin[0] + (centre_cols + 0.5) * grid.resolution
        ys = self.origin[1] + (centre_rows + 0.5) * grid.resolution
        self._free = ~self.blocked
        self._xs, self._ys = xs[self._free], ys[self._free]
        self.shape = (height, width)

    def particle_fields(self, lights, weights) -> np.ndarray:
        """(particles, free cells): each particle's summed light at the free cells' centres."""
        lights, weights = check_belief_arrays(lights, weights)
        fields = np.zeros((weights.size, self._xs.size))
        timing = self.world.timing
        moving = lights.shape[1] == MOVING_LIGHT_COLUMNS and np.any(lights[:, 7] != STATIC)
        if moving and timing is None:
            raise BeliefArrayError(
                'belief lights: moving lights (column kind) in a world whose lights do not '
                'move (no phase_bins)'
            )
        for particle in range(weights.size):
            rows = lights[lights[:, 0] == particle]
            if len(rows) == 0:
                continue
            hypothesis = [
                hypothesis_light(f'belief-{i}', tuple(row[1:]), timing)
                for i, row in enumerate(rows)
            ]
            fields[particle] = self.world.see(hypothesis).many(self._xs, self._ys)
        return fields

    def grid(self, lights, weights) -> BeliefGrid:
        """The belief's grids (module docstring)."""
        lights, weights = check_belief_arrays(lights, weights)
        fields = self.particle_fields(lights, weights)
        threshold = self.world.threshold
        best = int(np.argmax(weights))
        lit = np.sum(weights[:, None] * (fields >= threshold), axis=0)
        likely_field = self._spread(fields[best])
        lit_probability = self._spread(np.clip(lit, 0.0, 1.0))
        below = np.minimum(np.floor(100.0 * likely_field / threshold), LETHAL - 1)
        likely = _levels(np.where(likely_field >= threshold, LETHAL, below))
        uncertain = _levels(np.round(200.0 * np.minimum(lit_probability, 1 - lit_probability)))
        return BeliefGrid(
            self.resolution, self.origin, likely, uncertain, likely_field, lit_probability
        )

    def _spread(self, free_values: np.ndarray) -> np.ndarray:
        """Free cells' values on the whole grid, nan on the blocked ones."""
        values = np.full(self.shape, np.nan)
        values[self._free] = free_values
        return values


def _levels(values: np.ndarray) -> np.ndarray:
    """int8 OccupancyGrid values: the numbers given, -1 where nan (blocked)."""
    levels = np.full(values.shape, UNKNOWN, dtype=np.int8)
    known = np.isfinite(values)
    levels[known] = np.clip(values[known], 0, LETHAL).astype(np.int8)
    return levels
