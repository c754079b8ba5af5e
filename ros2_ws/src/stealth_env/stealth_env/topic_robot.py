"""The environment node's ``topics`` robot interface: a thin rclpy shell that feeds
``stealth_env.topic_moves`` with ``odom``, ``amcl_pose``, ``scan`` and ``ground_truth`` and sends
its commands on ``cmd_vel`` (and ``initialpose`` after a drive home). All names are relative, so
``--ros-args -r odom:=/robot/odom`` and the like plug it into any robot.

Everything happens in the odometry callback (one control step per message, in the robot's
time) and the node's housekeeping tick (wall-clock watchdogs); nothing blocks the executor.
Bad messages (a pose that is not finite, an ``amcl_pose`` in a frame other than ``map``) are
dropped with a throttled one-line error naming the topic; the move goes on with the next good
one.
"""

from __future__ import annotations

from collections.abc import Callable
import math
import time
from typing import NamedTuple

from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.qos import (
    qos_profile_sensor_data,
)
from sensor_msgs.msg import LaserScan
from stealth_node_kit.conversions import quaternion_yaw, seconds, yaw_quaternion
from stealth_node_kit.endpoints import QUIET_PUBLISHER, QUIET_SUBSCRIPTION
from stealth_node_kit.qos import kept_qos

from stealth_env.log_throttle import Throttle
from stealth_env.topic_moves import (
    STOP,
    Command,
    MoveGoal,
    MoveOutcome,
    Odom,
    Pose,
    PoseTracker,
    TopicConfig,
    TopicMove,
    forward_clearance,
    pose_problem,
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
# nav2's AMCL publishes amcl_pose reliable and transient local (the last one to late joiners).
ESTIMATE_QOS = kept_qos(5)


class MoveEnd(NamedTuple):
    """What a finished move hands back: outcome (None: it could not be run), poses, time."""

    outcome: MoveOutcome | None
    message: str
    estimate: Pose | None
    truth: Pose | None  # None when no ground truth is published
    t: float  # the robot's clock at the end (s)
    moved: bool


class TopicRobot:
    """One move (or a drive home of several) at a time over the robot's standard topics."""

    def __init__(self, node, config: TopicConfig, map_frame: str):
        self.node = node
        self.config = config
        self.map_frame = map_frame
        self.tracker = PoseTracker()
        self._scan: LaserScan | None = None
        self._truth: tuple[float, Pose] | None = None
        self._moves: list[MoveGoal] = []  # still to run after the current one
        self._move: TopicMove | None = None
        self._on_end: Callable[[MoveEnd], None] | None = None
        self._ending: tuple[MoveEnd, float] | None = None  # waiting for the truth, since (wall)
        self._on_placed: Callable[[], None] | None = None
        self._last_odom_wall = -math.inf
        self._bad_log: dict[tuple[str, str], Throttle] = {}  # by topic and kind of problem
        self.bad_messages = dict.fromkeys(TOPICS, 0)
        quiet = QUIET_SUBSCRIPTION
        sensor = qos_profile_sensor_data  # best effort: matches reliable writers too
        node.create_subscription(
            Odometry, TOPICS['odom'], self._on_odom, sensor, event_callbacks=quiet
        )
        node.create_subscription(
            PoseWithCovarianceStamped,
            TOPICS['estimate'],
            self._on_estimate,
            ESTIMATE_QOS,
            event_callbacks=quiet,
        )
        node.create_subscription(
            LaserScan, TOPICS['scan'], self._on_scan, sensor, event_callbacks=quiet
        )
        self._truth_sub = node.create_subscription(
            Odometry, TOPICS['truth'], self._on_truth, sensor, event_callbacks=quiet
        )
        self._cmd_pub = node.create_publisher(
            Twist, TOPICS['cmd_vel'], 10, event_callbacks=QUIET_PUBLISHER
        )
        self._initial_pose_pub = node.create_publisher(
            PoseWithCovarianceStamped, TOPICS['initial_pose'], 10, event_callbacks=QUIET_PUBLISHER
        )

    # --- what the node asks ---------------------------------------------------------------------

    @property
    def ready(self) -> bool:
        """Odometry and a localisation estimate have come."""
        return self.tracker.estimate is not None

    @property
    def busy(self) -> bool:
        return self._move is not None or self._ending is not None or bool(self._moves)

    def waiting_for(self) -> str:
        topics = [TOPICS['odom']] if self.tracker.latest is None else []
        if self.tracker.estimate is None:
            topics.append(f'{TOPICS["estimate"]} (frame {self.map_frame})')
        return ' and '.join(topics)

    def run(self, moves: list[MoveGoal], on_end: Callable[[MoveEnd], None]) -> None:
        """Run the moves one after the other; ``on_end`` gets the last one's end, or the first
        that was not DONE."""
        self.cancel()
        self._moves = list(moves)
        self._on_end = on_end
        self._next_move()

    def cancel(self) -> None:
        """Drop what is running (its end will not be reported) and stop the robot."""
        if self.busy:
            self.send(STOP)
        self._moves, self._move, self._ending, self._on_end = [], None, None, None

    def restart(self, pose: Pose, on_placed: Callable[[], None]) -> None:
        """The robot was teleported to ``pose``: ``on_placed`` once odometry after it came."""
        latest = self.tracker.latest
        self.tracker.restart(pose, after=latest.t if latest else -math.inf)
        self._on_placed = on_placed

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

    def silent_for(self) -> float:
        """Wall seconds since the last odometry message."""
        return time.monotonic() - self._last_odom_wall

    def tick(self) -> None:
        """Housekeeping: a robot waiting to be placed gets a zero command (a simulator that
        holds its clock at rest lets it run), and a move's end stops waiting for the truth."""
        if self._on_placed is not None:
            self.send(STOP)
        if self._ending is not None and time.monotonic() - self._ending[1] > TRUTH_WAIT:
            self._report(self._ending[0])

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
        pose = _pose_of(message.pose.pose)
        problem = pose_problem(*pose)
        twist = message.twist.twist
        if not problem and not (math.isfinite(twist.linear.x) and math.isfinite(twist.angular.z)):
            problem = f'velocities ({twist.linear.x}, {twist.angular.z}) are not finite'
        if problem:
            self._bad('odom', problem)
            return
        self._last_odom_wall = time.monotonic()
        self.tracker.add_odom(Odom(seconds(message.header.stamp), pose, twist.linear.x,
                                   twist.angular.z))  # fmt: skip
        if self._on_placed is not None and self.tracker.estimate is not None:
            on_placed, self._on_placed = self._on_placed, None
            on_placed()
        if self._move is not None:
            self._control()

    def _on_estimate(self, message: PoseWithCovarianceStamped) -> None:
        pose = _pose_of(message.pose.pose)
        problem = pose_problem(*pose, message.header.frame_id, self.map_frame)
        if problem:
            self._bad('estimate', problem)
            return
        self.tracker.add_estimate(seconds(message.header.stamp), pose)

    def _on_scan(self, message: LaserScan) -> None:
        self._scan = message

    def _on_truth(self, message: Odometry) -> None:
        pose = _pose_of(message.pose.pose)
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
            self._end(MoveEnd(None, f'no pose of the robot ({self.waiting_for()})', None,
                              None, 0.0, False))  # fmt: skip
            return
        self._move = TopicMove(self._moves.pop(0), estimate, latest.t, self.config)
        self._control()

    def _control(self) -> None:
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
        on_end, self._on_end = self._on_end, None
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


def _pose_of(pose) -> Pose:
    return Pose(pose.position.x, pose.position.y, quaternion_yaw(pose.orientation))
