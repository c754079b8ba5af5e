"""A simulated planar laser: rays cast on the occupancy grid, vectorised over beams.

Beams stop at the first blocked cell (occupied or unknown: the simulator treats unknown space as
solid, and the map's outside is unknown). Each ray is sampled every quarter cell; the first
blocked sample names the cell hit, and the range is the exact distance at which the ray enters
that cell's square. Only a corner clipped by less than a quarter cell between two samples can be
missed. A beam that hits nothing within ``range_max`` reads +inf, as REP 117 asks.

Two marches give the same samples, so the same ranges: a few beams are traced one by one in
plain Python, skipping the samples that a clearance map proves free (numpy's per-call overhead
would dominate), and many beams are marched together in numpy chunks.
"""

import dataclasses
import functools
import math

import cv2
import numpy as np
from stealth_core.occupancy_map import OccupancyMap

SAMPLES_PER_CELL = 4
CHUNK_SAMPLES = 128  # samples per beam marched at a time (1.6 m at 0.05 m cells)
# Up to this many beams (left), tracing each in Python beats the numpy march (on simple-maze).
TRACED_BEAMS = 24


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
        self._steps = (self.distances / self.resolution).tolist()

    @functools.cached_property
    def _free_samples(self) -> bytes:
        """Per quarter-cell square (row-major, SAMPLES_PER_CELL times the grid): 0 when its cell is
        blocked, else 1 + how many following samples are certainly free (at most 254).

        A sample's next ``s`` samples lie within ``s`` quarter cells of it, so they are free while
        ``s`` is below the distance from its square to the nearest blocked square. Between squares
        of a lattice that distance is the Euclidean distance transform to the blocked squares
        grown by one square (a 3x3 dilation).
        """
        scale = SAMPLES_PER_CELL
        blocked = np.repeat(np.repeat(self.blocked, scale, axis=0), scale, axis=1)
        grown = cv2.dilate(blocked.astype(np.uint8), np.ones((3, 3), np.uint8))
        distance = cv2.distanceTransform(1 - grown, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        # Strictly closer than the distance, with a margin for float32 (values above 254 are
        # capped, and below 256 float32 resolves far finer than the margin).
        values = np.clip(np.ceil(distance - 1e-3), 1.0, 255.0).astype(np.uint8)
        values[blocked] = 0
        return values.tobytes()

    def cast(self, x: float, y: float, yaw: float, bearings: np.ndarray) -> np.ndarray:
        """Noise-free ranges (m) from (x, y) along ``yaw + bearings``; +inf beyond range_max."""
        angles = yaw + np.asarray(bearings, dtype=float)
        cos_a, sin_a = np.cos(angles), np.sin(angles)
        starts_free = self._starts_free(x, y)
        if starts_free and len(angles) <= TRACED_BEAMS:
            return np.array(self._trace(x, y, cos_a, sin_a))
        # Many beams: numpy chunks end most of them; the few long ones left are traced on.
        handover = TRACED_BEAMS if starts_free else 0
        hit_col, hit_row, has_hit, active, marched = self._march(x, y, cos_a, sin_a, handover)
        res = self.resolution
        left = self.origin_x + (hit_col - 1) * res
        bottom = self.origin_y + (hit_row - 1) * res
        ranges = np.maximum(ray_entry(x, y, cos_a, sin_a, left, bottom, res), 0.0)
        ranges = np.where(has_hit & (ranges <= self.range_max), ranges, np.inf)
        if active.size:
            ranges[active] = self._trace(x, y, cos_a[active], sin_a[active], marched)
        return ranges

    def _start(self, x: float, y: float) -> tuple[float, float]:
        """Continuous padded-grid (col, row) of the start (+1 for the ring)."""
        res = self.resolution
        return (x - self.origin_x) / res + 1.0, (y - self.origin_y) / res + 1.0

    def _starts_free(self, x: float, y: float) -> bool:
        """Whether (x, y) lies in a free cell of the grid (the robot always does)."""
        col, row = self._start(x, y)
        height, width = self.blocked.shape
        return 0.0 <= col < width and 0.0 <= row < height and not self.blocked[int(row), int(col)]

    def _trace(self, x, y, cos_a, sin_a, first: int = 0) -> list[float]:
        """Each beam alone in plain Python, sample by sample, jumping over samples proven free.

        Every sample looked at is :meth:`_march`'s, scaled by a power of two (exact), and lies
        in a blocked cell exactly when :meth:`_march` finds it so; the range is
        :func:`ray_entry`'s arithmetic on floats: the ranges are the same. From a free start no
        sample gets past the ring of blocked cells (a skip never crosses a blocked cell), so no
        clipping is needed. Samples before ``first`` are known to be free.
        """
        steps, last, free_samples = self._steps, len(self._steps), self._free_samples
        scale, res, range_max = SAMPLES_PER_CELL, self.resolution, self.range_max
        row_stride = self.blocked.shape[1] * scale
        start_col, start_row = self._start(x, y)
        start_col, start_row = start_col * scale, start_row * scale
        ranges = []
        for cos_b, sin_b in zip(cos_a.tolist(), sin_a.tolist(), strict=True):
            cos_s, sin_s = cos_b * scale, sin_b * scale
            k = first
            while k < last:
                col = int(start_col + cos_s * steps[k])
                row = int(start_row + sin_s * steps[k])
                free_after = free_samples[row * row_stride + col]
                if free_after == 0:
                    break
                k += free_after
            else:
                ranges.append(math.inf)
                continue
            left = self.origin_x + (col // scale - 1) * res
            bottom = self.origin_y + (row // scale - 1) * res
            t_x = min((left - x) / cos_b, (left + res - x) / cos_b) if cos_b else -math.inf
            t_y = min((bottom - y) / sin_b, (bottom + res - y) / sin_b) if sin_b else -math.inf
            entry = max(t_x, t_y, 0.0)
            ranges.append(entry if entry <= range_max else math.inf)
        return ranges

    def _march(self, x, y, cos_a, sin_a, handover: int = 0):
        """All beams together, a chunk of samples at a time; only beams without a hit go on
        (indoors most beams end in the first metres), until ``handover`` or fewer are left.

        Returns the hit cells, which beams hit, the beams still going and the samples marched.
        """
        res = self.resolution
        height, width = self.blocked.shape
        start_col, start_row = self._start(x, y)
        hit_col = np.zeros(len(cos_a), dtype=np.intp)
        hit_row = np.zeros(len(cos_a), dtype=np.intp)
        has_hit = np.zeros(len(cos_a), dtype=bool)
        active = np.arange(len(cos_a))
        marched = 0
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
            marched = begin + len(steps)
            if active.size <= handover:
                break
        return hit_col, hit_row, has_hit, active, marched


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
