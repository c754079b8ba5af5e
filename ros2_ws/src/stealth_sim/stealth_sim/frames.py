"""The transform tree the simulator publishes on /tf, as REP 105 and nav2 lay it out.

``map -> odom -> base_link``: the odometry gives ``odom -> base_link`` (smooth, drifting), and
localisation gives ``map -> odom``, the correction that makes the chain end at its estimate:
``map->odom = estimate * odometry^-1``, exactly what AMCL publishes. Poses are planar transforms
``(x, y, yaw)``: a child frame's origin and heading in its parent frame. No rclpy here.
"""

import math
from typing import NamedTuple

from stealth_sim.kinematics import Pose, wrap_angle

MAP_FRAME, ODOM_FRAME, BASE_FRAME = 'map', 'odom', 'base_link'


class FrameTransform(NamedTuple):
    """The pose of ``child`` in ``parent`` (as a TransformStamped's header and child frame)."""

    parent: str
    child: str
    pose: Pose


def multiply(a: Pose, b: Pose) -> Pose:
    """``a * b``: with ``a`` the pose of frame B in A and ``b`` that of C in B, C in A."""
    cos_yaw, sin_yaw = math.cos(a.yaw), math.sin(a.yaw)
    return Pose(
        a.x + b.x * cos_yaw - b.y * sin_yaw,
        a.y + b.x * sin_yaw + b.y * cos_yaw,
        wrap_angle(a.yaw + b.yaw),
    )


def inverse(a: Pose) -> Pose:
    """``a^-1``: with ``a`` the pose of B in A, the pose of A in B (``a * a^-1`` = identity)."""
    cos_yaw, sin_yaw = math.cos(a.yaw), math.sin(a.yaw)
    return Pose(
        -a.x * cos_yaw - a.y * sin_yaw,
        a.x * sin_yaw - a.y * cos_yaw,
        wrap_angle(-a.yaw),
    )


def map_to_odom(estimate: Pose, odometry: Pose) -> Pose:
    """The ``map -> odom`` correction: ``estimate * odometry^-1``, so that
    ``map_to_odom * odometry`` is the estimate (``base_link`` in ``map``)."""
    return multiply(estimate, inverse(odometry))


def robot_transforms(estimate: Pose, odometry: Pose) -> tuple[FrameTransform, FrameTransform]:
    """The dynamic part of the tree: ``map -> odom`` from localisation and ``odom -> base_link``
    from the odometry."""
    return (
        FrameTransform(MAP_FRAME, ODOM_FRAME, map_to_odom(estimate, odometry)),
        FrameTransform(ODOM_FRAME, BASE_FRAME, odometry),
    )
