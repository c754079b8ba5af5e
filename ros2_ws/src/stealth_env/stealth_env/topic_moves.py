"""RL moves executed closed-loop over a robot's standard topics (the environment's ``topics``
mode): ``geometry_msgs/Twist`` out on ``cmd_vel``; ``odom``, ``amcl_pose`` and ``scan`` in. Pure
Python + numpy, no rclpy: the environment node only feeds messages in and sends commands out.

The move is the simulator's ``sim/execute_move`` (``stealth_sim.move_executor``), with its
tolerances, time limit and outcomes: turn in place until the estimated heading is within
tolerance and stop, then drive towards the target fixed at the start of the drive (estimated
start + distance along the heading), done when the target is within tolerance along the drive's
line, and brake to rest. What differs is what a robot on topics allows:

- **Estimate**: AMCL's estimate between its updates, as AMCL's ``map -> odom`` transform gives
  it: the latest ``amcl_pose`` carried forward by the odometry since its stamp
  (:class:`PoseTracker`). Times are the messages' stamps (the robot's clock: simulated time on a
  simulator), so the controller is indifferent to how fast that clock runs against the wall.
- **Control period**: a command acts from when the robot takes it until the next one, one odom
  period later, and is decided on a pose up to a period old. The braking curve of the service
  path (``v dt + v^2 / 2a = d``) is kept with ``dt`` the odom period, applied to the distance
  left once the robot has coasted one more period at its measured speed; so the approach never
  overshoots by more than the coasting a period of latency adds, and ends deadbeat.
- **BUMPED**: the simulator knows contact; a robot on topics sees it coming. An obstacle in the
  laser scan that the disc would touch before the target limits the speed (the robot brakes for
  it) and ends the move BUMPED once within ``bump_distance`` of it; a robot that moved during the
  move and then makes no progress for ``stall_time`` while told to drive is BUMPED too.
- **TIMED_OUT**: the same time limit; a robot that never moves on ``cmd_vel`` times out (it is
  not responding, which the node counts; it is not a bump).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
import dataclasses
import enum
import functools
import math
from typing import NamedTuple

import numpy as np
from stealth_core.controller import signed_approach_speed
from stealth_core.kinematics import Limits, Pose, compose, relative, wrap_angle
from stealth_core.move_lattice import MoveLattice, Node
from stealth_core.moves import ControllerConfig, MoveOutcome

__all__ = ['ControllerConfig', 'Limits', 'MoveOutcome', 'Pose']

ODOM_HISTORY = 64  # odometry poses kept to place an amcl_pose stamped in the past
_PERIOD_SMOOTHING = 0.2  # weight of the newest odom interval in the period's running mean


def pose_problem(x: float, y: float, yaw: float, frame: str = '', expected: str = '') -> str:
    """Why a received pose cannot be used ('' when it can): not finite, or in another frame."""
    if expected and frame != expected:
        return f"frame '{frame}', expected '{expected}'"
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        return f'pose ({x}, {y}, yaw {yaw}) is not finite'
    return ''


# --- the estimate -------------------------------------------------------------------------------


class Odom(NamedTuple):
    """One odometry message: stamp (s), pose in the odom frame, body velocities."""

    t: float
    pose: Pose
    linear: float = 0.0  # m/s
    angular: float = 0.0  # rad/s


class PoseTracker:
    """The map-frame estimate now: the latest localisation (``amcl_pose``) carried forward by
    the odometry, estimate = amcl_pose (+) odom(stamp)^-1 (+) odom(now); and the odom period.

    An ``amcl_pose`` stamped between two odometry messages is placed by interpolating them; one
    newer than every odometry message waits for the next. After a teleport (``restart``) the
    odometry jumps without its clock moving, so only messages stamped after it count.
    """

    def __init__(self):
        self._odoms: deque[Odom] = deque(maxlen=ODOM_HISTORY)
        self._waiting: tuple[float, Pose] | None = None  # an estimate newer than the odometry
        self._anchor: tuple[Pose, Pose] | None = None  # (estimate, odom pose) at one instant
        self._placed: Pose | None = None  # where the next odometry message puts the robot
        self._not_before = -math.inf  # messages stamped at or before this are stale
        self.period: float | None = None  # s between odometry messages (running mean)

    @property
    def latest(self) -> Odom | None:
        return self._odoms[-1] if self._odoms else None

    @property
    def estimate(self) -> Pose | None:
        """The estimate at the latest odometry's stamp, or None before both have come."""
        if self._anchor is None or not self._odoms:
            return None
        estimate, odom_pose = self._anchor
        return compose(estimate, *relative(odom_pose, self._odoms[-1].pose))

    def add_odom(self, odom: Odom) -> None:
        if odom.t <= self._not_before:
            return
        last = self.latest
        if last is not None:
            if odom.t <= last.t:
                if odom.t < last.t:  # the clock went back (a simulator restarted): start over
                    self._odoms.clear()
                    self.period = None
                return
            interval = odom.t - last.t
            self.period = (
                interval
                if self.period is None
                else self.period + _PERIOD_SMOOTHING * (interval - self.period)
            )
        self._odoms.append(odom)
        if self._placed is not None:
            self._anchor, self._placed = (self._placed, odom.pose), None
        if self._waiting is not None and self._waiting[0] <= odom.t:
            waiting, self._waiting = self._waiting, None
            self.add_estimate(*waiting)

    def add_estimate(self, t: float, pose: Pose) -> None:
        """A localisation estimate (amcl_pose) stamped t."""
        if t <= self._not_before:
            return
        odom_pose = self._odom_pose_at(t)
        if odom_pose is None:
            self._waiting = (t, pose)
        else:
            self._anchor = (pose, odom_pose)

    def restart(self, pose: Pose, after: float) -> None:
        """The robot was teleported to ``pose`` (odometry and localisation restarted there)
        after stamp ``after``: the first odometry message stamped later anchors it."""
        self._odoms.clear()
        self._waiting = self._anchor = None
        self._placed = pose
        self._not_before = after

    def place(self, pose: Pose) -> None:
        """The localisation was told the robot is at ``pose`` (an initialpose) while at rest:
        the estimate is that pose from the latest odometry on; older estimates are stale."""
        if self._odoms:
            self._anchor = (pose, self._odoms[-1].pose)
            self._not_before = self._odoms[-1].t
            self._waiting = None

    def _odom_pose_at(self, t: float) -> Pose | None:
        """The odometry pose at stamp t, interpolated; None when t is newer than every one."""
        odoms = self._odoms
        if not odoms or t > odoms[-1].t:
            return None
        if t <= odoms[0].t:
            return odoms[0].pose
        for index in range(len(odoms) - 1, 0, -1):
            before = odoms[index - 1]
            if before.t <= t:
                return interpolate(before, odoms[index], t)
        return odoms[0].pose


