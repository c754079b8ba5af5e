"""The transform tree the simulator publishes on /tf, as REP 105 and nav2 lay it out.

``map -> odom -> base_link``: the odometry gives ``odom -> base_link`` (smooth, drifting), and
localisation gives ``map -> odom``, the correction that makes the chain end at its estimate:
``map->odom = estimate * odometry^-1``, exactly what AMCL publishes. Poses are planar transforms
``(x, y, yaw)``: a child frame's origin and heading in its parent frame. No rclpy here.
"""

from typing import NamedTuple

from stealth_core.kinematics import Pose, compose, relative

MAP_FRAME, ODOM_FRAME, BASE_FRAME = 'map', 'odom', 'base_link'
ORIGIN = Pose(0.0, 0.0, 0.0)


class FrameTransform(NamedTuple):
    """The pose of ``child`` in ``parent`` (as a TransformStamped's header and child frame)."""

    parent: str
    child: str
    pose: Pose


def multiply(a: Pose, b: Pose) -> Pose:
    """``a * b``: with ``a`` the pose of frame B in A and ``b`` that of C in B, C in A (the
    kinematics' ``compose``: moving by ``b`` in ``a``'s own frame)."""
    return compose(a, *b)


def inverse(a: Pose) -> Pose:
    """``a^-1``: with ``a`` the pose of B in A, the pose of A in B (the kinematics' ``relative``
    of A's origin seen from ``a``)."""
    return Pose(*relative(a, ORIGIN))


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
