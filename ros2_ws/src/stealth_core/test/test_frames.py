"""The /tf tree's math: map -> odom is the localisation's correction, as AMCL publishes it."""

import math

import numpy as np
import pytest
from stealth_core.frames import (
    BASE_FRAME,
    MAP_FRAME,
    ODOM_FRAME,
    inverse,
    map_to_odom,
    multiply,
    robot_transforms,
)
from stealth_core.kinematics import Pose, compose, relative, wrap_angle


def matrix(pose: Pose) -> np.ndarray:
    """The homogeneous 3x3 matrix of a planar transform (an independent reference)."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return np.array([[c, -s, pose.x], [s, c, pose.y], [0.0, 0.0, 1.0]])


def assert_same_pose(actual: Pose, expected: Pose, tolerance: float = 1e-9) -> None:
    assert actual.x == pytest.approx(expected.x, abs=tolerance)
    assert actual.y == pytest.approx(expected.y, abs=tolerance)
    assert abs(wrap_angle(actual.yaw - expected.yaw)) < tolerance


def random_poses(count: int, seed: int = 0) -> list[Pose]:
    values = np.random.default_rng(seed).uniform([-50, -50, -4], [50, 50, 4], (count, 3))
    return [Pose(*row) for row in values.tolist()]


def test_composing_map_to_odom_with_the_odometry_gives_the_estimate():
    poses = random_poses(400)
    for estimate, odometry in zip(poses[::2], poses[1::2], strict=True):
        map_odom, odom_base = robot_transforms(estimate, odometry)
        assert (map_odom.parent, map_odom.child) == (MAP_FRAME, ODOM_FRAME)
        assert (odom_base.parent, odom_base.child) == (ODOM_FRAME, BASE_FRAME)
        assert odom_base.pose == odometry
        assert_same_pose(multiply(map_odom.pose, odom_base.pose), estimate)
        assert -math.pi <= map_odom.pose.yaw <= math.pi


def test_multiply_and_inverse_agree_with_matrices_and_with_kinematics():
    poses = random_poses(300, seed=1)
    for a, b in zip(poses[::2], poses[1::2], strict=True):
        product = multiply(a, b)
        assert np.allclose(matrix(product), matrix(a) @ matrix(b), atol=1e-9)
        assert np.allclose(matrix(inverse(a)), np.linalg.inv(matrix(a)), atol=1e-9)
        assert_same_pose(multiply(a, inverse(a)), Pose(0.0, 0.0, 0.0))
        assert_same_pose(multiply(inverse(a), a), Pose(0.0, 0.0, 0.0))
        # The simulator's own composition (moving by an offset in the body frame) is the same.
        assert_same_pose(product, compose(a, b.x, b.y, b.yaw))
        assert_same_pose(multiply(inverse(a), b), Pose(*relative(a, b)))


def test_the_correction_is_identity_when_odometry_and_estimate_agree_and_known_otherwise():
    pose = Pose(3.0, -2.0, 2.5)
    assert_same_pose(map_to_odom(pose, pose), Pose(0.0, 0.0, 0.0))
    # Odometry drifted by a quarter turn about its origin: map -> odom turns it back.
    estimate, odometry = Pose(1.0, 0.0, 0.0), Pose(0.0, 1.0, math.pi / 2)
    assert_same_pose(map_to_odom(estimate, odometry), Pose(0.0, 0.0, -math.pi / 2))
    # A pure offset: the robot is 0.5 m further along x than the odometry says.
    assert_same_pose(map_to_odom(Pose(2.5, 1.0, 0.3), Pose(2.0, 1.0, 0.3)), Pose(0.5, 0.0, 0.0))
