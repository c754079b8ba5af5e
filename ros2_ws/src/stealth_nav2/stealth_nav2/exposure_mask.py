"""The exposure mask for Nav2's keepout filter: the light on every cell of the map, at a time,
turned into nav_msgs/OccupancyGrid values (plain Python + numpy, no rclpy).

Values (``mask_levels``), read by ``nav2_costmap_2d::KeepoutFilter`` as cost ``round(v * 254 /
100)``:

- **100** (lethal, cost 254): the summed light at the cell is at or above the scenario's
  detection threshold, the environment's own rule (``reward.is_detected``, 'threshold' mode; in
  'probabilistic' mode the threshold is where detection is even odds);
- **1..99** (costs 3..251): the graded band, light above ``band_start * threshold`` and below
  the threshold, ``1 + floor(99 * (v - low) / (threshold - low))``: monotonic in the light, 99
  just under the threshold;
- **0**: dark, at or below the band's start;
- **-1** (unknown: the keepout filter leaves the costmap's cell as it is) on the map's blocked
  cells (occupied and unknown): walls are the static layer's business, and light is not judged
  there (a robot cannot stand in a wall).

The light is the environment's model, not a second one: the value at a cell centre equals
``lighting.point_visibility`` there (what ``StealthTask`` judges a robot at that point by,
without a heading: a heading can only lower a light, ``stealth_core.exposure``), to the last bit,
lights added in their order. Static lights come from ``visibility_cache.cached_visibility_field``
(computed once, on disk, with the scenario's bounce if any). A moving light is asked of a
``visibility.PointVisibility`` of its own, at the cell centres within its range at time t: its
per-lamp-cell sight memo keeps every line of sight traced once (a sweeping lamp's cell never
changes; a patrolling lamp's cells are remembered, up to a memory budget), so an update only
computes the intensities in the light's window and traces the cells it has never lit.
"""

from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np
from stealth_core.bounce import Bounce, check_static
from stealth_core.lighting import GridFrame
from stealth_core.searchlight import PatrolMotion, Searchlight
from stealth_core.visibility import PointVisibility
from stealth_core.visibility_cache import cached_visibility_field

LETHAL = 100  # nav_msgs/OccupancyGrid's top value: KeepoutFilter's LETHAL_OBSTACLE (254)
BAND_TOP = 99  # the graded band's highest value, just under the threshold
UNKNOWN = -1  # KeepoutFilter's NO_INFORMATION: the cell is left as the other layers made it
DEFAULT_BAND_START = 0.5  # the band starts at half the detection threshold
SIGHT_MEMORY = 128 * 2**20  # bytes of lamp-cell sight memos per moving light (int8 per cell)
MIN_LAMP_CELLS = 64  # lamp cells remembered per moving light, whatever the map's size


def check_band_start(band_start: float) -> float:
    """band_start as a float; ValueError unless it is a number in [0, 1]."""
    value = float(band_start)
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise ValueError(
            f'band_start: expected a fraction of the detection threshold in [0, 1], got '
            f'{band_start!r}'
        )
    return value


def mask_levels(
    total: np.ndarray, blocked: np.ndarray, threshold: float, band_start: float
) -> np.ndarray:
    """int8 mask values (rows from the bottom, as the map's) of a light field ``total`` (see
    the module docstring); ValueError for a threshold that is not a finite number > 0, a
    band_start outside [0, 1], or a field that is not finite or not the map's shape."""
    threshold = float(threshold)
    if not (math.isfinite(threshold) and threshold > 0.0):
        raise ValueError(f'detection threshold: expected a finite number > 0, got {threshold}')
    band_start = check_band_start(band_start)
    total = np.asarray(total, dtype=np.float64)
    if total.shape != blocked.shape or not np.all(np.isfinite(total)):
        raise ValueError(
            f"light field: expected finite numbers of the map's shape {blocked.shape}, got "
            f'shape {total.shape}'
        )
    low = band_start * threshold
    levels = np.zeros(total.shape, dtype=np.int8)
    band = (total > low) & (total < threshold)
    fraction = (total[band] - low) / (threshold - low)  # in (0, 1)
    levels[band] = np.minimum(1 + np.floor(BAND_TOP * fraction), BAND_TOP).astype(np.int8)
    levels[total >= threshold] = LETHAL  # detected: reward.is_detected's 'threshold' rule
    levels[blocked] = UNKNOWN
    return levels


