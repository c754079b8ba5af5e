"""Poses from another frame into the map over the transforms heard on /tf (plain pytest)."""

import math

import pytest
from stealth_core.kinematics import Pose
from stealth_nav2.frame_tree import FrameError, FrameTree


def close(a, b):
    return all(math.isclose(u, v, abs_tol=1e-12) for u, v in zip(a, b, strict=True))


def test_a_pose_in_odom_is_carried_into_map():
    tree = FrameTree()
    tree.update('map', 'odom', Pose(1.0, 2.0, math.pi / 2))
    assert close(tree.transform(Pose(1.0, 0.0, 0.0), 'odom', 'map'), (1.0, 3.0, math.pi / 2))
    assert close(tree.transform(Pose(1.0, 3.0, math.pi / 2), 'map', 'odom'), (1.0, 0.0, 0.0))


def test_chains_and_leading_slashes():
    tree = FrameTree()
    tree.update('/map', 'odom', Pose(1.0, 0.0, 0.0))
    tree.update('odom', 'base_link', Pose(0.0, 2.0, 0.0))
    assert close(tree.transform(Pose(0.0, 0.0, 0.0), 'base_link', 'map'), (1.0, 2.0, 0.0))
    tree.update('map', 'odom', Pose(5.0, 0.0, 0.0))  # the latest transform replaces the last
    assert close(tree.transform(Pose(0.0, 0.0, 0.0), 'base_link', 'map'), (5.0, 2.0, 0.0))


def test_an_unknown_frame_is_named():
    tree = FrameTree()
    tree.update('map', 'odom', Pose(0.0, 0.0, 0.0))
    with pytest.raises(FrameError, match="from frame 'world' to 'map'.*frames heard: map, odom"):
        tree.transform(Pose(0.0, 0.0, 0.0), 'world', 'map')
