"""Diff-drive (unicycle) kinematics at a fixed step, and where on the map the robot's disc fits.

The robot is a disc of radius ``robot_radius``. It may not touch a blocked cell (occupied or
unknown) nor leave the map: "touch" means coming closer than the radius to the cell's square, the
rule ``stealth_core.move_lattice`` uses, so the simulator and the lattice agree on what fits.

Collision is checked on the swept segment of every step, exactly (segment-to-square distances),
so no speed or step length lets the robot tunnel through a wall one cell thick. A clearance map
(the Euclidean distance transform of free space) settles most steps in open space with one
lookup; only steps near walls pay for the exact test.
"""

import dataclasses
import math
import numbers
from typing import NamedTuple

import cv2
import numpy as np

from stealth_core.occupancy_map import OccupancyMap

TWO_PI = 2.0 * math.pi
# Bisection steps for the contact point of a bump: the robot stops within 2**-12 of its step.
_CONTACT_BISECTIONS = 12


class Pose(NamedTuple):
    """A planar pose: position (m) and heading (rad, counter-clockwise from +x)."""

    x: float
    y: float
    yaw: float


class RobotState(NamedTuple):
    """The robot's true pose and body velocities: linear (m/s, along its heading), angular
    (rad/s)."""

    pose: Pose
    linear: float = 0.0
    angular: float = 0.0


def wrap_angle(angle):
    """An angle (or array of angles) in [-pi, pi]; one already in range comes back unchanged."""
    if isinstance(angle, float | int):
        return math.remainder(angle, TWO_PI)
    return angle - TWO_PI * np.round(np.asarray(angle) / TWO_PI)


def compose(pose: Pose, forward: float, left: float, turn: float) -> Pose:
    """The pose reached by moving (forward, left) in ``pose``'s own frame, then turning."""
    cos_yaw, sin_yaw = math.cos(pose.yaw), math.sin(pose.yaw)
    return Pose(
        pose.x + forward * cos_yaw - left * sin_yaw,
        pose.y + forward * sin_yaw + left * cos_yaw,
        math.remainder(pose.yaw + turn, TWO_PI),
    )


def relative(origin: Pose, pose: Pose) -> tuple[float, float, float]:
    """``pose`` seen from ``origin``: (forward, left, turn), the inverse of :func:`compose`."""
    dx, dy = pose.x - origin.x, pose.y - origin.y
    cos_yaw, sin_yaw = math.cos(origin.yaw), math.sin(origin.yaw)
    return (
        dx * cos_yaw + dy * sin_yaw,
        -dx * sin_yaw + dy * cos_yaw,
        math.remainder(pose.yaw - origin.yaw, TWO_PI),
    )


def require_finite(**values: float) -> None:
    """Raise ValueError naming the first value that is not a finite number."""
    for name, value in values.items():
        if not is_finite_number(value):
            raise ValueError(f'{name}: expected a finite number, got {value!r}')


def is_finite_number(value) -> bool:
    """True for finite ints and floats, numpy's included; not for booleans."""
    if type(value) is float:  # the common case, without the slower abstract-class check
        return math.isfinite(value)
    return (
        isinstance(value, numbers.Real)
        and not isinstance(value, bool | np.bool_)
        and math.isfinite(value)
    )


@dataclasses.dataclass(frozen=True)
class Limits:
    """Velocity and acceleration limits of the drive (m/s, rad/s, m/s^2, rad/s^2), all > 0."""

    max_linear_speed: float = 0.5
    max_angular_speed: float = 1.5
    max_linear_accel: float = 1.0
    max_angular_accel: float = 3.0

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if not (is_finite_number(value) and value > 0):
                raise ValueError(f'{field.name}: expected a finite number > 0, got {value!r}')


def limited_velocity(
    current: float, command: float, max_speed: float, max_accel: float, dt: float
) -> float:
    """The velocity after one step towards ``command``, clamped to the speed and accel limits."""
    target = min(max(command, -max_speed), max_speed)
    change = min(max(target - current, -max_accel * dt), max_accel * dt)
    return current + change