def interpolate(a: Odom, b: Odom, t: float) -> Pose:
    """The odometry pose at t between two messages: cubic Hermite in x, y and yaw with the
    messages' velocities as slopes, exact for the constant accelerations of a velocity ramp."""
    dt = b.t - a.t
    s = (t - a.t) / dt
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    yaw_b = a.pose.yaw + wrap_angle(b.pose.yaw - a.pose.yaw)  # unwrapped: the short way round

    def hermite(p0, p1, slope0, slope1):
        return h00 * p0 + h10 * dt * slope0 + h01 * p1 + h11 * dt * slope1

    return Pose(
        hermite(
            a.pose.x, b.pose.x, a.linear * math.cos(a.pose.yaw), b.linear * math.cos(b.pose.yaw)
        ),
        hermite(
            a.pose.y, b.pose.y, a.linear * math.sin(a.pose.yaw), b.linear * math.sin(b.pose.yaw)
        ),
        wrap_angle(hermite(a.pose.yaw, yaw_b, a.angular, b.angular)),
    )


# --- the move -----------------------------------------------------------------------------------


class MoveGoal(NamedTuple):
    """What a move over topics is to reach, in the controller's own terms rather than the kinds
    of the simulator's request (``stealth_core.moves.MoveRequest``, whose grid moves and drives
    depend on where the robot is).

    Turn to ``heading`` (rad, map frame), then drive ``distance`` (m; 0: only the turn); or,
    with a ``target`` (x, y in m, map frame), turn to face it and drive there, as the
    simulator's GO_TO (heading and distance then follow from where the move starts); or, with
    ``hold`` > 0, stand still that long (s of the robot's clock), as the simulator's HOLD.

    ``line_from`` (x, y), with a target: the drive follows the line from there to the target (a
    leg of a path), steering back onto it ``TopicConfig.lookahead`` ahead (pure pursuit) when
    the estimate is off it (a localisation update moved it), instead of aiming at the target,
    which on a long leg would take metres to come back."""

    heading: float
    distance: float = 0.0
    target: tuple[float, float] | None = None
    hold: float = 0.0
    line_from: tuple[float, float] | None = None


