"""The environment node's ``topics`` robot interface (a :class:`stealth_env.robot.Robot`): a thin
rclpy shell that feeds ``stealth_env.topic_moves`` with ``odom``, ``amcl_pose``, ``scan`` and
``ground_truth`` and sends its commands on ``cmd_vel`` (and ``initialpose`` after a drive home).
All names are relative, so ``--ros-args -r odom:=/robot/odom`` and the like plug it into any
robot. A reset is the simulator's teleport (``reset_mode teleport``: the first state once
odometry from after it has come) or a drive back to the start along a collision-free path on
the move lattice (``drive``: lights ignored, then ``initialpose``).

Everything happens in the odometry callback (one control step per message, in the robot's
time) and the node's housekeeping tick (the watchdogs of :mod:`stealth_env.robot_watch`: a robot
that stops publishing ``odom`` for ``move_timeout`` fails its move, its drive home or its
teleport; under ``use_sim_time`` that is simulated time, and a ``/clock`` that stops advancing
for ``clock_timeout`` wall seconds fails them too); nothing blocks the executor. Only odometry
wakes the node: ``amcl_pose``, ``scan`` and (under ``use_sim_time``) ``/clock`` wait in their
queues until the next odometry message or tick takes them, before it, and ``ground_truth`` until
a move ends (``stealth_node_kit.on_demand``): a simulator in lockstep sends all five every
control period, and a wake-up for each cost the node most of its time.

Commands answer the latest odometry, one per message: a simulator may run in lockstep with
this controller (``stealth_sim.lockstep``: the next control period once the command for the
latest odometry has come), where a command sent while newer odometry is on its way would be
taken as the answer to that one and leave the controller a period behind for good. So after a
command, odometry is on its way (for ODOM_WAIT of wall time at most: then the command is taken
as lost): a new move's first command waits for it (on a robot that publishes odometry on its
own clock, at most one odometry period). While there is no odometry yet, a teleported robot
waits for its first odometry, or (under ``use_sim_time``) the robot has nothing to do, the tick
sends a zero command unless odometry is on its way: a simulator that holds its clock at rest
until commanded then lets time go on (a recorder on simulated time starts with it).
A robot that does not move on ``cmd_vel`` makes moves TIME OUT; after ``unresponsive_moves``
episode moves of them in a row it is not responding (:meth:`TopicRobot.not_responding`).
Bad messages (a pose that is not finite, an ``amcl_pose`` in a frame other than ``map``) are
dropped with a throttled one-line error naming the topic; the move goes on with the next good
one.
"""

from __future__ import annotations

from collections.abc import Callable
import functools
import math
import time

from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.qos import (
    qos_profile_sensor_data,
)
from sensor_msgs.msg import LaserScan
from stealth_core.move_lattice import MoveLattice
from stealth_core.moves import MoveOutcome
from stealth_node_kit.conversions import seconds, yaw_quaternion
from stealth_node_kit.endpoints import QUIET_PUBLISHER, QUIET_SUBSCRIPTION
from stealth_node_kit.log_throttle import Throttle
from stealth_node_kit.on_demand import OnDemand, clock_on_demand
from stealth_node_kit.qos import kept_qos

from stealth_env.env_messages import pose_of
from stealth_env.robot import MoveEnd, OnMoveEnd, OnReset, failed
from stealth_env.robot_watch import ClockWatch, Silence, silence_reason
from stealth_env.service_robot import Teleport
from stealth_env.topic_moves import (
    STOP,
    Command,
    MoveGoal,
    Odom,
    Pose,
    PoseTracker,
    TopicConfig,
    TopicMove,
    forward_clearance,
    pose_problem,
    route_home,
)

TOPICS = {
    'cmd_vel': 'cmd_vel',
    'odom': 'odom',
    'estimate': 'amcl_pose',
    'scan': 'scan',
    'truth': 'ground_truth',
    'initial_pose': 'initialpose',
}
BAD_MESSAGE_LOG_PERIOD = 5.0  # s of wall time between lines about one topic's bad messages
TRUTH_WAIT = 1.0  # s of wall time a finished move waits for the ground truth of its end
CLOCK_TIMEOUT = 10.0  # wall s without an advancing /clock (use_sim_time) that fail a move
ODOM_WAIT = 0.5  # wall s after a command within which its odometry is awaited
# nav2's AMCL publishes amcl_pose reliable and transient local (the last one to late joiners).
ESTIMATE_QOS = kept_qos(5)


