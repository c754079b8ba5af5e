"""One navigation of the navigator node: plan with the planner server's action (as Nav2's BT
does), follow the path with the project's controller over the robot's topics, replan when the
robot is blocked (backing off first, ``back_off``), strays or falls behind a timed path (a
recovery), and end with an :class:`Outcome`. Nothing here blocks the executor: answers,
odometry and the node's steady tick move it on.
"""

from __future__ import annotations

from collections.abc import Callable
import dataclasses
import math
import time
from typing import NamedTuple

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
from stealth_env.env_messages import pose_of
from stealth_env.robot import MoveEnd
from stealth_env.topic_moves import STOP, Pose
from stealth_node_kit.conversions import seconds, time_msg, yaw_quaternion

from stealth_nav2 import navigation_goals as codes
from stealth_nav2.back_off import BackedOff, BackOff, backs_off, nearest_bearing
from stealth_nav2.navigation_goals import ViaPoses
from stealth_nav2.path_following import Arrived, PathFollower, Replan, TimedPose


class Outcome(NamedTuple):
    """How a navigation ended: a GoalStatus, Nav2's error code (0: none) and why."""

    status: int
    error_code: int = 0
    message: str = ''


SUCCEEDED = Outcome(GoalStatus.STATUS_SUCCEEDED)
CLOCK_MISMATCH = 3600.0  # s between a path's first stamp and the robot's clock: another clock


class Stage:
    WAITING = 'waiting for the robot pose'
    PLANNING = 'planning'
    FOLLOWING = 'following'
    BACKING_OFF = 'backing off'
    DONE = 'done'