def go_to(x: float, y: float, line_from: tuple[float, float] | None = None) -> MoveGoal:
    """The move to the point (x, y) of the map frame (along the line from ``line_from``)."""
    line = None if line_from is None else (float(line_from[0]), float(line_from[1]))
    return MoveGoal(0.0, 0.0, (float(x), float(y)), 0.0, line)


def hold_goal(seconds: float) -> MoveGoal:
    """The goal of standing still for ``seconds`` of the robot's clock."""
    return MoveGoal(0.0, 0.0, None, float(seconds))


class Command(NamedTuple):
    """Velocities to send on cmd_vel (m/s, rad/s)."""

    linear: float
    angular: float


STOP = Command(0.0, 0.0)


class Finished(NamedTuple):
    """The end of a move: its outcome, why, and whether the robot moved at all during it."""

    outcome: MoveOutcome
    message: str
    duration: float  # s of the robot's clock
    moved: bool


@dataclasses.dataclass(frozen=True)
class TopicConfig:
    """What a move over topics needs besides the simulator's controller settings."""

    limits: Limits = Limits()  # the robot's (or lower): the braking curve and the time limit
    robot_radius: float = 0.2  # m: the disc the scan check sweeps forward
    bump_distance: float = 0.05  # m: this close to an obstacle in the way ends a move BUMPED
    stall_time: float = 1.0  # s without progress while driving, after moving: BUMPED
    progress: float = 0.005  # m: less than this over stall_time is no progress
    default_period: float = 0.1  # s: the control period until odometry has shown its own
    # When a command takes effect after the odometry it answers, in odometry periods: 1 (a
    # robot that takes it at its next control cycle) to 0 (a simulator in lockstep).
    command_latency: float = 1.0
    lookahead: float = 0.6  # m along a move's line (MoveGoal.line_from) it steers for


class MoveStage(enum.Enum):
    """What a move in progress is doing (``TopicMove.stage``)."""

    TURN = 'turn'
    DRIVE = 'drive'
    BRAKE = 'brake'
    HOLD = 'hold'


MESSAGES = {
    MoveOutcome.DONE: '',
    MoveOutcome.BUMPED: 'the robot met a wall or unknown space and stopped',
    MoveOutcome.TIMED_OUT: 'the move did not finish within {limit:.1f} s',
}