class TopicRobot:
    """One move (or a drive home of several) at a time over the robot's standard topics.

    `teleport`: the reset of ``reset_mode teleport`` (None: drive home over `lattice`);
    `move_timeout`, `clock_timeout`: the node's parameters (they can change).
    """

    def __init__(
        self,
        node,
        config: TopicConfig,
        map_frame: str,
        lattice: MoveLattice,
        teleport: Teleport | None,
        unresponsive_moves: int,
        move_timeout: Callable[[], float],
        clock_timeout: Callable[[], float] = lambda: CLOCK_TIMEOUT,
    ):
        self.node = node
        self.config = config
        self.map_frame = map_frame
        self.lattice = lattice
        self.teleport = teleport
        self.unresponsive_moves = unresponsive_moves
        self._move_timeout = move_timeout
        self._clock_timeout = clock_timeout
        self._unresponsive = 0  # episode moves in a row that timed out without the robot moving
        self._judged_on_estimate = False  # said once: no ground truth, judged on the estimate
        self._on_silent: Callable[[str], None] | None = None  # the running moves' failure
        self.tracker = PoseTracker()
        self._scan: LaserScan | None = None
        self._truth: tuple[float, Pose] | None = None
        self._moves: list[MoveGoal] = []  # still to run after the current one
        self._move: TopicMove | None = None
        self._on_end: Callable[[MoveEnd], None] | None = None
        self._ending: tuple[MoveEnd, float] | None = None  # waiting for the truth, since (wall)
        self._on_placed: Callable[[], None] | None = None
        self._on_not_placed: Callable[[str], None] | None = None  # a teleport's failure
        self._odom_silence = Silence()  # on the robot's clock (_now)
        self._awaiting: float | None = None  # wall time of a command no odometry came after
        self._deferred = False  # the move's first command waits for the odometry on its way
        self._clock_watch = ClockWatch()
        self._bad_log: dict[tuple[str, str], Throttle] = {}  # by topic and kind of problem
        self.bad_messages = dict.fromkeys(TOPICS, 0)
        quiet = QUIET_SUBSCRIPTION
        sensor = qos_profile_sensor_data  # best effort: matches reliable writers too
        node.create_subscription(
            Odometry, TOPICS['odom'], self._on_odom, sensor, event_callbacks=quiet
        )
        # Taken when odometry comes (and at each tick), not each on its own wake-up.
        self._pending = OnDemand()
        clock_on_demand(node, self._pending)  # under use_sim_time: /clock first
        node.create_subscription(
            PoseWithCovarianceStamped,
            TOPICS['estimate'],
            self._on_estimate,
            ESTIMATE_QOS,
            event_callbacks=quiet,
            callback_group=self._pending,
        )
        node.create_subscription(
            LaserScan,
            TOPICS['scan'],
            self._on_scan,
            sensor,
            event_callbacks=quiet,
            callback_group=self._pending,
        )
        self._truths = OnDemand()  # only a move's end needs the ground truth: taken then
        self._truth_sub = node.create_subscription(
            Odometry,
            TOPICS['truth'],
            self._on_truth,
            sensor,
            event_callbacks=quiet,
            callback_group=self._truths,
        )
        self._cmd_pub = node.create_publisher(
            Twist, TOPICS['cmd_vel'], 10, event_callbacks=QUIET_PUBLISHER
        )
        self._initial_pose_pub = node.create_publisher(
            PoseWithCovarianceStamped, TOPICS['initial_pose'], 10, event_callbacks=QUIET_PUBLISHER
        )

    # --- what the node asks ---------------------------------------------------------------------

    def ready(self) -> bool:
        """Odometry and a localisation estimate have come (and the teleport answers)."""
        if self.teleport is not None and not self.teleport.ready():
            return False
        return self.tracker.estimate is not None

    def describe(self) -> str:
        names = ', '.join(self.node.resolve_topic_name(t) for t in TOPICS.values())
        moves = f'topics ({names}'
        if self.teleport is not None:
            return f'{moves}, {self.teleport.describe()})'
        return f'{moves}; reset by driving to the start)'

    @property
    def scan(self) -> LaserScan | None:
        """The latest laser scan (None before one came), including any waiting to be taken."""
        self._pending.drain()
        return self._scan

    @property
    def busy(self) -> bool:
        return self._move is not None or self._ending is not None or bool(self._moves)

    def waiting_for(self) -> str:
        topics = [TOPICS['odom']] if self.tracker.latest is None else []
        if self.tracker.estimate is None:
            topics.append(f'{TOPICS["estimate"]} (frame {self.map_frame})')
        return ' and '.join(topics)

    def run(self, move: MoveGoal, on_end: OnMoveEnd) -> None:
        """One move of an episode: its end counts towards :meth:`not_responding`."""
        self._run_moves([move], functools.partial(self._episode_move_end, on_end),
                        lambda reason: on_end(failed(reason)))  # fmt: skip

    def _episode_move_end(self, on_end: OnMoveEnd, end: MoveEnd) -> None:
        if end.outcome is not None:
            timed_out = end.outcome == MoveOutcome.TIMED_OUT
            self._unresponsive = self._unresponsive + 1 if timed_out and not end.moved else 0
            if end.truth is None and not self._judged_on_estimate and not self.not_responding():
                self._judged_on_estimate = True
                self.node.get_logger().warning(
                    f'no {self.node.resolve_topic_name(TOPICS["truth"])} is published: steps '
                    'are judged on the localisation estimate (StepInfo.true_pose is NaN)'
                )
        on_end(end)

    def not_responding(self) -> str:
        if self._unresponsive < self.unresponsive_moves:
            return ''
        cmd_vel = self.node.resolve_topic_name(TOPICS['cmd_vel'])
        return (
            f'the robot is not responding to {cmd_vel}: {self._unresponsive} moves in a row '
            'timed out without it moving (is it running, and is cmd_vel remapped to its topic?)'
        )

    def reset(self, pose: Pose, on_done: OnReset) -> None:
        """Teleport to `pose` (the first state once odometry from after it has come), or drive
        there and tell the localisation."""
        if self.teleport is None:
            self._drive_home(pose, on_done)
            return

        def placed(problem: str) -> None:
            if problem:
                on_done(problem, -math.inf)
            else:
                self.restart(
                    pose, lambda: on_done('', self._clock()), lambda why: on_done(why, -math.inf)
                )

        self.teleport.place(pose, placed)

    def _drive_home(self, start: Pose, on_done: OnReset) -> None:
        here = self.tracker.estimate
        moves = route_home(self.lattice, here, start) if here is not None else None
        if moves is None:
            on_done(f'no collision-free path from {here} to the start', -math.inf)
            return

        def arrived(end: MoveEnd) -> None:
            if end.outcome != MoveOutcome.DONE:
                outcome = 'no move' if end.outcome is None else end.outcome.name
                on_done(f'driving to the start: {outcome} {end.message}', -math.inf)
                return
            self.set_initial_pose(start)
            on_done('', self._clock())

        self._run_moves(moves, arrived, lambda reason: on_done(reason, -math.inf))

    def _clock(self) -> float:
        """The robot's clock by its latest odometry (s; -inf before any)."""
        latest = self.tracker.latest
        return latest.t if latest is not None else -math.inf

    def _run_moves(
        self, moves: list[MoveGoal], on_end: OnMoveEnd, on_silent: Callable[[str], None]
    ) -> None:
        """Run the moves one after the other; ``on_end`` gets the last one's end, or the first
        that was not DONE; ``on_silent`` why they failed when odometry stops."""
        self._stop()
        self._moves = list(moves)
        self._on_end, self._on_silent = on_end, on_silent
        self._odom_silence.heard(self._now())  # silence counts from now
        self._next_move()

    def cancel(self) -> None:
        """Drop what is running (its end will not be reported) and stop the robot."""
        self._stop()
        if self.teleport is not None:
            self.teleport.cancel()

    def _stop(self) -> None:
        if self.busy:
            self.send(STOP)
        self._moves, self._move, self._ending, self._on_end = [], None, None, None
        self._on_silent = None
        self._on_placed = self._on_not_placed = None
        self._deferred = False

    def restart(
        self,
        pose: Pose,
        on_placed: Callable[[], None],
        on_not_placed: Callable[[str], None] | None = None,
    ) -> None:
        """The robot was teleported to ``pose``: ``on_placed`` once odometry after it came, or
        ``on_not_placed`` why none came (the watchdogs)."""
        latest = self.tracker.latest
        self.tracker.restart(pose, after=latest.t if latest else -math.inf)
        self._on_placed, self._on_not_placed = on_placed, on_not_placed
        self._odom_silence.heard(self._now())

    def set_initial_pose(self, pose: Pose) -> None:
        """Tell the localisation where the robot is (AMCL's initialpose, zero covariance: its
        default spread) and take it as the estimate from now on."""
        message = PoseWithCovarianceStamped()
        message.header.frame_id = self.map_frame
        message.header.stamp = self.node.get_clock().now().to_msg()
        message.pose.pose.position.x, message.pose.pose.position.y = pose.x, pose.y
        message.pose.pose.orientation = yaw_quaternion(pose.yaw)
        self._initial_pose_pub.publish(message)
        self.tracker.place(pose)

    def send(self, command: Command) -> None:
        twist = Twist()
        twist.linear.x, twist.angular.z = float(command.linear), float(command.angular)
        self._cmd_pub.publish(twist)
        if self._awaiting is None:
            self._awaiting = time.monotonic()

    def _odom_coming(self) -> bool:
        """Whether odometry answering a command sent since the latest one is on its way."""
        return self._awaiting is not None and time.monotonic() - self._awaiting < ODOM_WAIT

    def sim_time(self) -> bool:
        """Whether the node runs on simulated time (use_sim_time): the robot's clock."""
        return bool(self.node.get_parameter('use_sim_time').value)

    def _now(self) -> float:
        """The robot's clock now (s): /clock under use_sim_time, else the wall clock."""
        if self.sim_time():
            return self.node.get_clock().now().nanoseconds * 1e-9
        return time.monotonic()

    def silent_for(self) -> float:
        """Seconds of the robot's clock without odometry since the robot was last given
        something to do."""
        return self._odom_silence.silent_for(self._now())

    def tick(self) -> None:
        """Housekeeping: the teleport's deadline; a robot with no odometry yet, waiting to be
        placed or idle on simulated time gets a zero command (a simulator that holds its clock
        at rest lets it run); a
        move's end stops waiting for the truth; and a robot that stops publishing odometry (or
        whose /clock stops) while it has something to do fails it, as a simulator that does not
        answer does."""
        self._drain()
        wall = time.monotonic()
        waiting = self.busy or self._on_placed is not None
        sim_time = self.sim_time()
        if sim_time:
            self._clock_watch.observe(self.node.get_clock().now().nanoseconds, wall, waiting)
        if self.teleport is not None:
            self.teleport.tick()
        blind = self._on_placed is not None or self.tracker.latest is None
        if (blind or sim_time and not waiting) and not self._odom_coming():
            self.send(STOP)
        if self._deferred and self._move is not None and not self._odom_coming():
            self._control()  # the odometry awaited did not come: go on without it
        if self._ending is not None and wall - self._ending[1] > TRUTH_WAIT:
            self._report(self._ending[0])
        if not waiting:
            return
        reason = silence_reason(
            sim_time=sim_time,
            clock_silent=self._clock_watch.silence.silent_for(wall),
            clock_timeout=self._clock_timeout(),
            odom_silent=self.silent_for(),
            move_timeout=self._move_timeout(),
            clock_topic=self.node.resolve_topic_name('/clock'),
            odom_topic=self.node.resolve_topic_name(TOPICS['odom']),
        )
        if not reason:
            return
        on_silent = self._on_silent or self._on_not_placed
        self._stop()
        if on_silent is not None:
            on_silent(reason)

    # --- messages -------------------------------------------------------------------------------

    def _bad(self, key: str, problem: str) -> None:
        self.bad_messages[key] += 1
        kind = (key, problem.split(' ', 1)[0])  # 'frame', 'pose', 'velocities'
        throttle = self._bad_log.setdefault(kind, Throttle(BAD_MESSAGE_LOG_PERIOD))
        if throttle():
            self.node.get_logger().error(
                f'{TOPICS[key]}: message dropped, {problem} ({self.bad_messages[key]} so far)'
            )

    def _on_odom(self, message: Odometry) -> None:
        self._drain()  # what came before it: the clock, estimate, scan (ground truth)
        pose = pose_of(message.pose.pose)
        problem = pose_problem(*pose)
        twist = message.twist.twist
        if not problem and not (math.isfinite(twist.linear.x) and math.isfinite(twist.angular.z)):
            problem = f'velocities ({twist.linear.x}, {twist.angular.z}) are not finite'
        if problem:
            self._bad('odom', problem)
            return
        self._odom_silence.heard(self._now())
        self._awaiting = None
        self.tracker.add_odom(Odom(seconds(message.header.stamp), pose, twist.linear.x,
                                   twist.angular.z))  # fmt: skip
        if self._on_placed is not None and self.tracker.estimate is not None:
            on_placed, self._on_placed, self._on_not_placed = self._on_placed, None, None
            on_placed()
        if self._move is not None:
            self._control()

    def _drain(self, truth: bool = False) -> None:
        """Take what came on the topics taken on demand; the ground truth only at a move's end
        (``truth``) or while that end waits for it: converting one each control period was
        ~0.1 ms of the node's ~1.4 ms (measured), and its queue keeps the latest."""
        self._pending.drain()
        if truth or self._ending is not None:
            self._truths.drain()

    def _on_estimate(self, message: PoseWithCovarianceStamped) -> None:
        pose = pose_of(message.pose.pose)
        problem = pose_problem(*pose, message.header.frame_id, self.map_frame)
        if problem:
            self._bad('estimate', problem)
            return
        self.tracker.add_estimate(seconds(message.header.stamp), pose)

    def _on_scan(self, message: LaserScan) -> None:
        self._scan = message

    def _on_truth(self, message: Odometry) -> None:
        pose = pose_of(message.pose.pose)
        problem = pose_problem(*pose, message.header.frame_id, self.map_frame)
        if problem:
            self._bad('truth', problem)
            return
        t = seconds(message.header.stamp)
        self._truth = (t, pose)
        if self._ending is not None and t >= self._ending[0].t:
            self._report(self._ending[0])

    # --- moves ----------------------------------------------------------------------------------

    def _next_move(self) -> None:
        latest, estimate = self.tracker.latest, self.tracker.estimate
        if estimate is None:
            self._end(failed(f'no pose of the robot ({self.waiting_for()})'))
            return
        self._move = TopicMove(self._moves.pop(0), estimate, latest.t, self.config)
        self._deferred = self._odom_coming()  # then it starts on the odometry coming
        if not self._deferred:
            self._control()

    def _control(self) -> None:
        self._deferred = False
        odom, estimate = self.tracker.latest, self.tracker.estimate
        result = self._move.update(
            odom.t, estimate, odom, self._clearance(odom), self.tracker.period
        )
        if isinstance(result, Command):
            self.send(result)
            return
        self._move = None
        self.send(STOP)
        end = MoveEnd(result.outcome, result.message, estimate, None, odom.t, result.moved)
        if result.outcome == MoveOutcome.DONE and self._moves:
            self._next_move()
        else:
            self._end(end)

    def _end(self, end: MoveEnd) -> None:
        self._moves = []
        self._drain(truth=True)  # the ground truth of the end may have come meanwhile
        if end.outcome is not None and self._truth_sub.get_publisher_count():
            truth = self._truth
            if truth is None or truth[0] < end.t:  # its ground truth is still on the way
                self._ending = (end, time.monotonic())
                return
        self._report(end)

    def _report(self, end: MoveEnd) -> None:
        self._ending = None
        if self._truth is not None:
            end = end._replace(truth=self._truth[1])
        on_end, self._on_end, self._on_silent = self._on_end, None, None
        if on_end is not None:
            on_end(end)

    def _clearance(self, odom: Odom) -> float:
        """Forward clearance from the latest scan, less what the robot drove since it."""
        scan = self._scan
        if scan is None or not scan.ranges:
            return math.inf
        clearance = forward_clearance(
            np.asarray(scan.ranges, dtype=float),
            scan.angle_min,
            scan.angle_increment,
            self.config.robot_radius,
            scan.range_min,
            scan.range_max,
        )
        age = max(0.0, odom.t - seconds(scan.header.stamp))
        return clearance - max(0.0, odom.linear) * age
