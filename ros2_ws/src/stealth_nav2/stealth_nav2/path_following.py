"""Following a planned path, stamped or not, as moves of the project's controller
(``stealth_env.topic_moves``: a turn and a drive to a point, or a hold). Plain Python, no rclpy:
the navigator node feeds it poses and times and runs the moves it asks for.

A path is a list of :class:`TimedPose` (map frame; ``t`` is the pose's header stamp in seconds
of the robot's clock). Nav2's planners stamp every pose with the same time: such a path is
**untimed**, and the robot drives it as fast as its limits allow. The covert planner stamps each
pose with when to be there (where lights move, the plan waits for a beam to look away): a path
whose stamps rise is **timed**, and its stamps bind:

- **legs**: the path becomes legs, each a drive to a point, a turn in place or a wait, ending at
  one of the path's poses; straight runs become one drive (for a timed path only where the
  stamps along the run advance evenly, so the run can be paced), a pose at the same place with
  another heading a turn, one with a later stamp a wait;
- **pace**: a timed drive is given the speed that ends it at its last pose's stamp (never above
  the robot's limit), so it passes the poses along a run near their own stamps rather than ahead
  of them; a leg that ends early holds until its stamp. A leg is **late** once it runs more than
  ``max_lateness`` past the later of its stamp and the soonest the robot could end it (from when
  it started: the turn and the drive at the limits, their speed ramps, the rests between), so
  stamps the robot cannot keep (a static scene's nominal 1 s a step) are followed as fast as it
  can, while a robot held up (load, a slow start) asks for a new plan from where and when it is
  (not a recovery: Nav2 replans as it goes too). Checked as a leg runs once the plan's first
  turn or drive has finished (which always does, so replanning cannot keep the robot from
  getting on), and at each leg's end;
- **steering**: each drive follows its leg's line (``MoveGoal.line_from``), steering back onto
  it a lookahead ahead when a localisation update moved the estimate off it;
- **recoveries**: a move that ends BUMPED (blocked) or TIMED_OUT, and a robot more than
  ``stray_distance`` off its leg, ask for a new plan as a recovery (the navigator counts them);
  a blocked one backs off first (``back_off``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import dataclasses
import enum
import math
from typing import NamedTuple

from stealth_core.kinematics import wrap_angle
from stealth_env.topic_moves import Limits, MoveGoal, MoveOutcome, Pose, go_to, hold_goal

SAME_PLACE = 0.01  # m: poses closer than this are at one place (a turn or a wait there)
STRAIGHT = 1e-3  # rad: drives whose directions differ by less than this are one straight run
EVEN_PACE = 0.05  # relative: a run's stamps advance evenly when speeds agree this closely
MIN_HOLD = 0.05  # s: an early arrival by less than this is on time
SETTLE = 0.5  # s a leg's turn and drive each may take to come to rest, beyond the ramps


class TimedPose(NamedTuple):
    """One pose of a path: map frame (m, rad) and its stamp (s of the robot's clock)."""

    x: float
    y: float
    yaw: float
    t: float


class LegKind(enum.Enum):
    DRIVE = 'drive'
    TURN = 'turn'
    WAIT = 'wait'


class Leg(NamedTuple):
    """A part of the path run as one move (then a hold until ``arrive_by`` when early)."""

    kind: LegKind
    x0: float  # where the leg starts (m, map): a pose of the path, or the robot's start
    y0: float
    x: float  # where it ends
    y: float
    heading: float  # the direction a DRIVE drives in, the heading a TURN turns to (rad)
    t0: float | None  # the stamp of the pose it starts from (None: the robot's start)
    arrive_by: float | None  # the stamp of its last pose (timed paths), else None
    last: int  # index of the pose it ends at


@dataclasses.dataclass(frozen=True)
class FollowSettings:
    """How closely a path is followed, and the robot's limits the legs are paced within."""

    limits: Limits = Limits()
    heading_tolerance: float = 0.1  # rad: a pose's heading this close needs no turn
    join_distance: float = 0.25  # m: a robot this close to the first pose starts from it
    max_lateness: float = 1.5  # s late at a pose's stamp: replan (timed paths)
    stray_distance: float = 0.5  # m off the current leg: replan
    min_pace_speed: float = 0.05  # m/s: a paced drive never crawls slower


def path_problem(poses: Sequence[TimedPose]) -> str:
    """Why a path cannot be followed ('' when it can)."""
    if not poses:
        return 'the path has no poses'
    for index, pose in enumerate(poses):
        if not all(math.isfinite(value) for value in pose):
            return f'pose {index} of the path is not finite: {tuple(pose)}'
        if index and pose.t < poses[index - 1].t:
            return (
                f'pose {index} of the path is stamped {pose.t:.3f} s, before pose {index - 1} '
                f'({poses[index - 1].t:.3f} s): stamps must not go back'
            )
    return ''


def is_timed(poses: Sequence[TimedPose]) -> bool:
    """Whether the path's stamps say when to be where (they rise), rather than all being the
    path's own stamp (Nav2's planners)."""
    return len(poses) > 1 and poses[-1].t > poses[0].t


def legs_of(poses: Sequence[TimedPose], start: Pose, settings: FollowSettings) -> list[Leg]:
    """The legs that follow the path from ``start`` (the robot's estimate): from the first
    pose when the robot is within ``join_distance`` of it, else from the robot's place."""
    timed = is_timed(poses)
    legs: list[Leg] = []
    first = poses[0]
    joined = math.dist((start.x, start.y), (first.x, first.y)) <= settings.join_distance
    x, y = start.x, start.y
    t = None  # the stamp of the pose the robot is at (None: off the path, at its start)
    heading = start.yaw
    for index, pose in enumerate(poses):
        arrive_by = pose.t if timed else None
        if index == 0 and joined:
            x, y, t = first.x, first.y, arrive_by
            if timed:  # be at the first pose at its stamp too (a plan may start on a later bin)
                legs.append(Leg(LegKind.WAIT, x, y, x, y, heading, None, arrive_by, 0))
            continue
        if math.dist((x, y), (pose.x, pose.y)) > SAME_PLACE:
            direction = math.atan2(pose.y - y, pose.x - x)
            leg = Leg(LegKind.DRIVE, x, y, pose.x, pose.y, direction, t, arrive_by, index)
            if legs and _continues(legs[-1], leg):
                previous = legs[-1]
                legs[-1] = leg._replace(x0=previous.x0, y0=previous.y0, t0=previous.t0)
            else:
                legs.append(leg)
            x, y, t, heading = pose.x, pose.y, arrive_by, direction
            continue
        if index == 0:
            continue  # the first pose's heading is where the planner thought the robot faced
        if abs(wrap_angle(pose.yaw - heading)) > settings.heading_tolerance:
            legs.append(Leg(LegKind.TURN, x, y, x, y, pose.yaw, t, arrive_by, index))
            heading = pose.yaw
        elif timed and pose.t > t:
            legs.append(Leg(LegKind.WAIT, x, y, x, y, heading, t, arrive_by, index))
        t = arrive_by
    final = poses[-1]
    if abs(wrap_angle(final.yaw - heading)) > settings.heading_tolerance:
        # The goal's orientation (the last pose's), after driving in from another direction.
        arrive_by = final.t if timed else None
        legs.append(Leg(LegKind.TURN, x, y, x, y, final.yaw, arrive_by, arrive_by,
                        len(poses) - 1))  # fmt: skip
    return legs


def _continues(previous: Leg, leg: Leg) -> bool:
    """Whether ``leg`` carries ``previous`` on in a straight line (at an even pace: the same
    speed by the stamps, when timed)."""
    if previous.kind is not LegKind.DRIVE or (previous.x, previous.y) != (leg.x0, leg.y0):
        return False
    if abs(wrap_angle(leg.heading - previous.heading)) > STRAIGHT:
        return False
    if leg.arrive_by is None:
        return True
    if previous.t0 is None:
        return False  # the drive onto the path is paced on its own
    run_time, step_time = previous.arrive_by - previous.t0, leg.arrive_by - leg.t0
    if run_time <= 0 or step_time <= 0:
        return False
    run = math.dist((previous.x0, previous.y0), (previous.x, previous.y))
    step = math.dist((leg.x0, leg.y0), (leg.x, leg.y))
    return math.isclose(run / run_time, step / step_time, rel_tol=EVEN_PACE)


class Move(NamedTuple):
    """A move for the controller: the goal, within these limits (a paced drive is slower)."""

    goal: MoveGoal
    limits: Limits
    leg: int  # index of the leg it runs (a hold: the leg it waits at the end of)


class Replan(NamedTuple):
    """The path cannot be followed on from here: plan again (a recovery, unless only late)."""

    reason: str
    recovery: bool = True
    blocked: bool = False  # the move ended BUMPED: back off first (``back_off``)


class Arrived(NamedTuple):
    """The last leg is done."""

    lateness: float  # s after the last pose's stamp (timed paths; 0 when untimed or early)


class PathFollower:
    """One path being followed: ``next_move`` says what to run, ``move_ended`` takes its end.

    Times are seconds of the robot's clock (odometry stamps), the clock of the path's
    stamps."""

    def __init__(
        self,
        poses: Sequence[TimedPose],
        start: Pose,
        settings: FollowSettings,
        now: float | None = None,
        keep_clear: Callable[[list[Leg]], list[Leg]] | None = None,
    ):
        """``now``: the robot's clock as the path arrives; a timed path that is already late
        then (planning took time) is allowed that much more lateness. ``keep_clear``: what
        moves the legs off walls (``leg_clearance``), if anything."""
        problem = path_problem(poses)
        if problem:
            raise ValueError(problem)
        self.poses = list(poses)
        self.settings = settings
        self.timed = is_timed(poses)
        late = 0.0 if now is None or not self.timed else now - self.poses[0].t
        self.max_lateness = settings.max_lateness + max(0.0, late)
        self.legs = legs_of(self.poses, start, settings)
        if keep_clear is not None:
            self.legs = keep_clear(self.legs)
        self.leg = 0  # the leg running or next
        self._heading = start.yaw  # the heading the robot starts the next leg with
        self._due: float | None = None  # when the running leg is due to end (timed paths)
        self._moved_legs = 0  # legs whose turn or drive has finished
        self._holding = False  # the current leg's motion is done; holding until its stamp
        self._lengths = _cumulative_lengths(self.poses)

    @property
    def waits(self) -> int:
        """How many times a timed path stays at one place to a later stamp (a wait for a light;
        a leg of its own, or the hold after a turn there)."""
        if not self.timed:
            return 0
        pairs = zip(self.poses, self.poses[1:], strict=False)
        return sum(math.dist(a[:2], b[:2]) <= SAME_PLACE and b.t > a.t for a, b in pairs)

    @property
    def end(self) -> tuple[float, float]:
        """Where the robot is to end up: the last leg's end (the path's last pose, unless the
        legs were moved off a wall)."""
        if self.legs:
            return self.legs[-1].x, self.legs[-1].y
        return self.poses[-1].x, self.poses[-1].y

    @property
    def done(self) -> bool:
        return self.leg >= len(self.legs)

    def next_move(self, now: float) -> Move | Arrived:
        """The move to run now (after the previous one ended)."""
        limits = self.settings.limits
        while self.leg < len(self.legs):
            leg = self.legs[self.leg]
            if self._holding or leg.kind is LegKind.WAIT:
                early = None if leg.arrive_by is None else leg.arrive_by - now
                if early is not None and early > MIN_HOLD:
                    self._holding = True
                    return Move(hold_goal(early), limits, self.leg)
                self._holding = False
                self.leg += 1
                continue
            self._due = None
            if leg.arrive_by is not None:
                self._due = max(leg.arrive_by, now + self._soonest(leg))
            if leg.kind is LegKind.TURN:
                return Move(MoveGoal(leg.heading), limits, self.leg)
            return Move(go_to(leg.x, leg.y, (leg.x0, leg.y0)), self._paced(leg, now), self.leg)
        return Arrived(max(0.0, now - self.poses[-1].t) if self.timed else 0.0)

    def move_ended(
        self, outcome: MoveOutcome, message: str, now: float, estimate: Pose
    ) -> Replan | None:
        """The running move ended: None to go on (``next_move``), or a :class:`Replan`."""
        if outcome is not MoveOutcome.DONE:
            what = 'blocked' if outcome is MoveOutcome.BUMPED else 'the move timed out'
            blocked = outcome is MoveOutcome.BUMPED
            return Replan(f'{what}: {message}' if message else what, blocked=blocked)
        if self._holding:  # the hold at the end of the leg is over
            self._holding = False
            self.leg += 1
            return None
        leg = self.legs[self.leg]
        self._heading = leg.heading
        self._moved_legs += 1
        off = math.dist((estimate.x, estimate.y), (leg.x, leg.y))
        if off > self.settings.stray_distance:
            return Replan(f'strayed: ended {off:.2f} m from the path at ({leg.x:.2f}, '
                          f'{leg.y:.2f})')  # fmt: skip
        if self._due is not None and now - self._due > self.max_lateness:
            late = now - leg.arrive_by
            return Replan(f'{late:.1f} s late at pose {leg.last} of the path, '
                          f'{now - self._due:.1f} s more than the robot needed (allowed '
                          f'{self.max_lateness:.1f} s)', recovery=False)  # fmt: skip
        self._holding = True  # hold until the leg's stamp if early, then the next leg
        return None

    def behind(self, now: float) -> Replan | None:
        """A :class:`Replan` once the leg running is late (a timed path; checked while it
        runs, once a leg of the plan has been driven)."""
        if self.done or self._holding or self._moved_legs == 0 or self._due is None:
            return None
        if now - self._due <= self.max_lateness:
            return None
        leg = self.legs[self.leg]
        return Replan(f'{now - leg.arrive_by:.1f} s behind pose {leg.last} of the path, '
                      f'{now - self._due:.1f} s more than the robot needed (allowed '
                      f'{self.max_lateness:.1f} s)', recovery=False)  # fmt: skip

    def off_path(self, estimate: Pose) -> float:
        """How far the robot is from the leg it runs (m): from the segment a drive runs along,
        from the place a turn or a wait is at."""
        if self.done:
            return 0.0
        leg = self.legs[self.leg]
        if leg.kind is LegKind.DRIVE and not self._holding:
            start = (leg.x0, leg.y0)
        else:
            start = (leg.x, leg.y)
        return _segment_distance((estimate.x, estimate.y), start, (leg.x, leg.y))

    def distance_remaining(self, estimate: Pose) -> float:
        """Path length left (m): from the robot to the end of the leg it runs, then along the
        path to its last pose."""
        if self.done:
            return 0.0
        leg = self.legs[self.leg]
        here = math.dist((estimate.x, estimate.y), (leg.x, leg.y))
        return here + self._lengths[-1] - self._lengths[leg.last]

    def time_remaining(self, estimate: Pose, now: float) -> float:
        """Seconds to the end: to the last pose's stamp on a timed path, else the distance left
        at the speed limit."""
        if self.timed:
            return max(0.0, self.poses[-1].t - now)
        return self.distance_remaining(estimate) / self.settings.limits.max_linear_speed

    def _soonest(self, leg: Leg) -> float:
        """The least time the leg can take (s): its turn and its drive at the limits, with
        their speed ramps and a rest after each."""
        limits = self.settings.limits
        turn = abs(wrap_angle(leg.heading - self._heading))
        took = 0.0
        if turn > self.settings.heading_tolerance:
            took += turn / limits.max_angular_speed
            took += limits.max_angular_speed / limits.max_angular_accel + SETTLE
        distance = math.dist((leg.x0, leg.y0), (leg.x, leg.y))
        if leg.kind is LegKind.DRIVE and distance > 0:
            took += distance / limits.max_linear_speed
            took += limits.max_linear_speed / limits.max_linear_accel + SETTLE
        return took

    def _paced(self, leg: Leg, now: float) -> Limits:
        """The limits of a drive that should end at its stamp: the speed that takes the time
        left after the turn onto it and the speed ramps, within the robot's limit."""
        limits = self.settings.limits
        if leg.arrive_by is None:
            return limits
        distance = math.dist((leg.x0, leg.y0), (leg.x, leg.y))
        turn = abs(wrap_angle(leg.heading - self._heading)) / limits.max_angular_speed
        ramps = limits.max_linear_speed / limits.max_linear_accel
        available = leg.arrive_by - now - turn - ramps
        if available <= 0 or distance <= 0:
            return limits
        speed = max(self.settings.min_pace_speed, distance / available)
        if speed >= limits.max_linear_speed:
            return limits
        return dataclasses.replace(limits, max_linear_speed=speed)


def _cumulative_lengths(poses: Sequence[TimedPose]) -> list[float]:
    lengths = [0.0]
    for a, b in zip(poses, poses[1:], strict=False):
        lengths.append(lengths[-1] + math.dist((a.x, a.y), (b.x, b.y)))
    return lengths


def _segment_distance(p, a, b) -> float:
    """Distance from point p to the segment a-b."""
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    length_sq = dx * dx + dy * dy
    if length_sq == 0:
        return math.dist(p, a)
    s = min(1.0, max(0.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / length_sq))
    return math.dist(p, (ax + s * dx, ay + s * dy))