class TopicMove:
    """One move in progress. ``update`` with every odometry message (the robot's estimate, its
    measured velocities, the forward clearance from the latest scan) gives the command to send,
    or a :class:`Finished` once the robot is at rest after the move."""

    def __init__(
        self,
        move: MoveGoal,
        start: Pose,
        t: float,
        config: TopicConfig | None = None,
        controller: ControllerConfig | None = None,
    ):
        self.config = config = config or TopicConfig()
        self.controller = controller = controller or ControllerConfig()
        if move.target is not None:
            dx, dy = move.target[0] - start.x, move.target[1] - start.y
            distance = math.hypot(dx, dy)
            if distance <= controller.position_tolerance:  # there already: no turn, no drive
                move = MoveGoal(start.yaw, 0.0, move.target, 0.0, move.line_from)
            else:
                move = MoveGoal(math.atan2(dy, dx), distance, move.target, 0.0, move.line_from)
        self.move = move._replace(heading=wrap_angle(move.heading))
        self.start_time = t
        self.start = start
        limits = config.limits
        nominal = (
            abs(wrap_angle(self.move.heading - start.yaw)) / limits.max_angular_speed
            + move.distance / limits.max_linear_speed
        )
        self.time_limit = controller.time_limit_factor * nominal + controller.time_limit_margin
        self.stage = MoveStage.HOLD if move.hold > 0 else MoveStage.TURN
        self._after_brake: MoveOutcome | None = None  # None: continue with the drive
        self._target: tuple[float, float] | None = None
        self._start_odom: Pose | None = None
        self._moved = False
        self._progress_mark: tuple[float, Pose] | None = None
        self._sent = STOP  # the command in flight: it acts until the next one arrives

    def update(
        self,
        t: float,
        estimate: Pose,
        odom: Odom,
        clearance: float = math.inf,
        period: float | None = None,
    ) -> Command | Finished:
        """The command for now. ``clearance``: how far the disc can drive straight ahead before
        touching what the scan sees (m); ``period``: the odometry period (s)."""
        period = period or self.config.default_period
        self._note_motion(odom)
        result = self._decide(t, estimate, odom, clearance, period)
        if isinstance(result, Command):
            self._sent = result
        return result

    def _decide(self, t, estimate, odom, clearance, period) -> Command | Finished:
        elapsed = t - self.start_time
        if self.stage is MoveStage.HOLD:
            return self._hold(elapsed)
        if self.stage is not MoveStage.BRAKE and elapsed > self.time_limit:
            return self._brake(MoveOutcome.TIMED_OUT)
        if self.stage is MoveStage.TURN:
            return self._turn(t, estimate, odom, period)
        if self.stage is MoveStage.DRIVE:
            return self._drive(t, estimate, odom, clearance, period)
        return self._braking(t, estimate, odom, period)

    # --- stages ---------------------------------------------------------------------------------

    def _hold(self, elapsed: float) -> Command | Finished:
        """Stop and stay; done when the time is up (a robot that still rolls has moved)."""
        if elapsed >= self.move.hold:
            return Finished(MoveOutcome.DONE, '', elapsed, self._moved)
        return STOP

    def _turn(self, t: float, estimate: Pose, odom: Odom, period: float) -> Command | Finished:
        error = wrap_angle(self.move.heading - estimate.yaw)
        if abs(error) <= self.controller.heading_tolerance:
            self.stage = MoveStage.BRAKE  # then the drive, once at rest
            return self._braking(t, estimate, odom, period)
        return Command(0.0, self._turn_rate(error, odom.angular, period))

    def _start_drive(self, estimate: Pose) -> None:
        heading, distance, target = self.move.heading, self.move.distance, self.move.target
        self._target = target or (
            estimate.x + distance * math.cos(heading),
            estimate.y + distance * math.sin(heading),
        )
        self.stage = MoveStage.DRIVE

    def _drive(
        self, t: float, estimate: Pose, odom: Odom, clearance: float, period: float
    ) -> Command | Finished:
        controller = self.controller
        heading = self.move.heading
        dx, dy = self._target[0] - estimate.x, self._target[1] - estimate.y
        remaining = self._remaining(estimate)
        if abs(remaining) <= controller.position_tolerance:
            return self._brake(MoveOutcome.DONE)
        free = clearance - self.config.bump_distance  # how far until too close to an obstacle
        if clearance < remaining - self.config.bump_distance:  # it stands before the target
            if free <= controller.position_tolerance:
                return self._brake(MoveOutcome.BUMPED)
            remaining = free
        if self._stalled(t, odom):
            return self._brake(MoveOutcome.BUMPED)
        aim = self._aim(estimate, dx, dy) if remaining > controller.aim_distance else heading
        error = wrap_angle(aim - estimate.yaw)
        limits = self.config.limits
        # Signed: past the target (a command that came late at speed), it backs up to it.
        latency = period * self.config.command_latency
        left = remaining - coast(odom.linear, self._sent.linear, limits.max_linear_accel, latency)
        speed = signed_approach_speed(
            left,
            limits.max_linear_speed,
            limits.max_linear_accel * controller.braking_share,
            period,
        )
        # Slow down while badly misaligned rather than drive sideways off the line.
        speed *= max(0.0, math.cos(error))
        return Command(speed, self._turn_rate(error, odom.angular, period))

    def _braking(self, t: float, estimate: Pose, odom: Odom, period: float):
        stopped = self.controller.stopped_speed
        at_rest = abs(odom.linear) <= stopped and abs(odom.angular) <= stopped
        overdue = t - self.start_time > 2 * self.time_limit  # odometry that never shows rest
        if not (at_rest or overdue):
            return STOP
        tolerance = self.controller.position_tolerance
        if self._after_brake is MoveOutcome.DONE and abs(self._remaining(estimate)) > tolerance:
            self._after_brake = None  # it coasted past the target: back to it
            self.stage = MoveStage.DRIVE
            return self._drive(t, estimate, odom, math.inf, period)
        if self._after_brake is not None:
            outcome = self._after_brake
            message = MESSAGES[outcome].format(limit=self.time_limit)
            return Finished(outcome, message, t - self.start_time, self._moved)
        # The turn is over: check the heading once at rest (a coarse period may coast past it).
        self.stage = MoveStage.TURN
        error = wrap_angle(self.move.heading - estimate.yaw)
        if abs(error) > self.controller.heading_tolerance:
            return Command(0.0, self._turn_rate(error, odom.angular, period))
        if self.move.distance <= 0:
            self._after_brake = MoveOutcome.DONE
            return self._braking(t, estimate, odom, period)
        self._start_drive(estimate)
        return self._drive(t, estimate, odom, math.inf, period)

    def _aim(self, estimate: Pose, dx: float, dy: float) -> float:
        """The direction to steer in: at the target, or, following a line, at the point
        ``lookahead`` ahead of the robot along it (never beyond the target)."""
        line_from = self.move.line_from
        if line_from is None:
            return math.atan2(dy, dx)
        (ax, ay), (tx, ty) = line_from, self._target
        length = math.hypot(tx - ax, ty - ay)
        if length <= 0:
            return math.atan2(dy, dx)
        ux, uy = (tx - ax) / length, (ty - ay) / length
        along = (estimate.x - ax) * ux + (estimate.y - ay) * uy
        ahead = min(max(along, 0.0) + self.config.lookahead, length)
        return math.atan2(ay + ahead * uy - estimate.y, ax + ahead * ux - estimate.x)

    def _remaining(self, estimate: Pose) -> float:
        """How far the target lies ahead along the drive's line (negative: behind; 0 before
        the drive)."""
        if self._target is None:
            return 0.0
        heading = self.move.heading
        return (self._target[0] - estimate.x) * math.cos(heading) + (
            self._target[1] - estimate.y
        ) * math.sin(heading)

    def _brake(self, then: MoveOutcome | None) -> Command:
        self.stage = MoveStage.BRAKE
        if then is not None:
            self._after_brake = then
        return STOP

    # --- helpers --------------------------------------------------------------------------------

    def _turn_rate(self, error: float, rate: float, period: float) -> float:
        """Turn rate towards a heading error, on the braking curve, after a period of coasting."""
        limits = self.config.limits
        latency = period * self.config.command_latency
        left = error - coast(rate, self._sent.angular, limits.max_angular_accel, latency)
        return signed_approach_speed(
            left,
            limits.max_angular_speed,
            limits.max_angular_accel * self.controller.braking_share,
            period,
        )

    def _note_motion(self, odom: Odom) -> None:
        if self._start_odom is None:
            self._start_odom = odom.pose
            return
        if not self._moved:
            forward, left, turn = relative(self._start_odom, odom.pose)
            self._moved = (
                math.hypot(forward, left) > self.config.progress
                or abs(turn) > self.controller.heading_tolerance
            )

    def _stalled(self, t: float, odom: Odom) -> bool:
        """No progress for stall_time while driving, in a move the robot did move in."""
        mark = self._progress_mark
        if mark is None or math.dist(mark[1][:2], odom.pose[:2]) >= self.config.progress:
            self._progress_mark = (t, odom.pose)
            return False
        return self._moved and t - mark[0] >= self.config.stall_time


