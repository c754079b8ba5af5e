"""A simulated planar laser: rays cast on the occupancy grid, vectorised over beams.

Beams stop at the first blocked cell (occupied or unknown: the simulator treats unknown space as
solid, and the map's outside is unknown). Each ray is sampled every quarter cell; the first
blocked sample names the cell hit, and the range is the exact distance at which the ray enters
that cell's square. Only a corner clipped by less than a quarter cell between two samples can be
missed. A beam that hits nothing within ``range_max`` reads +inf, as REP 117 asks.
"""

import dataclasses
import math

import numpy as np

from stealth_sim.occupancy_map import OccupancyMap

SAMPLES_PER_CELL = 4
CHUNK_SAMPLES = 128  # samples per beam marched at a time (1.6 m at 0.05 m cells)


@dataclasses.dataclass(frozen=True)
class LaserConfig:
    """Beam count, range limits (m), Gaussian range noise (m) and field of view (rad)."""

    beams: int = 180
    range_max: float = 12.0
    range_min: float = 0.05
    noise_std: float = 0.01
    field_of_view: float = 2.0 * math.pi

    def __post_init__(self):
        if not (isinstance(self.beams, int) and self.beams >= 1):
            raise ValueError(f'laser_beams: expected an integer >= 1, got {self.beams!r}')
        checks = (
            ('laser_range', self.range_max, self.range_max > 0),
            ('laser_range_min', self.range_min, 0 <= self.range_min < self.range_max),
            ('laser_noise', self.noise_std, self.noise_std >= 0),
            ('laser_field_of_view', self.field_of_view, 0 < self.field_of_view <= 2 * math.pi),
        )
        for name, value, valid in checks:
            if not (math.isfinite(value) and valid):
                raise ValueError(f'{name}: out of range, got {value!r}')

    @property
    def angle_min(self) -> float:
        return -0.5 * self.field_of_view

    @property
    def angle_increment(self) -> float:
        """A full circle has no duplicate last beam; a partial fan spans both edges."""
        if self.field_of_view >= 2.0 * math.pi or self.beams == 1:
            return self.field_of_view / self.beams
        return self.field_of_view / (self.beams - 1)

    @property
    def angle_max(self) -> float:
        return self.angle_min + (self.beams - 1) * self.angle_increment

    def bearings(self, indices=None) -> np.ndarray:
        """Beam angles (rad, robot frame), all or those of the given beam indices."""
        if indices is None:
            indices = np.arange(self.beams)
        return self.angle_min + np.asarray(indices, dtype=float) * self.angle_increment


class RayCaster:
    """Exact-entry ray casting against a map's blocked cells."""

    def __init__(self, occupancy_map: OccupancyMap, range_max: float):
        # A ring of blocked cells: off the map is unknown, and unknown stops the beam.
        self.blocked = np.pad(occupancy_map.blocked, 1, constant_values=True)
        self.resolution = occupancy_map.resolution
        self.origin_x, self.origin_y = occupancy_map.origin[:2]
        self.range_max = float(range_max)
        step = self.resolution / SAMPLES_PER_CELL
        self.distances = np.arange(1, math.ceil(self.range_max / step) + 2) * step

    def cast(self, x: float, y: float, yaw: float, bearings: np.ndarray) -> np.ndarray:
        """Noise-free ranges (m) from (x, y) along ``yaw + bearings``; +inf beyond range_max.

        The rays are marched a chunk of samples at a time, and only the beams that have hit
        nothing yet go on: indoors most beams end in the first metres.
        """
        angles = yaw + np.asarray(bearings, dtype=float)
        cos_a, sin_a = np.cos(angles), np.sin(angles)
        res = self.resolution
        height, width = self.blocked.shape
        # Continuous padded-grid coordinates of the start (+1 for the ring).
        start_col = (x - self.origin_x) / res + 1.0
        start_row = (y - self.origin_y) / res + 1.0
        hit_col = np.zeros(len(angles), dtype=np.intp)
        hit_row = np.zeros(len(angles), dtype=np.intp)
        has_hit = np.zeros(len(angles), dtype=bool)
        active = np.arange(len(angles))
        for begin in range(0, len(self.distances), CHUNK_SAMPLES):
            steps = self.distances[begin : begin + CHUNK_SAMPLES] / res
            # Clipping before the cast makes truncation act as floor.
            cols = np.clip(start_col + np.outer(cos_a[active], steps), 0, width - 1)
            rows = np.clip(start_row + np.outer(sin_a[active], steps), 0, height - 1)
            cols, rows = cols.astype(np.intp), rows.astype(np.intp)
            hit = self.blocked[rows, cols]
            first = np.argmax(hit, axis=1)
            done = hit[np.arange(len(active)), first]
            beams = active[done]
            hit_col[beams] = cols[done, first[done]]
            hit_row[beams] = rows[done, first[done]]
            has_hit[beams] = True
            active = active[~done]
            if active.size == 0:
                break
        left = self.origin_x + (hit_col - 1) * res
        bottom = self.origin_y + (hit_row - 1) * res
        ranges = np.maximum(ray_entry(x, y, cos_a, sin_a, left, bottom, res), 0.0)
        return np.where(has_hit & (ranges <= self.range_max), ranges, np.inf)


def ray_entry(x, y, cos_a, sin_a, left, bottom, side) -> np.ndarray:
    """Distance along each ray (x, y) + t (cos_a, sin_a) at which it enters its square."""
    with np.errstate(divide='ignore', invalid='ignore'):
        t_x = np.minimum((left - x) / cos_a, (left + side - x) / cos_a)
        t_y = np.minimum((bottom - y) / sin_a, (bottom + side - y) / sin_a)
    # A ray parallel to an axis never crosses that axis' slab boundaries: no constraint.
    t_x = np.where(cos_a == 0.0, -np.inf, t_x)
    t_y = np.where(sin_a == 0.0, -np.inf, t_y)
    return np.maximum(t_x, t_y)


def noisy_ranges(
    true_ranges: np.ndarray, config: LaserConfig, rng: np.random.Generator
) -> np.ndarray:
    """Readings of a real laser: Gaussian noise on each return, clamped to [range_min, inf).

    Readings at or beyond range_max are +inf (no return).
    """
    noisy = true_ranges + rng.normal(0.0, config.noise_std, true_ranges.shape)
    noisy = np.maximum(noisy, config.range_min)
    return np.where(np.isfinite(true_ranges) & (noisy < config.range_max), noisy, np.inf)
