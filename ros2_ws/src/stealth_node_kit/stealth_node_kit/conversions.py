"""Conversions between plain numbers and the message fields every node fills."""

from __future__ import annotations

import array
import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion
from nav_msgs.msg import OccupancyGrid
import numpy as np

MAP_FRAME = 'map'  # stealth_core.frames.MAP_FRAME: the frame of every map-aligned grid

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


def grid_msg(levels: np.ndarray, resolution: float, origin, t: float) -> OccupancyGrid:
    """OccupancyGrid of (rows, cols) int8 levels (row 0 the bottom, as /map) with these cells
    (m) from origin (x, y, yaw) of the map frame, stamped t: the environment's visibility grid
    and ``sensed_light``, the exposure mask, the light model's belief."""
    levels = np.ascontiguousarray(levels, dtype=np.int8)
    grid = OccupancyGrid()
    grid.header.stamp, grid.header.frame_id = time_msg(t), MAP_FRAME
    grid.info.map_load_time = grid.header.stamp
    grid.info.resolution = float(resolution)
    grid.info.height, grid.info.width = levels.shape
    x, y, yaw = origin
    grid.info.origin.position.x, grid.info.origin.position.y = float(x), float(y)
    grid.info.origin.orientation = yaw_quaternion(yaw)
    grid.data = array.array('b', levels.tobytes())
    return grid
