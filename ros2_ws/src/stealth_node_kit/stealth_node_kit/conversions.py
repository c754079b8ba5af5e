"""Conversions between plain numbers and the message fields every node fills."""

from __future__ import annotations

import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion

_NS_PER_S = 1_000_000_000


def time_msg(seconds: float) -> Time:
    """builtin_interfaces/Time of a time in seconds, rounded to the nanosecond."""
    nanoseconds = round(seconds * 1e9)
    return Time(sec=nanoseconds // _NS_PER_S, nanosec=nanoseconds % _NS_PER_S)


def seconds(stamp: Time) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def yaw_quaternion(yaw: float) -> Quaternion:
    """The rotation by `yaw` (rad) about +z."""
    return set_yaw(Quaternion(), yaw)


def set_yaw(quaternion: Quaternion, yaw: float) -> Quaternion:
    """``quaternion`` (x and y left 0) made the rotation by `yaw` (rad) about +z, in place: for
    a message kept and refilled every control period."""
    quaternion.z, quaternion.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return quaternion


def quaternion_yaw(q: Quaternion) -> float:
    """The heading (rad, about +z) of a rotation; roll and pitch are ignored."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
