"""Localisation from noisy odometry and laser scans: a particle filter run the way AMCL runs one.

* Motion: every particle moves by the odometry's motion perturbed with AMCL's diff-drive model
  (``odometry_noise``), with the filter's own alphas.
* Sensor: AMCL's default likelihood-field model (nav2_amcl ``LikelihoodFieldModel``): each beam
  endpoint scores ``pz = z_hit exp(-d^2 / 2 sigma_hit^2) + z_rand / range_max``, ``d`` the
  distance from the endpoint to the nearest obstacle (``max_occ_dist`` off the map or beyond),
  beams at max range skipped, and a particle's weight multiplied by ``1 + sum(pz^3)``, AMCL's
  ad-hoc combination. Obstacles are the blocked cells (occupied or unknown), since the simulated
  laser is stopped by both; AMCL counts occupied cells only.
* Resampling: systematic (low-variance) every ``resample_interval`` updates, with a fixed
  particle count instead of AMCL's KLD-adaptive one.
* Schedule (:class:`Localiser`): a filter update whenever the odometry has moved
  ``update_min_d`` or turned ``update_min_a`` since the last; in between, the estimate follows the
  odometry from the last update (map -> odom stays fixed, as AMCL's transform does).

The estimate is the weighted mean (circular for yaw) and its covariance the weighted spread of the
particles, so it is as wide as the filter's belief.
"""

import dataclasses
import math

import cv2
import numpy as np
from stealth_core.kinematics import Pose, compose, relative, wrap_angle
from stealth_core.occupancy_map import OccupancyMap

from stealth_sim.odometry_noise import (
    MotionDelta,
    MotionNoise,
    apply_noisy_motion,
    decompose,
    noise_stddevs,
)


@dataclasses.dataclass(frozen=True)
class LikelihoodModel:
    """AMCL's likelihood-field parameters, with nav2's defaults."""

    z_hit: float = 0.5
    z_rand: float = 0.5
    sigma_hit: float = 0.2  # m
    max_occ_dist: float = 2.0  # m (laser_likelihood_max_dist)
    max_beams: int = 60


@dataclasses.dataclass(frozen=True)
class FilterConfig:
    """Particle count and AMCL's update schedule (m, rad; nav2's defaults)."""

    particles: int = 500
    update_min_d: float = 0.25
    update_min_a: float = 0.2
    resample_interval: int = 1
    likelihood: LikelihoodModel = LikelihoodModel()

    def __post_init__(self):
        if not (isinstance(self.particles, int) and self.particles >= 1):
            raise ValueError(f'particles: expected an integer >= 1, got {self.particles!r}')