def coast(velocity: float, command: float, accel: float, dt: float) -> float:
    """How far (m or rad) a robot moving at ``velocity`` goes in ``dt`` while it follows
    ``command`` within ``accel``: where the command in flight leaves it for the next one."""
    ramp = min(abs(command - velocity) / accel, dt)
    reached = velocity + math.copysign(accel * ramp, command - velocity)
    return (velocity + reached) / 2 * ramp + reached * (dt - ramp)


# --- the laser --------------------------------------------------------------------------------


@functools.lru_cache(maxsize=8)
def _beam_directions(angle_min: float, angle_increment: float, beams: int):
    """Cosine and sine of each beam's bearing: the same for every scan of one laser (a scan
    per control period)."""
    bearings = angle_min + angle_increment * np.arange(beams)
    return np.cos(bearings), np.sin(bearings)


def forward_clearance(
    ranges: Sequence[float] | np.ndarray,
    angle_min: float,
    angle_increment: float,
    radius: float,
    range_min: float = 0.0,
    range_max: float = math.inf,
) -> float:
    """How far a disc of ``radius`` centred on the laser can drive straight ahead (along the
    scan's +x) before touching a point the scan sees (m; inf when none is in the way).

    Readings outside [range_min, range_max] or not finite are no returns."""
    ranges = np.asarray(ranges, dtype=float)
    cos_bearing, sin_bearing = _beam_directions(angle_min, angle_increment, ranges.size)
    with np.errstate(invalid='ignore'):
        valid = np.isfinite(ranges) & (ranges >= range_min) & (ranges <= range_max)
    forward = ranges[valid] * cos_bearing[valid]
    side = ranges[valid] * sin_bearing[valid]
    in_way = (forward > 0) & (np.abs(side) < radius)
    if not in_way.any():
        return math.inf
    contact = forward[in_way] - np.sqrt(radius * radius - side[in_way] ** 2)
    return max(0.0, float(contact.min()))


