"""A planning request's poses as plain numbers, checked before anything is computed with them
(no rclpy).

A start or goal arrives as float64 fields, any of which may be nan, +-inf, a finite extreme
(1e308: the arithmetic on it overflows, and a cell index of it cannot be an int) or an
orientation that is no rotation. Each pose becomes a planar ``Pose`` (x, y, yaw) or a
``PlanError`` ``START_OUTSIDE_MAP`` / ``GOAL_OUTSIDE_MAP`` naming the field, its value and what
was expected: such a pose is no place on the map, which is how Nav2's planner server answers a
pose off its costmap. Nothing else escapes (an exception of another kind reaches the node's
executor as a traceback and the client as error code 0).

The rules (docs/nav2.md lists them with the codes):

* position x, y, z and the orientation's x, y, z, w must be finite;
* z is otherwise ignored: paths lie in the map's plane, as Nav2's 2-D planners have them;
* the orientation may have any non-zero length: it is normalised, as tf2 does, and its heading
  about +z taken (roll and pitch ignored); the zero quaternion is no rotation;
* x and y must be on the map (the cells' area, [x_min, x_max) by [y_min, y_max)).
"""

from __future__ import annotations

from collections.abc import Sequence
import math

from stealth_core.kinematics import Pose

from stealth_nav2.plan_errors import PlanError

ROLES = ('START', 'GOAL')
POSITION_FIELDS = ('position.x', 'position.y', 'position.z')
ORIENTATION_FIELDS = ('orientation.x', 'orientation.y', 'orientation.z', 'orientation.w')
POSE_FIELDS = POSITION_FIELDS + ORIENTATION_FIELDS  # geometry_msgs/Pose's
TRANSFORM_FIELDS = tuple(  # geometry_msgs/Transform's
    name.replace('position', 'translation').replace('orientation', 'rotation')
    for name in POSE_FIELDS
)
_PLAIN_UP_TO = 1e6  # m: coordinates shown with two decimals below this, in short form above


def planar_pose(
    position: Sequence[float], orientation: Sequence[float], names=POSE_FIELDS
) -> Pose:
    """(x, y, yaw) of a pose given as position (x, y, z) and orientation (x, y, z, w);
    ValueError naming the first field that is not finite (as ``names`` call them), or a zero
    orientation."""
    for name, value in zip(names, (*position, *orientation), strict=True):
        if not math.isfinite(value):
            raise ValueError(f'{name} is {value}: expected a finite number')
    try:
        yaw = planar_yaw(*orientation)
    except ValueError as error:  # the zero quaternion
        raise ValueError(f'{names[3].split(".")[0]} is {error}') from None
    return Pose(float(position[0]), float(position[1]), yaw)


def planar_yaw(x: float, y: float, z: float, w: float) -> float:
    """The heading about +z (rad, in [-pi, pi]) of the rotation a finite quaternion of any
    non-zero length stands for; ValueError for the zero quaternion.

    Scaled by its largest component first, so that no square overflows (1e308) or underflows
    (5e-324) to 0; the heading is then the same for every length, as tf2's getYaw gives it."""
    largest = max(abs(x), abs(y), abs(z), abs(w))
    if largest == 0:
        raise ValueError(
            '(0, 0, 0, 0): expected a rotation, a quaternion of non-zero length (x = y = z = 0, '
            'w = 1 for none)'
        )
    x, y, z, w = x / largest, y / largest, z / largest, w / largest
    return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def request_pose(role: str, label: str, position, orientation) -> Pose:
    """``planar_pose`` for a request's start or goal (role START or GOAL, label the words that
    name it in messages: 'goal', 'start (amcl_pose)'): a bad field is {role}_OUTSIDE_MAP."""
    if role not in ROLES:
        raise ValueError(f'role: expected one of {", ".join(ROLES)}, got {role!r}')
    try:
        return planar_pose(position, orientation)
    except ValueError as error:
        raise PlanError(f'{role}_OUTSIDE_MAP', f'{label} {error}') from None


def check_on_map(occupancy, pose: Pose, role: str, label: str) -> None:
    """{role}_OUTSIDE_MAP unless (x, y) is on the map, {role}_OCCUPIED when it is in an
    occupied or unknown cell. Any floats: a point far off the map is told apart in floats,
    before a cell index (an int) is made of it; a yaw that is not finite is no heading."""
    if not math.isfinite(pose.yaw):
        raise PlanError(
            f'{role}_OUTSIDE_MAP', f'{label} yaw is {pose.yaw}: expected a finite number'
        )
    x_min, y_min, x_max, y_max = occupancy.bounds
    margin = occupancy.resolution  # the cell lookup below decides the edges exactly
    near = (
        x_min - margin <= pose.x <= x_max + margin and y_min - margin <= pose.y <= y_max + margin
    )
    if not (near and occupancy.contains_point(pose.x, pose.y)):
        raise PlanError(
            f'{role}_OUTSIDE_MAP',
            f'{label} {point(pose.x, pose.y)} is outside the map: expected x in '
            f'[{x_min:g}, {x_max:g}) and y in [{y_min:g}, {y_max:g})',
        )
    col, row = occupancy.world_to_cell(pose.x, pose.y)
    if occupancy.blocked[row, col]:
        kind = 'unknown' if occupancy.unknown[row, col] else 'occupied'
        raise PlanError(
            f'{role}_OCCUPIED', f'{label} {point(pose.x, pose.y)} is in an {kind} cell'
        )


def goal_label(k: int, count: int) -> str:
    """How messages name goal k (from 0) of a request's ``count``: 'goal', or 'goal 2 of 3'."""
    return 'goal' if count == 1 else f'goal {k + 1} of {count}'


def point(x: float, y: float) -> str:
    """'(x, y)' for messages: two decimals, or a short form for nan, inf and huge values."""
    return f'({_coordinate(x)}, {_coordinate(y)})'


def _coordinate(value: float) -> str:
    return f'{value:.2f}' if abs(value) < _PLAIN_UP_TO else f'{value:.3g}'
