"""The particle filter's parts: initialisation, motion, likelihood field, resampling, estimate."""

import math

import numpy as np
import pytest
from sim_test_maps import as_map, maze_map, room
from stealth_core.kinematics import Pose
from stealth_sim.laser import LaserConfig, RayCaster
from stealth_sim.localisation import (
    FilterConfig,
    LikelihoodField,
    LikelihoodModel,
    Localiser,
    ParticleFilter,
    covariance_from_spread,
    validate_covariance,
)
from stealth_sim.odometry_noise import MotionDelta, MotionNoise

MODEL = LikelihoodModel()
DEFAULT_NOISE = MotionNoise()


def make_filter(occupancy_map=None, particles=500, noise=DEFAULT_NOISE, seed=0, range_max=8.0):
    occupancy_map = occupancy_map or maze_map()
    field = LikelihoodField(occupancy_map, MODEL, range_max)
    config = FilterConfig(particles=particles)
    return ParticleFilter(field, config, noise, np.random.default_rng(seed))


def test_initialisation_draws_the_requested_gaussian():
    particle_filter = make_filter(particles=40_000)
    covariance = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.005], [0.0, 0.005, 0.01]])
    particle_filter.initialise(Pose(3.0, 4.0, 3.1), covariance)
    mean, spread = particle_filter.estimate()
    assert mean.x == pytest.approx(3.0, abs=0.005) and mean.y == pytest.approx(4.0, abs=0.005)
    assert abs(math.remainder(mean.yaw - 3.1, 2 * math.pi)) < 0.003
    assert spread == pytest.approx(covariance, abs=0.003)


def test_covariance_from_spread_wraps_yaw_around_pi():
    poses = np.array([[0.0, 0.0, math.pi - 0.1], [2.0, 0.0, -math.pi + 0.1]])
    mean, covariance = covariance_from_spread(poses, np.array([0.5, 0.5]))
    assert (mean.x, mean.y) == (1.0, 0.0) and abs(abs(mean.yaw) - math.pi) < 1e-12
    assert covariance == pytest.approx(np.array([[1, 0, 0.1], [0, 0, 0], [0.1, 0, 0.01]]))


@pytest.mark.parametrize(
    'matrix',
    [
        np.eye(2),
        np.diag([1.0, -1.0, 1.0]),
        [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]],
        np.full((3, 3), np.nan),
    ],
)
def test_invalid_covariances_are_rejected(matrix):
    with pytest.raises(ValueError, match='covariance'):
        validate_covariance(matrix)


def test_a_zero_variance_is_allowed():
    particle_filter = make_filter()
    particle_filter.initialise(Pose(1.0, 1.0, 0.0), np.diag([0.01, 0.0, 0.0]))
    assert np.all(particle_filter.particles[:, 1] == 1.0)


def test_prediction_without_noise_moves_every_particle_in_its_own_frame():
    particle_filter = make_filter(noise=MotionNoise(0, 0, 0, 0), particles=50)
    particle_filter.initialise(Pose(5.0, 5.0, 0.0), np.diag([0.1, 0.1, 1.0]))
    before = particle_filter.particles.copy()
    particle_filter.predict(MotionDelta(0.5, 1.0, -0.2))
    after = particle_filter.particles
    assert after[:, 0] == pytest.approx(before[:, 0] + np.cos(before[:, 2] + 0.5))
    assert after[:, 1] == pytest.approx(before[:, 1] + np.sin(before[:, 2] + 0.5))
    turned = np.remainder(after[:, 2] - before[:, 2] - 0.3 + math.pi, 2 * math.pi) - math.pi
    assert np.abs(turned) == pytest.approx(0.0, abs=1e-12)