# --- driving back to the start ------------------------------------------------------------------


def route_home(lattice: MoveLattice, pose: Pose, start: Pose) -> list[MoveGoal] | None:
    """Moves from ``pose`` back to ``start`` on the collision-free move lattice (lights
    ignored): to the nearest valid node, along a shortest lattice path with straight runs
    merged into one drive, then a turn to the start's heading. None when there is no path."""
    start_node = lattice.point_to_node(start.x, start.y)
    candidates = sorted(
        (n for n in _nodes_around(lattice, pose) if lattice.is_valid(n)),
        key=lambda n: math.dist(lattice.node_to_point(n), pose[:2]),
    )
    for node in candidates:
        path = lattice.bfs(node, lambda n: n == start_node)
        if path is not None:
            break
    else:
        return None
    moves = []
    here = pose[:2]
    for point in _corners([lattice.node_to_point(n) for n in path]):
        distance = math.dist(here, point)
        if distance > ControllerConfig().position_tolerance:
            moves.append(MoveGoal(math.atan2(point[1] - here[1], point[0] - here[0]), distance))
        here = point
    moves.append(MoveGoal(start.yaw))
    return moves


def _nodes_around(lattice: MoveLattice, pose: Pose) -> list[Node]:
    i, j = lattice.point_to_node(pose.x, pose.y)
    return [(i + di, j + dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)]


def _corners(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The points where a lattice path turns, and its end: straight runs become one drive."""
    corners = []
    for index, point in enumerate(points):
        if 0 < index < len(points) - 1:
            before, after = points[index - 1], points[index + 1]
            turn = (point[0] - before[0]) * (after[1] - point[1]) - (point[1] - before[1]) * (
                after[0] - point[0]
            )
            if abs(turn) < 1e-12:
                continue
        corners.append(point)
    return corners