class LightField:
    """The summed light on every cell of one map at any time t (s), for a fixed set of lights;
    equal to ``lighting.point_visibility`` at each cell centre (see the module docstring).

    bounce: the scenario's one-bounce light (static lights only: refused with moving ones, as
    the scenario and ``visibility`` refuse it); cache_dir: the static field's disk cache
    (``visibility.cache_directory``'s default when None).
    """

    def __init__(
        self,
        blocked: np.ndarray,
        resolution: float,
        origin: Sequence[float],
        lights: Sequence[Searchlight],
        bounce: Bounce | None = None,
        cache_dir=None,
    ):
        self.frame = GridFrame.of(blocked, resolution, origin)
        self.blocked = blocked
        self.lights = tuple(lights)
        self.moving = any(light.is_moving for light in self.lights)
        for light in self.lights:  # a lamp off the map: refused now, not at some update
            route = light.motion.waypoints if isinstance(light.motion, PatrolMotion) else ()
            for x, y in ((light.x, light.y), *route):  # the map is convex: the route is inside
                self.frame.cell_of(x, y, what=f'searchlight {light.name!r}')
        if bounce is not None and bounce.albedo > 0.0:
            check_static(self.lights)
        static = [light for light in self.lights if not light.is_moving]
        total, per_light = cached_visibility_field(
            blocked, resolution, origin, static, 0.0, cache_dir, bounce=bounce
        )
        # The field is the lights added in their order, as the reference adds them: the static
        # lights before the first moving one are one precomputed sum (the reference's 0.0 + a
        # + b ... too); every later light is added in turn at each update.
        leading = 0
        while leading < len(self.lights) and not self.lights[leading].is_moving:
            leading += 1
        if self.moving:
            total = np.zeros(blocked.shape)
            for layer in per_light[:leading]:
                total += layer
        self._prefix = total  # all of it (and the bounce) when no light moves
        static_layers = iter(per_light[leading:])
        memo_lamps = max(MIN_LAMP_CELLS, SIGHT_MEMORY // max(blocked.size, 1))
        self._rest: list[tuple[Searchlight, object]] = []
        for light in self.lights[leading:]:
            if light.is_moving:
                points = PointVisibility(blocked, resolution, origin, (light,),
                                         max_lamps=memo_lamps)  # fmt: skip
                self._rest.append((light, points))
            else:
                self._rest.append((light, next(static_layers)))
        self._centres = self.frame.cell_centre(
            np.arange(self.frame.width), np.arange(self.frame.height)
        )

    def at(self, t: float = 0.0) -> np.ndarray:
        """(height, width): the summed light on each cell at time t (s); a fresh array."""
        total = self._prefix.copy()
        for light, source in self._rest:
            if isinstance(source, np.ndarray):
                total += source
                continue
            cols, rows = self._window(light.at(t))
            xs, ys = np.meshgrid(self._centres[0][cols], self._centres[1][rows])
            total[rows, cols] += source.many(xs, ys, t)  # 0 beyond its range: adds nothing
        return total

    def _window(self, light: Searchlight) -> tuple[slice, slice]:
        """Column and row slices of the cells whose centres can be within the light's range."""
        frame = self.frame
        reach = int(np.ceil(light.range / frame.resolution)) + 1
        col, row = frame.cell_of(light.x, light.y, what=f'searchlight {light.name!r}')
        return (
            slice(max(col - reach, 0), min(col + reach + 1, frame.width)),
            slice(max(row - reach, 0), min(row + reach + 1, frame.height)),
        )


class ExposureMask:
    """Mask values of one map, its lights and detection threshold at any time (see the module
    docstring); ``of_scenario`` builds it from a ``stealth_core.scenario.Scenario``."""

    def __init__(
        self,
        blocked: np.ndarray,
        resolution: float,
        origin: Sequence[float],
        lights: Sequence[Searchlight],
        detection_threshold: float,
        band_start: float = DEFAULT_BAND_START,
        bounce: Bounce | None = None,
        cache_dir=None,
    ):
        self.field = LightField(blocked, resolution, origin, lights, bounce, cache_dir)
        self.threshold = float(detection_threshold)
        self.band_start = check_band_start(band_start)
        mask_levels(np.zeros(blocked.shape), blocked, self.threshold, self.band_start)  # checks

    @classmethod
    def of_scenario(cls, scenario, band_start: float = DEFAULT_BAND_START, cache_dir=None):
        occupancy = scenario.map
        return cls(
            occupancy.blocked,
            occupancy.resolution,
            occupancy.origin,
            scenario.lights,
            scenario.detection_threshold,
            band_start,
            bounce=scenario.bounce,
            cache_dir=cache_dir,
        )

    @property
    def moving(self) -> bool:
        """Whether the mask changes with time (some light moves)."""
        return self.field.moving

    def at(self, t: float = 0.0) -> np.ndarray:
        """(height, width) int8 mask values at time t (s)."""
        return mask_levels(self.field.at(t), self.field.blocked, self.threshold, self.band_start)