class LikelihoodField:
    """AMCL's per-beam score ``pz^3`` at every cell, precomputed for one laser range_max.

    ``pz`` depends on the endpoint only through its cell's distance to the nearest blocked cell
    (centre to centre, clamped at ``max_occ_dist``, as AMCL's cspace), so the whole model is a
    lookup. A ring of ``max_occ_dist`` cells around the map scores endpoints off the map.
    """

    def __init__(self, occupancy_map: OccupancyMap, model: LikelihoodModel, range_max: float):
        free = (~occupancy_map.blocked).astype(np.uint8)
        cells = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        distance = np.minimum(cells * occupancy_map.resolution, model.max_occ_dist)
        distance = np.pad(distance, 1, constant_values=model.max_occ_dist)
        pz = model.z_hit * np.exp(-(distance * distance) / (2.0 * model.sigma_hit**2))
        pz += model.z_rand / range_max
        self.score = (pz * pz * pz).astype(np.float64)
        self.distance = distance
        self.range_max = range_max
        self.inverse_resolution = 1.0 / occupancy_map.resolution
        self.origin_x, self.origin_y = occupancy_map.origin[:2]
        self._flat_score = self.score.ravel()

    def to_grid(self, x, y):
        """Continuous padded-grid coordinates (col, row) of points (m), +1 for the ring."""
        inverse = self.inverse_resolution
        return (x - self.origin_x) * inverse + 1.0, (y - self.origin_y) * inverse + 1.0

    def _flat_cells(self, cols: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Flat index of the cells at padded-grid coordinates; off the map is the ring."""
        height, width = self.score.shape
        # Clipping before the cast makes truncation act as floor.
        cols = np.clip(cols, 0.0, width - 1).astype(np.intp)
        rows = np.clip(rows, 0.0, height - 1).astype(np.intp)
        rows *= width
        rows += cols
        return rows

    def lookup(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance (m) from each point to the nearest obstacle; ``max_occ_dist`` off the map."""
        return self.distance.ravel()[self._flat_cells(*self.to_grid(x, y))]

    def scores(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``pz^3`` of beam endpoints at the given points."""
        return self.grid_scores(*self.to_grid(x, y))

    def grid_scores(self, cols: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """``pz^3`` of beam endpoints at padded-grid coordinates (see :meth:`to_grid`)."""
        return self._flat_score[self._flat_cells(cols, rows)]


def covariance_from_spread(poses: np.ndarray, weights: np.ndarray) -> tuple[Pose, np.ndarray]:
    """Weighted mean pose (circular mean of yaw) and the 3x3 covariance of (x, y, yaw)."""
    x_mean, y_mean, _ = (weights @ poses).tolist()
    heading = weights @ np.exp(1j * poses[:, 2])
    yaw_mean = math.atan2(heading.imag, heading.real)
    deviations = poses - (x_mean, y_mean, yaw_mean)
    deviations[:, 2] = wrap_angle(deviations[:, 2])
    covariance = (deviations.T * weights) @ deviations
    return Pose(x_mean, y_mean, yaw_mean), covariance


def validate_covariance(covariance) -> np.ndarray:
    """A 3x3 symmetric positive semi-definite matrix of finite numbers, or ValueError."""
    matrix = np.asarray(covariance, dtype=float)
    if matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)):
        raise ValueError('covariance: expected a finite 3x3 matrix over (x, y, yaw)')
    if not np.allclose(matrix, matrix.T, atol=1e-12):
        raise ValueError('covariance: expected a symmetric matrix')
    if np.linalg.eigvalsh(matrix).min() < -1e-12:
        raise ValueError('covariance: expected a positive semi-definite matrix')
    return matrix


class ParticleFilter:
    """Particles (N, 3) of (x, y, yaw) with normalised weights."""

    def __init__(
        self,
        field: LikelihoodField,
        config: FilterConfig,
        motion_noise: MotionNoise,
        rng: np.random.Generator,
    ):
        self.field = field
        self.config = config
        self.motion_noise = motion_noise
        self.rng = rng
        count = config.particles
        self.particles = np.zeros((count, 3))
        self.weights = np.full(count, 1.0 / count)

    def initialise(self, mean: Pose, covariance) -> None:
        """Draw the particles from a Gaussian around ``mean``, as AMCL's pf_init does."""
        covariance = validate_covariance(covariance)
        count = self.config.particles
        # Eigen-decomposition rather than Cholesky: a zero variance is allowed.
        values, vectors = np.linalg.eigh(covariance)
        scale = vectors * np.sqrt(np.maximum(values, 0.0))
        draws = self.rng.standard_normal((count, 3)) @ scale.T
        self.particles = np.column_stack(
            [mean.x + draws[:, 0], mean.y + draws[:, 1], wrap_angle(mean.yaw + draws[:, 2])]
        )
        self.weights = np.full(count, 1.0 / count)

    def predict(self, delta: MotionDelta) -> None:
        """Move every particle by the odometry's motion with sampled AMCL noise."""
        stddevs = noise_stddevs(delta, self.motion_noise)
        normals = self.rng.standard_normal(self.particles.shape)
        moved = np.empty_like(self.particles)
        moved[:, 0], moved[:, 1], moved[:, 2] = apply_noisy_motion(
            *self.particles.T, delta, stddevs, normals
        )
        self.particles = moved

    def correct(self, ranges: np.ndarray, bearings: np.ndarray) -> None:
        """Weigh the particles by AMCL's likelihood-field model of one scan."""
        range_max = self.field.range_max
        usable = np.isfinite(ranges) & (ranges < range_max)
        ranges, bearings = ranges[usable], bearings[usable]
        if ranges.size == 0:
            return
        # Endpoints as complex grid coordinates col + i row: the beams in the robot frame (in
        # cells) turned into every particle's frame by one outer product (no trig per pair).
        poses, field = self.particles, self.field
        cols, rows = field.to_grid(poses[:, 0], poses[:, 1])
        beams = (ranges * field.inverse_resolution) * np.exp(1j * bearings)
        ends = np.multiply.outer(np.exp(1j * poses[:, 2]), beams)
        ends += (cols + 1j * rows)[:, None]
        scores = field.grid_scores(ends.real, ends.imag)
        weights = self.weights * (1.0 + scores.sum(axis=1))
        self.weights = weights / weights.sum()

    def resample(self) -> None:
        """Systematic resampling: one uniform draw, N evenly spaced pointers into the weights."""
        count = len(self.weights)
        pointers = (self.rng.random() + np.arange(count)) / count
        cumulative = np.cumsum(self.weights)
        cumulative[-1] = 1.0
        self.particles = self.particles[np.searchsorted(cumulative, pointers)]
        self.weights = np.full(count, 1.0 / count)

    def estimate(self) -> tuple[Pose, np.ndarray]:
        return covariance_from_spread(self.particles, self.weights)


class Localiser:
    """AMCL's loop around the filter: when to update, and the estimate between updates."""

    def __init__(self, particle_filter: ParticleFilter):
        self.filter = particle_filter
        self.config = particle_filter.config
        self.updates = 0
        self._odom_at_update = Pose(0.0, 0.0, 0.0)
        self._estimate_at_update = Pose(0.0, 0.0, 0.0)
        self.covariance = np.zeros((3, 3))

    def initialise(self, pose: Pose, covariance, odom_pose: Pose) -> None:
        """Restart the filter around ``pose`` (what an /initialpose does)."""
        self.filter.initialise(pose, covariance)
        self._odom_at_update = odom_pose
        self._estimate_at_update, self.covariance = self.filter.estimate()

    def moved_enough(self, odom_pose: Pose) -> bool:
        forward, left, turn = relative(self._odom_at_update, odom_pose)
        return (
            math.hypot(forward, left) >= self.config.update_min_d
            or abs(turn) >= self.config.update_min_a
        )

    def has_moved(self, odom_pose: Pose) -> bool:
        return odom_pose != self._odom_at_update

    def update(self, odom_pose: Pose, ranges: np.ndarray, bearings: np.ndarray) -> None:
        """One filter update: predict with the odometry since the last update, weigh, resample."""
        self.filter.predict(decompose(self._odom_at_update, odom_pose))
        self.filter.correct(ranges, bearings)
        self._estimate_at_update, self.covariance = self.filter.estimate()
        self.updates += 1
        if self.updates % self.config.resample_interval == 0:
            self.filter.resample()
        self._odom_at_update = odom_pose

    def estimate(self, odom_pose: Pose) -> Pose:
        """The last update's estimate carried forward by the odometry since."""
        return compose(self._estimate_at_update, *relative(self._odom_at_update, odom_pose))