def integrate(pose: Pose, linear: float, angular: float, dt: float) -> Pose:
    """Exact unicycle motion at constant velocities for ``dt``: an arc, or a line.

    The chord of the arc has length ``v dt sinc(w dt / 2)`` along the mid-step heading; the
    series form of sinc keeps it exact as ``w`` goes to zero (a straight line).
    """
    half_turn = 0.5 * angular * dt
    if abs(half_turn) < 1e-4:
        sinc = 1.0 - half_turn * half_turn / 6.0
    else:
        sinc = math.sin(half_turn) / half_turn
    chord = linear * dt * sinc
    heading = pose.yaw + half_turn
    return Pose(
        pose.x + chord * math.cos(heading),
        pose.y + chord * math.sin(heading),
        math.remainder(pose.yaw + angular * dt, TWO_PI),
    )


class DiscFootprint:
    """Where a disc of ``radius`` fits on a map: never closer than the radius to a blocked cell.

    The map is padded with a ring of blocked cells, so leaving the map is a collision like any
    other; points beyond the ring are outside and never fit.
    """

    def __init__(self, occupancy_map: OccupancyMap, radius: float):
        require_finite(robot_radius=radius)
        if radius < 0:
            raise ValueError(f'robot_radius: expected a number >= 0 (m), got {radius!r}')
        self.radius = float(radius)
        self.resolution = occupancy_map.resolution
        pad = math.ceil(radius / self.resolution) + 2
        self.blocked = np.pad(occupancy_map.blocked, pad, constant_values=True)
        self.origin_x = occupancy_map.origin[0] - pad * self.resolution
        self.origin_y = occupancy_map.origin[1] - pad * self.resolution
        free = (~self.blocked).astype(np.uint8)
        centre_distance = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        # From any point of a cell to the nearest blocked square is at least this far: the
        # centre-to-centre distance less half a diagonal at each end (and a float32 margin).
        self.lower_bound = (centre_distance.astype(np.float64) - math.sqrt(2.0) - 1e-3) * (
            self.resolution
        )

    def cell_of(self, x: float, y: float) -> tuple[int, int] | None:
        """(row, col) in the padded grid, or None outside it."""
        col = math.floor((x - self.origin_x) / self.resolution)
        row = math.floor((y - self.origin_y) / self.resolution)
        rows, cols = self.blocked.shape
        if 0 <= row < rows and 0 <= col < cols:
            return row, col
        return None

    def fits(self, x: float, y: float) -> bool:
        """True when the disc centred at (x, y) touches no blocked cell."""
        return self.sweep_is_free(x, y, x, y)

    def sweep_is_free(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """True when the disc moved along the segment (x0, y0)-(x1, y1) touches no blocked cell."""
        start, end = self.cell_of(x0, y0), self.cell_of(x1, y1)
        if start is None or end is None:
            return False
        length = math.hypot(x1 - x0, y1 - y0)
        if self.lower_bound[start] - length >= self.radius:
            return True
        return not self._sweep_touches_blocked(x0, y0, x1, y1)

    def free_fraction(self, x0: float, y0: float, x1: float, y1: float) -> float:
        """How far along the segment (0..1) the disc gets before it would touch a blocked cell.

        Assumes the start fits; bisection to within ``2**-12`` of the segment.
        """
        low, high = 0.0, 1.0
        for _ in range(_CONTACT_BISECTIONS):
            middle = 0.5 * (low + high)
            if self.sweep_is_free(x0, y0, x0 + middle * (x1 - x0), y0 + middle * (y1 - y0)):
                low = middle
            else:
                high = middle
        return low

    def _sweep_touches_blocked(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """Exact test: is any blocked square closer than the radius to the segment?"""
        res, radius = self.resolution, self.radius
        col_lo = math.floor((min(x0, x1) - radius - self.origin_x) / res)
        col_hi = math.floor((max(x0, x1) + radius - self.origin_x) / res)
        row_lo = math.floor((min(y0, y1) - radius - self.origin_y) / res)
        row_hi = math.floor((max(y0, y1) + radius - self.origin_y) / res)
        row_lo, col_lo = max(row_lo, 0), max(col_lo, 0)
        window = self.blocked[row_lo : row_hi + 1, col_lo : col_hi + 1]
        block_rows, block_cols = np.nonzero(window)
        if block_rows.size == 0:
            return False
        left = self.origin_x + (block_cols + col_lo) * res
        bottom = self.origin_y + (block_rows + row_lo) * res
        return bool(
            np.any(segment_to_squares_sq(x0, y0, x1, y1, left, bottom, res) < radius * radius)
            or np.any(segment_crosses_squares(x0, y0, x1, y1, left, bottom, res))
        )


def segment_to_squares_sq(x0, y0, x1, y1, left, bottom, side) -> np.ndarray:
    """Squared distance from the segment to each axis-aligned square (left, bottom, side).

    Between a segment and a convex polygon that do not intersect, the distance is reached at a
    vertex of one of them; :func:`segment_crosses_squares` covers the intersecting case.
    """

    def point_to_squares_sq(px, py):
        dx = np.maximum(np.maximum(left - px, px - (left + side)), 0.0)
        dy = np.maximum(np.maximum(bottom - py, py - (bottom + side)), 0.0)
        return dx * dx + dy * dy

    nearest = np.minimum(point_to_squares_sq(x0, y0), point_to_squares_sq(x1, y1))
    dx, dy = x1 - x0, y1 - y0
    length_sq = dx * dx + dy * dy
    if length_sq == 0.0:
        return nearest
    for corner_x, corner_y in (
        (left, bottom),
        (left + side, bottom),
        (left, bottom + side),
        (left + side, bottom + side),
    ):
        t = np.clip(((corner_x - x0) * dx + (corner_y - y0) * dy) / length_sq, 0.0, 1.0)
        ex, ey = x0 + t * dx - corner_x, y0 + t * dy - corner_y
        nearest = np.minimum(nearest, ex * ex + ey * ey)
    return nearest


def segment_crosses_squares(x0, y0, x1, y1, left, bottom, side) -> np.ndarray:
    """Whether the segment meets each square (the slab test, boundaries included)."""
    t_enter = np.zeros(np.shape(left))
    t_exit = np.ones(np.shape(left))
    for start, delta, low in ((x0, x1 - x0, left), (y0, y1 - y0, bottom)):
        if delta == 0.0:
            inside = (low <= start) & (start <= low + side)
            t_exit = np.where(inside, t_exit, -1.0)
            continue
        t_a, t_b = (low - start) / delta, (low + side - start) / delta
        t_enter = np.maximum(t_enter, np.minimum(t_a, t_b))
        t_exit = np.minimum(t_exit, np.maximum(t_a, t_b))
    return t_enter <= t_exit


def step_robot(
    state: RobotState,
    linear_command: float,
    angular_command: float,
    limits: Limits,
    dt: float,
    footprint: DiscFootprint,
) -> tuple[RobotState, bool]:
    """One physics step: velocities move towards the command within the limits, the pose follows.

    Returns the new state and whether the robot bumped. A bump stops the robot where its disc
    first touches the blocked cell; the step's rotation still happens (a disc turns freely).
    """
    linear = limited_velocity(
        state.linear, linear_command, limits.max_linear_speed, limits.max_linear_accel, dt
    )
    angular = limited_velocity(
        state.angular, angular_command, limits.max_angular_speed, limits.max_angular_accel, dt
    )
    start = state.pose
    end = integrate(start, linear, angular, dt)
    if footprint.sweep_is_free(start.x, start.y, end.x, end.y):
        return RobotState(end, linear, angular), False
    fraction = footprint.free_fraction(start.x, start.y, end.x, end.y)
    contact = Pose(
        start.x + fraction * (end.x - start.x), start.y + fraction * (end.y - start.y), end.yaw
    )
    return RobotState(contact, 0.0, 0.0), True