def test_likelihood_field_is_the_distance_to_the_nearest_blocked_cell_clamped():
    data = room(100, 100)
    field = LikelihoodField(as_map(data), MODEL, 8.0)
    # Cell centres at 0.075 and 2.475 from the left wall's centre 0.025: 0.05 and 2.45 m.
    distances = field.lookup(np.array([0.075, 2.475, 2.475, -3.0]), np.array([2.5, 2.5, 0.075, 0]))
    assert distances == pytest.approx([0.05, MODEL.max_occ_dist, 0.05, MODEL.max_occ_dist])
    score = field.scores(np.array([0.025]), np.array([2.5]))[0]  # on the wall
    assert score == pytest.approx((MODEL.z_hit + MODEL.z_rand / 8.0) ** 3)


def test_the_true_pose_outweighs_displaced_ones():
    occupancy_map = maze_map()
    particle_filter = make_filter(occupancy_map, particles=5)
    true_pose = Pose(3.0, 2.0, 0.4)
    offsets = [(0, 0, 0), (0.2, 0, 0), (0, -0.2, 0), (0, 0, 0.1), (0.5, 0.5, 0.3)]
    particle_filter.particles = np.array(true_pose) + np.array(offsets)
    bearings = LaserConfig(beams=60).bearings()
    ranges = RayCaster(occupancy_map, 8.0).cast(*true_pose, bearings)
    particle_filter.correct(ranges, bearings)
    assert np.argmax(particle_filter.weights) == 0
    assert particle_filter.weights.sum() == pytest.approx(1.0)


def test_systematic_resampling_keeps_each_particles_share_within_one_copy():
    particle_filter = make_filter(particles=100)
    particle_filter.particles = np.column_stack([np.arange(100.0), np.zeros(100), np.zeros(100)])
    weights = np.random.default_rng(2).random(100) ** 4
    particle_filter.weights = weights / weights.sum()
    expected = particle_filter.weights * 100
    particle_filter.resample()
    copies = np.bincount(particle_filter.particles[:, 0].astype(int), minlength=100)
    assert np.all(np.abs(copies - expected) < 1.0)
    assert np.all(particle_filter.weights == 0.01)


def test_localiser_updates_on_amcls_thresholds_and_carries_the_estimate_in_between():
    localiser = Localiser(make_filter())
    localiser.initialise(Pose(2.0, 2.0, 0.0), np.diag([0.01, 0.01, 0.001]), Pose(0.0, 0.0, 0.0))
    assert not localiser.moved_enough(Pose(0.2, 0.0, 0.0))
    assert localiser.moved_enough(Pose(0.25, 0.0, 0.0))
    assert localiser.moved_enough(Pose(0.0, 0.0, -0.2))
    start = localiser.estimate(Pose(0.0, 0.0, 0.0))
    carried = localiser.estimate(Pose(0.1, 0.0, math.pi / 2))
    assert carried.x - start.x == pytest.approx(0.1 * math.cos(start.yaw), abs=1e-12)
    assert carried.yaw - start.yaw == pytest.approx(math.pi / 2, abs=1e-12)


def test_filter_recovers_from_a_wrong_initial_guess_that_its_covariance_admits():
    """Started 0.3 m and 0.1 rad off, with a covariance that covers that, a few updates
    while driving bring the estimate to the truth."""
    occupancy_map = maze_map()
    localiser = Localiser(make_filter(occupancy_map, particles=1000, seed=3))
    caster = RayCaster(occupancy_map, 8.0)
    bearings = LaserConfig(beams=60).bearings()
    true_pose = Pose(2.0, 2.0, 0.0)
    localiser.initialise(Pose(2.3, 1.8, 0.1), np.diag([0.3**2, 0.3**2, 0.15**2]), true_pose)
    for step in range(1, 13):
        true_pose = Pose(2.0 + 0.25 * step, 2.0, 0.0)
        localiser.update(true_pose, caster.cast(*true_pose, bearings), bearings)
    estimate = localiser.estimate(true_pose)
    assert math.hypot(estimate.x - true_pose.x, estimate.y - true_pose.y) < 0.08
    spread = math.sqrt(np.trace(localiser.covariance[:2, :2]))
    assert spread < 0.15