class Navigation:
    """To ``goals[-1]`` (through the others first when ``through``), in the map frame, for the
    navigator ``node`` (its robot, planner clients, watch, values and settings)."""

    def __init__(
        self,
        node,
        goals: list[Pose],
        through: bool,
        planner_id: str,
        on_done: Callable[[Outcome], None],
    ):
        self.node = node
        self.robot = node.robot
        self.through = through
        self.planner_id = planner_id
        self.via = ViaPoses(goals, node.values['via_radius'])
        self.on_done = on_done
        self.stage = Stage.WAITING
        self.recoveries = 0
        self.follower: PathFollower | None = None
        self.back_off: BackOff | None = None
        self.plans = 0
        self.started_wall = time.monotonic()
        self.started_robot: float | None = None  # the robot's clock at the start (s)
        self._since = self.started_wall  # wall time the current stage began
        self._plan_handle = None  # the planner's goal handle, once it accepted
        self._plan_sent = False  # a plan request is on its way or being answered

    # --- what the node asks ---------------------------------------------------------------------

    @property
    def done(self) -> bool:
        return self.stage == Stage.DONE

    def start(self) -> None:
        self.node.watch.restart(time.monotonic())
        self.tick()

    def tick(self) -> None:
        """Deadlines and watchdogs, on the node's steady timer."""
        if self.done:
            return
        now = time.monotonic()
        values = self.node.values
        silent = self.node.watch.silent(now, *self.node.topic_names)
        if silent:
            self._fail(self._code(codes.TIMEOUT), silent)
        elif self.stage == Stage.WAITING:
            if self.robot.ready():
                self.started_robot = self.robot.tracker.latest.t
                self._plan()
        elif self.stage == Stage.PLANNING:
            if not self._plan_sent and not self._client().server_is_ready():
                if now - self._since > values['server_timeout']:
                    wait = values['server_timeout']
                    self._fail(self._code(codes.TIMEOUT), (
                        f'no planner server on {self._action_name()} within server_timeout '
                        f'{wait:g} s (is planner_server running?)'))  # fmt: skip
            elif not self._plan_sent:
                self._send_plan_request()
            elif now - self._since > values['planner_timeout']:
                self._fail(self._code(codes.TIMEOUT), (
                    f'no plan from {self._action_name()} within planner_timeout '
                    f"{values['planner_timeout']:g} s"))  # fmt: skip
        elif self.stage == Stage.FOLLOWING:
            estimate = self.robot.tracker.estimate
            if self.through and estimate is not None:
                self.via.passed(estimate)
            off = self.follower.off_path(estimate) if estimate is not None else 0.0
            behind = self.follower.behind(self.robot.tracker.latest.t)
            if off > values['stray_distance']:
                self._recover(f'strayed {off:.2f} m off the path')
            elif behind is not None:
                self._recover(behind.reason, counted=False)
        elif self.stage == Stage.BACKING_OFF:
            self._back_off_step()

    def cancel(self) -> None:
        """The goal was cancelled: stop the robot now."""
        self._finish(Outcome(GoalStatus.STATUS_CANCELED))

    def preempt(self) -> None:
        self._finish(Outcome(GoalStatus.STATUS_ABORTED, 0, 'preempted by a newer goal'))

    def progress(self) -> dict:
        """The feedback's numbers now."""
        estimate = self.robot.tracker.estimate
        latest = self.robot.tracker.latest
        now = latest.t if latest is not None else None
        elapsed = 0.0
        if now is not None and self.started_robot is not None:
            elapsed = max(0.0, now - self.started_robot)
        distance = remaining = 0.0
        if self.follower is not None and estimate is not None:
            distance = self.follower.distance_remaining(estimate)
            remaining = self.follower.time_remaining(estimate, now)
        return {
            'pose': estimate,
            't': now,
            'navigation_time': elapsed,
            'estimated_time_remaining': remaining,
            'number_of_recoveries': self.recoveries,
            'distance_remaining': distance,
            'number_of_poses_remaining': len(self.via.poses),
        }

    # --- planning -------------------------------------------------------------------------------

    def _client(self):
        return self.node.through_client if self.through else self.node.to_pose_client

    def _action_name(self) -> str:
        name = 'compute_path_through_poses' if self.through else 'compute_path_to_pose'
        return self.node.resolve_topic_name(name)

    def _code(self, code: int) -> int:
        return codes.navigator_code(code, self.through)

    def _plan(self) -> None:
        self.stage = Stage.PLANNING
        self._since = time.monotonic()
        self._plan_handle, self._plan_sent = None, False
        if self._client().server_is_ready():
            self._send_plan_request()

    def _send_plan_request(self) -> None:
        estimate, latest = self.robot.tracker.estimate, self.robot.tracker.latest
        frame = self.node.frames.map
        start = self._stamped(estimate, latest.t, frame)
        if self.through:
            goal = ComputePathThroughPoses.Goal(
                goals=[self._stamped(p, latest.t, frame) for p in self.via.poses]
            )
        else:
            goal = ComputePathToPose.Goal(goal=self._stamped(self.via.poses[-1], latest.t, frame))
        goal.start, goal.use_start, goal.planner_id = start, True, self.planner_id
        self._plan_sent = True
        self.plans += 1
        self._client().send_goal_async(goal).add_done_callback(self._on_plan_accepted)

    @staticmethod
    def _stamped(pose: Pose, t: float, frame: str) -> PoseStamped:
        message = PoseStamped()
        message.header.frame_id = frame
        message.header.stamp = time_msg(t)
        message.pose.position.x, message.pose.position.y = float(pose.x), float(pose.y)
        message.pose.orientation = yaw_quaternion(pose.yaw)
        return message

    def _on_plan_accepted(self, future) -> None:
        handle = future.result()
        if self.done:
            if handle is not None and handle.accepted:
                handle.cancel_goal_async()
            return
        if handle is None or not handle.accepted:
            self._fail(self._code(codes.UNKNOWN),
                       f'{self._action_name()} rejected the plan request')  # fmt: skip
            return
        self._plan_handle = handle
        handle.get_result_async().add_done_callback(self._on_plan_result)

    def _on_plan_result(self, future) -> None:
        if self.done:
            return
        answer = future.result()
        result = answer.result
        if answer.status != GoalStatus.STATUS_SUCCEEDED or result.error_code:
            why = result.error_msg or f'the plan request ended with status {answer.status}'
            self._fail(result.error_code or self._code(codes.UNKNOWN),
                       f'planning failed (planner {self.planner_id}): {why}')  # fmt: skip
            return
        path = result.path
        frame = self.node.frames.map
        if path.header.frame_id not in ('', frame) or any(
            p.header.frame_id not in ('', frame) for p in path.poses
        ):
            self._fail(self._code(codes.UNKNOWN),
                       f"the planner's path is in frame '{path.header.frame_id}', "
                       f"expected '{frame}'")  # fmt: skip
            return
        poses = [TimedPose(*pose_of(p.pose), seconds(p.header.stamp)) for p in path.poses]
        now = self.robot.tracker.latest.t
        if poses and abs(poses[0].t - now) > CLOCK_MISMATCH:
            message = (
                f"the planner's path is stamped {poses[0].t:.1f} s, the robot's clock (odom) "
                f'says {now:.1f} s: run both on one clock (use_sim_time on a simulator)'
            )
            self._fail(self._code(codes.UNKNOWN), message)
            return
        try:
            self.follower = PathFollower(poses, self.robot.tracker.estimate,
                                         self.node.follow_settings, now,
                                         self.node.keep_clear(self.via.poses[-1]))  # fmt: skip
        except ValueError as error:
            self._fail(self._code(codes.UNKNOWN), f"the planner's path: {error}")
            return
        self._plan_handle, self._plan_sent = None, False
        self.stage = Stage.FOLLOWING
        self._since = time.monotonic()
        legs = self.follower.legs
        timing = f'timed, {self.follower.waits} waits' if self.follower.timed else 'untimed'
        self.node.get_logger().info(
            f'plan {self.plans} ({self.planner_id}): {len(poses)} poses ({timing}), '
            f'{len(legs)} legs, planned in {seconds(result.planning_time):.3f} s'
        )
        self._next_move()

    # --- following ------------------------------------------------------------------------------

    def _next_move(self) -> None:
        now = self.robot.tracker.latest.t
        step = self.follower.next_move(now)
        if isinstance(step, Arrived):
            # The planner's path ends where its task counts the goal reached (within the
            # scenario's goal radius, which may stop short of a goal in the light): the end of
            # the path is the one to reach (moved off a wall: its last leg's), not the goal
            # pose itself.
            end, estimate = self.follower.end, self.robot.tracker.estimate
            off = math.dist(end, estimate[:2])
            if off > self.node.values['goal_tolerance']:
                self._recover(f'the path ended {off:.2f} m from its last pose')
                return
            goal = math.dist(self.via.poses[-1][:2], estimate[:2])
            late = f', {step.lateness:.1f} s after its stamp' if step.lateness else ''
            self.node.get_logger().info(f'goal reached ({goal:.2f} m from the goal pose{late})')
            self._finish(SUCCEEDED)
            return
        self.robot.config = dataclasses.replace(self.node.topic_config, limits=step.limits)
        self.robot.run(step.goal, self._on_move_end)

    def _on_move_end(self, end: MoveEnd) -> None:
        if self.done:
            return
        if end.outcome is None:  # odometry stopped (the robot's own watchdog), or no pose
            self._fail(self._code(codes.TIMEOUT), end.message)
            return
        not_responding = self.robot.not_responding()
        if not_responding:
            self._fail(codes.FAILED_TO_MAKE_PROGRESS, not_responding)
            return
        verdict = self.follower.move_ended(end.outcome, end.message, end.t, end.estimate)
        if isinstance(verdict, Replan):
            self._recover(verdict.reason, verdict.recovery, backs_off(verdict,
                          self.node.back_off_settings))  # fmt: skip
        else:
            self._next_move()

    def _recover(self, reason: str, counted: bool = True, back_off: bool = False) -> None:
        """Plan again from where the robot is: a recovery (given up after max_recoveries), or,
        for a robot behind a timed path's schedule, a plain replan. A blocked robot backs off
        first (``back_off``: then the replan from where it stopped)."""
        self.robot.cancel()
        limit = self.node.values['max_recoveries']
        if counted and self.recoveries >= limit:
            self._fail(codes.FAILED_TO_MAKE_PROGRESS,
                       f'the robot could not follow the path: {reason} (after {limit} '
                       'recoveries)')  # fmt: skip
            return
        here = self.robot.tracker.estimate
        at = f' at ({here.x:.2f}, {here.y:.2f})' if here is not None else ''
        self.follower = None
        if counted:
            self.recoveries += 1
        latest = self.robot.tracker.latest
        if back_off and latest is not None:
            settings = self.node.back_off_settings
            self.back_off = BackOff(latest.pose, latest.t, settings, self._turn_to_nearest())
            turn = self.back_off.turn
            how = f' (turning {turn:+.2f} rad to face the nearest obstacle)' if turn else ''
            self.node.get_logger().warning(
                f'backing off {settings.distance:.2f} m{how} (recovery {self.recoveries}){at}: '
                f'{reason}'
            )
            self.stage = Stage.BACKING_OFF
            self._back_off_step()
            return
        if counted:
            self.node.get_logger().warning(
                f'replanning (recovery {self.recoveries}){at}: {reason}'
            )
        else:
            self.node.get_logger().info(f'replanning{at}: {reason}')
        self._plan()

    def _turn_to_nearest(self) -> float:
        """The turn that faces the scan's nearest return (0: none, or straight back-offs)."""
        scan = self.robot.scan
        if not self.node.back_off_settings.turn_to_nearest or scan is None:
            return 0.0
        bearing = nearest_bearing(scan.ranges, scan.angle_min, scan.angle_increment,
                                  scan.range_min, scan.range_max)  # fmt: skip
        return 0.0 if bearing is None else bearing

    def _back_off_step(self) -> None:
        """Drive the back-off on (the node's tick), then plan again from where it ended."""
        latest = self.robot.tracker.latest
        if latest is None:  # odometry started over (its clock went back): wait for the next
            return
        step = self.back_off.update(latest.t, latest.pose)
        if not isinstance(step, BackedOff):
            self.robot.send(step)
            return
        self.robot.send(STOP)
        self.back_off = None
        here = self.robot.tracker.estimate
        at = f' at ({here.x:.2f}, {here.y:.2f})' if here is not None else ''
        short = f' (stopped short: {step.short})' if step.short else ''
        self.node.get_logger().info(f'backed off {step.travelled:.2f} m{short}: replanning{at}')
        self._plan()

    # --- the end --------------------------------------------------------------------------------

    def _fail(self, code: int, message: str) -> None:
        self._finish(Outcome(GoalStatus.STATUS_ABORTED, code, message))

    def _finish(self, outcome: Outcome) -> None:
        if self.done:
            return
        self.stage = Stage.DONE
        self.robot.cancel()
        self.robot.send(STOP)  # at once, whatever the robot was doing (planning, holding)
        handle, self._plan_handle = self._plan_handle, None
        if handle is not None:  # a plan being made that nobody wants any more
            handle.cancel_goal_async()
        if outcome.status == GoalStatus.STATUS_ABORTED and outcome.message:
            self.node.get_logger().error(f'navigation aborted: {outcome.message}')
        self.on_done(outcome)
