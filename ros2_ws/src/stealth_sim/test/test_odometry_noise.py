"""The odometry error follows AMCL's diff-drive model: the statistics match the alphas."""

import math

import numpy as np
import pytest
from stealth_core.kinematics import Pose, compose, wrap_angle
from stealth_sim.odometry_noise import (
    MotionDelta,
    MotionNoise,
    NoisyOdometry,
    apply_noisy_motion,
    decompose,
    noise_stddevs,
)

NOISE = MotionNoise(alpha1=0.05, alpha2=0.02, alpha3=0.1, alpha4=0.03)
SAMPLES = 40_000


def sampled_errors(delta: MotionDelta, noise: MotionNoise, seed: int = 0) -> np.ndarray:
    """(rot1, trans, rot2) errors of many noisy copies of one motion from the origin."""
    rng = np.random.default_rng(seed)
    zeros = np.zeros(SAMPLES)
    stddevs = noise_stddevs(delta, noise)
    normals = rng.standard_normal((SAMPLES, 3))
    poses = np.column_stack(apply_noisy_motion(zeros, zeros, zeros, delta, stddevs, normals))
    recovered = np.array([decompose(Pose(0, 0, 0), Pose(*pose)) for pose in poses])
    # A sampled translation below zero reads back as a half-turned bearing: fold it back.
    flipped = np.abs(wrap_angle(recovered[:, 0] - delta.rot1)) > math.pi / 2
    recovered[flipped] = recovered[flipped] * [1, -1, 1] + [-math.pi, 0, math.pi]
    errors = recovered - np.array(delta)
    errors[:, [0, 2]] = wrap_angle(errors[:, [0, 2]])
    return errors


@pytest.mark.parametrize(
    'delta',
    [MotionDelta(0.3, 0.25, -0.2), MotionDelta(0.0, 0.5, 0.0), MotionDelta(1.2, 0.05, 0.4)],
)
def test_error_standard_deviations_match_the_alphas(delta):
    errors = sampled_errors(delta, NOISE)
    a1, a2, a3, a4 = 0.05, 0.02, 0.1, 0.03
    rot1, trans, rot2 = delta
    expected = [
        math.sqrt(a1 * rot1**2 + a2 * trans**2),
        math.sqrt(a3 * trans**2 + a4 * rot1**2 + a4 * rot2**2),
        math.sqrt(a1 * rot2**2 + a2 * trans**2),
    ]
    assert errors.std(axis=0) == pytest.approx(expected, rel=0.02)
    standard_errors = np.array(expected) / math.sqrt(SAMPLES)
    assert np.all(np.abs(errors.mean(axis=0)) < 4 * standard_errors)


def test_driving_backwards_is_as_noisy_as_driving_forwards():
    forward = noise_stddevs(MotionDelta(0.2, 0.3, -0.1), NOISE)
    backward = noise_stddevs(MotionDelta(0.2 - math.pi, 0.3, -0.1 + math.pi), NOISE)
    assert backward == pytest.approx(forward)


def test_decompose_follows_amcl_including_turns_in_place():
    start = Pose(1.0, 1.0, 0.5)
    assert decompose(start, Pose(1.0, 1.0, 1.0)) == pytest.approx((0.0, 0.0, 0.5))
    # Shorter than 1 cm: the geometry stays exact, but the whole turn counts as rot2 for the noise.
    short = decompose(start, Pose(1.0, 1.005, 1.0))
    assert short == pytest.approx((math.pi / 2 - 0.5, 0.005, 1.0 - math.pi / 2))
    a1, a2, a3, a4 = 0.05, 0.02, 0.1, 0.03
    assert noise_stddevs(short, NOISE) == pytest.approx(
        (
            math.sqrt(a2 * 0.005**2),
            math.sqrt(a3 * 0.005**2 + a4 * 0.5**2),
            math.sqrt(a1 * 0.5**2 + a2 * 0.005**2),
        )
    )
    rot1, trans, rot2 = decompose(start, compose(start, 0.0, 2.0, 0.0))
    assert (rot1, trans, rot2) == pytest.approx((math.pi / 2, 2.0, -math.pi / 2))


def test_noise_free_odometry_is_the_truth():
    odometry = NoisyOdometry(MotionNoise(0, 0, 0, 0), np.random.default_rng(0))
    pose = Pose(2.0, -1.0, 0.4)
    odometry.reset(pose)
    rng = np.random.default_rng(1)
    for forward, turn in rng.uniform([-0.02, -0.05], [0.03, 0.05], size=(500, 2)):
        pose = compose(pose, forward, 0.0, turn)
        assert odometry.update(pose) == pytest.approx(pose, abs=1e-9)


def drive_straight(odometry: NoisyOdometry, length: float, steps: int) -> list[Pose]:
    odometry.reset(Pose(0.0, 0.0, 0.0))
    return [odometry.update(Pose(length * k / steps, 0.0, 0.0)) for k in range(1, steps + 1)]


def test_one_segment_of_odometry_carries_exactly_the_models_error():
    """A 0.25 m drive in 1 cm steps is one segment: its error is AMCL's for (0, 0.25, 0)."""
    odometry = NoisyOdometry(NOISE, np.random.default_rng(5))
    finals = np.array([drive_straight(odometry, 0.25, 25)[-1] for _ in range(4000)])
    s_rot, s_trans, _ = noise_stddevs(MotionDelta(0.0, 0.25, 0.0), NOISE)
    along = finals[:, 0] - 0.25
    assert along.std() == pytest.approx(s_trans, rel=0.05)
    assert finals[:, 2].std() == pytest.approx(math.hypot(s_rot, s_rot), rel=0.05)
    assert abs(along.mean()) < 4 * s_trans / math.sqrt(4000)


def test_errors_of_successive_segments_add_up_independently():
    odometry = NoisyOdometry(NOISE, np.random.default_rng(6))
    finals = np.array([drive_straight(odometry, 1.0, 100)[-1] for _ in range(2000)])
    s_rot, s_trans, _ = noise_stddevs(MotionDelta(0.0, 0.25, 0.0), NOISE)
    # Four segments; the heading errors also bend the later segments, which adds a little
    # along-track error of second order only.
    assert (finals[:, 0] - 1.0).std() == pytest.approx(2 * s_trans, rel=0.07)
    assert finals[:, 2].std() == pytest.approx(2 * math.hypot(s_rot, s_rot), rel=0.07)


def test_odometry_moves_continuously_within_and_across_segments():
    odometry = NoisyOdometry(NOISE, np.random.default_rng(8))
    poses = np.array(drive_straight(odometry, 2.0, 400))
    steps = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    turns = np.abs(wrap_angle(np.diff(poses[:, 2])))
    # A true step is 5 mm; the odometry's steps stay of that order (no jumps at the cuts).
    assert steps.max() < 0.005 * 2.5 and turns.max() < 0.01


def test_the_same_seed_gives_the_same_odometry():
    first = drive_straight(NoisyOdometry(NOISE, np.random.default_rng(9)), 1.0, 50)
    second = drive_straight(NoisyOdometry(NOISE, np.random.default_rng(9)), 1.0, 50)
    assert first == second


def test_alphas_must_be_finite_and_non_negative():
    with pytest.raises(ValueError, match='alpha3'):
        MotionNoise(alpha3=-0.1)
    with pytest.raises(ValueError, match='alpha1'):
        MotionNoise(alpha1=math.inf)
