"""The navigator (node ``bt_navigator``, as Nav2's, so clients find it where they expect): Nav2's
navigation actions, planned by the planner server's actions and driven over the robot's
standard topics with the project's controller (``stealth_env.topic_moves``), so that a
``nav2_simple_commander`` client's ``goToPose``, ``goThroughPoses`` and ``followWaypoints``
work against it unchanged.

## Actions (served)

* ``navigate_to_pose`` (nav2_msgs/NavigateToPose), ``navigate_through_poses``
  (NavigateThroughPoses) and ``follow_waypoints`` (FollowWaypoints: Nav2 serves it from its
  ``waypoint_follower`` node; here the navigator runs the waypoints itself, each as a
  navigation to it, with waypoint_follower's ``stop_on_failure``, ``number_of_loops`` and
  ``goal_index``). One goal runs at a time: a new goal of the running action preempts it (the
  old one ends ABORTED, 'preempted by a newer goal'), a goal of another action is rejected.
  ``behavior_tree`` selects the planner: '' is ``planner_id``; a planner id (``policy``: the
  learned policy, ``covert``, ``dark_path``, ``astar``) is that one; anything else aborts the
  goal (error 9001/9101, FAILED_TO_LOAD_BEHAVIOR_TREE) naming them.
* Feedback at ``feedback_rate`` (wall): current_pose, navigation_time (the robot's clock),
  estimated_time_remaining (to the last pose's stamp on a timed path, else the distance left at
  the speed limit), number_of_recoveries, distance_remaining (along the path), and
  number_of_poses_remaining; FollowWaypoints' current_waypoint.
* Cancel stops the robot at once (a zero Twist in the cancel's callback) and the goal ends
  CANCELED. Errors: ``stealth_nav2.navigation_goals`` (the planner's code and message carried
  into the result's error_msg when a plan fails).

## Actions (called)

``compute_path_to_pose`` (ComputePathToPose), ``compute_path_through_poses``
(ComputePathThroughPoses): the planner server, with ``use_start`` and the robot's estimate
stamped with the robot's clock.

## Topics

``cmd_vel`` (out), ``odom``, ``amcl_pose`` (map frame, transient local), ``scan``,
``ground_truth`` (in), ``initialpose`` (unused here): ``stealth_env.topic_robot``'s, all names
relative (remap to plug in any robot). ``map`` (nav_msgs/OccupancyGrid, transient local, in):
the map the legs are kept off walls on (``stealth_nav2.leg_clearance``; until it comes, the
path is driven as planned).

## Services

``bt_navigator/get_state`` (lifecycle_msgs/GetState): active once the robot's pose is known;
and ``<localizer_state>/get_state`` (default ``amcl/get_state``) the same, so
``waitUntilNav2Active()`` works with the simulator's non-lifecycle localisation.

## Parameters

``stealth_nav2.navigator_parameters``.
"""

from __future__ import annotations

import dataclasses
import time

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from lifecycle_msgs.msg import State
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import (
    ComputePathThroughPoses,
    ComputePathToPose,
    FollowWaypoints,
    NavigateThroughPoses,
    NavigateToPose,
)
from nav2_msgs.msg import MissedWaypoint
from nav_msgs.msg import OccupancyGrid
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.task import Future
from stealth_core.clearance import Clearance, ClearanceSettings
from stealth_env.env_messages import pose_of
from stealth_env.env_parameters import topic_config
from stealth_env.topic_moves import Odom, PoseTracker
from stealth_env.topic_robot import TOPICS, TopicRobot
from stealth_node_kit.conversions import time_msg, yaw_quaternion
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.qos import kept_qos
from stealth_node_kit.running import StartupNode, run_node

from stealth_nav2 import navigation_goals as codes
from stealth_nav2.back_off import BackOffSettings
from stealth_nav2.leg_clearance import keep_clear
from stealth_nav2.navigation_goals import Frames, WaypointRun, goal_in_map, planner_for
from stealth_nav2.navigation_run import Navigation, Outcome
from stealth_nav2.navigator_parameters import PARAMETERS
from stealth_nav2.path_following import FollowSettings
from stealth_nav2.scene_source import SceneError, map_from_message
from stealth_nav2.sensor_watch import SensorWatch

NODE_NAME = 'bt_navigator'
TICK_PERIOD = 0.05  # s of wall time between the watchdogs' looks


class WatchedTracker(PoseTracker):
    """The robot's pose tracker, telling the sensor watch when odom and amcl_pose come."""

    def __init__(self, watch: SensorWatch):
        super().__init__()
        self.watch = watch

    def add_odom(self, odom: Odom) -> None:
        self.watch.odom(time.monotonic(), odom.pose)
        super().add_odom(odom)

    def add_estimate(self, t: float, pose) -> None:
        self.watch.estimate(time.monotonic())
        super().add_estimate(t, pose)


@dataclasses.dataclass
class Task:
    """The goal running: which action, its handle, and its navigation now."""

    action: str
    handle: object
    navigation: Navigation | None = None
    waypoint: int = 0


class Navigator(StartupNode):
    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)

    def set_up(self) -> None:
        self.values = declare_parameters(self, PARAMETERS)
        if not self.values['planner_id']:
            raise StartupError('parameter planner_id: expected a planner id (covert, ...), got ""')
        self.add_on_set_parameters_callback(self._validate)
        values = self.values
        self.frames = Frames(values['map_frame'], values['odom_frame'], values['robot_frame'])
        self.topic_config = dataclasses.replace(
            topic_config(values, values['robot_radius']), lookahead=values['lookahead_distance']
        )
        self.watch = SensorWatch(values['sensor_timeout'], values['localisation_travel'])
        self.robot = TopicRobot(self, self.topic_config, self.frames.map, None, None,
                                values['unresponsive_moves'], self._sensor_timeout)  # fmt: skip
        self.robot.tracker = WatchedTracker(self.watch)
        self.topic_names = (
            self.resolve_topic_name(TOPICS['odom']),
            self.resolve_topic_name(TOPICS['estimate']),
        )
        self.to_pose_client = ActionClient(self, ComputePathToPose, 'compute_path_to_pose')
        self.through_client = ActionClient(
            self, ComputePathThroughPoses, 'compute_path_through_poses'
        )
        self.task: Task | None = None
        self._map = None  # the occupancy map from the map topic
        self._clearance: Clearance | None = None  # its footprints, for the current settings
        self.create_subscription(OccupancyGrid, 'map', self._on_map, kept_qos(1))
        self._servers = [
            self._serve(NavigateToPose, 'navigate_to_pose', self._execute_to_pose),
            self._serve(NavigateThroughPoses, 'navigate_through_poses', self._execute_through),
            self._serve(FollowWaypoints, 'follow_waypoints', self._execute_waypoints),
        ]
        self.create_service(GetState, '~/get_state', self._get_state)
        if values['localizer_state']:
            self.create_service(GetState, f'{values["localizer_state"]}/get_state',
                                self._get_state)  # fmt: skip
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(TICK_PERIOD, self._tick, clock=steady)
        self.create_timer(1.0 / values['feedback_rate'], self._feedback, clock=steady)
        self.get_logger().info(
            f'navigator ready: navigate_to_pose, navigate_through_poses, follow_waypoints; '
            f'planner {values["planner_id"]} on {self.resolve_topic_name("compute_path_to_pose")}'
            f'; robot over {", ".join(self.resolve_topic_name(t) for t in TOPICS.values())}'
        )

    # --- parameters -----------------------------------------------------------------------------

    def _validate(self, changes) -> SetParametersResult:
        problem = non_finite(changes)
        for change in changes:
            if change.name == 'planner_id' and not change.value:
                problem = 'planner_id must name a planner, got an empty string'
        if problem:
            return SetParametersResult(successful=False, reason=problem)
        for change in changes:
            self.values[change.name] = change.value
        self.watch.timeout = self.values['sensor_timeout']
        self.watch.travel = self.values['localisation_travel']
        return SetParametersResult(successful=True)

    def _sensor_timeout(self) -> float:
        return self.values['sensor_timeout']

    @property
    def back_off_settings(self) -> BackOffSettings:
        values = self.values
        return BackOffSettings(values['back_off_distance'], values['back_off_speed'],
                               values['stall_time'],
                               turn_to_nearest=values['back_off_from_nearest'])  # fmt: skip

    def _on_map(self, message: OccupancyGrid) -> None:
        try:
            self._map, _ = map_from_message(message)
        except SceneError as error:
            self.get_logger().error(f'{self.resolve_topic_name("map")}: map ignored, {error}')
            return
        self._clearance = None

    def keep_clear(self, goal):
        """What moves a path's legs off walls (towards ``goal`` at the end), or None (no map
        yet, or clearance off)."""
        values = self.values
        settings = ClearanceSettings(values['robot_radius'], values['clearance_margin'],
                                     values['clearance_shift'])  # fmt: skip
        if self._map is None or settings.margin <= 0 or settings.max_shift <= 0:
            return None
        if self._clearance is None or self._clearance.settings != settings:
            self._clearance = Clearance(self._map, settings)
        clearance = self._clearance
        return lambda legs: keep_clear(legs, clearance, (goal.x, goal.y))

    @property
    def follow_settings(self) -> FollowSettings:
        values = self.values
        return FollowSettings(
            limits=self.topic_config.limits,
            max_lateness=values['max_lateness'],
            stray_distance=values['stray_distance'],
        )

    # --- actions --------------------------------------------------------------------------------

    def _serve(self, action_type, name, execute):
        def goal_callback(_request):
            running = self.task
            if running is not None and running.action != name:
                self.get_logger().error(
                    f'{name} goal rejected: a {running.action} goal is running (cancel it first)'
                )
                return GoalResponse.REJECT
            return GoalResponse.ACCEPT

        return ActionServer(self, action_type, name, execute_callback=execute,
                            goal_callback=goal_callback,
                            cancel_callback=self._cancel)  # fmt: skip

    def _cancel(self, handle) -> CancelResponse:
        task = self.task
        if task is not None and task.handle is handle and task.navigation is not None:
            task.navigation.cancel()  # a zero Twist now
        return CancelResponse.ACCEPT

    def _begin(self, action: str, handle) -> Task:
        """The task of a new goal; a running goal of the same action is preempted."""
        previous = self.task
        if previous is not None and previous.navigation is not None:
            previous.navigation.preempt()
        self.task = Task(action, handle)
        return self.task

    async def _navigate(self, task: Task, stamped: list[PoseStamped], behavior_tree: str):
        """Run one navigation of the task to the poses (through all but the last); its
        Outcome."""
        through = task.action == 'navigate_through_poses'
        values = self.values
        planner_id, problem = planner_for(behavior_tree, values['planner_id'],
                                          values['planner_ids'])  # fmt: skip
        if problem:
            return self._refused(codes.FAILED_TO_LOAD_BEHAVIOR_TREE, through, problem)
        goals = []
        tracker = self.robot.tracker
        latest = tracker.latest
        for index, pose in enumerate(stamped):
            goal, problem = goal_in_map(pose.header.frame_id, pose_of(pose.pose), self.frames,
                                        tracker.estimate, latest and latest.pose)  # fmt: skip
            if problem:
                where = f'poses[{index}]' if through else 'pose'
                return self._refused(codes.TF_ERROR, through, f'{where}: {problem}')
            goals.append(goal)
        if not goals:
            return self._refused(codes.UNKNOWN, through, 'poses: no poses given')
        done = Future()
        task.navigation = Navigation(self, goals, through, planner_id, done.set_result)
        where = ', '.join(f'({g.x:.2f}, {g.y:.2f})' for g in goals)
        self.get_logger().info(f'{task.action}: to {where} with planner {planner_id}')
        task.navigation.start()
        return await done

    def _refused(self, code: int, through: bool, message: str) -> Outcome:
        """A goal that cannot start: one line, and the abort with the navigator's code."""
        self.get_logger().error(f'goal aborted: {message}')
        return Outcome(GoalStatus.STATUS_ABORTED, codes.navigator_code(code, through), message)

    def _end(self, task: Task, handle, outcome: Outcome) -> None:
        if self.task is task:
            self.task = None
        if handle.is_cancel_requested:
            handle.canceled()
        elif outcome.status == GoalStatus.STATUS_SUCCEEDED:
            handle.succeed()
        else:
            handle.abort()

    async def _execute_to_pose(self, handle):
        task = self._begin('navigate_to_pose', handle)
        request = handle.request
        outcome = await self._navigate(task, [request.pose], request.behavior_tree)
        self._end(task, handle, outcome)
        return NavigateToPose.Result(error_code=outcome.error_code, error_msg=outcome.message)

    async def _execute_through(self, handle):
        task = self._begin('navigate_through_poses', handle)
        request = handle.request
        outcome = await self._navigate(task, list(request.poses), request.behavior_tree)
        self._end(task, handle, outcome)
        return NavigateThroughPoses.Result(error_code=outcome.error_code,
                                           error_msg=outcome.message)  # fmt: skip

    async def _execute_waypoints(self, handle):
        task = self._begin('follow_waypoints', handle)
        request = handle.request
        poses = list(request.poses)
        run = WaypointRun(len(poses), request.goal_index, request.number_of_loops,
                          self.values['stop_on_failure'])  # fmt: skip
        result = FollowWaypoints.Result()
        problem = run.problem()
        outcome = Outcome(GoalStatus.STATUS_ABORTED, codes.WAYPOINTS_UNKNOWN, problem)
        while not problem:
            if handle.is_cancel_requested:
                outcome = Outcome(GoalStatus.STATUS_CANCELED)
                break
            task.waypoint = run.index
            self._publish_waypoint(handle, run.index)
            outcome = await self._navigate(task, [poses[run.index]], '')
            if outcome.status == GoalStatus.STATUS_CANCELED or self.task is not task:
                break  # cancelled, or preempted by a newer follow_waypoints goal
            succeeded = outcome.status == GoalStatus.STATUS_SUCCEEDED
            if run.finished(succeeded, outcome.error_code, outcome.message):
                break
        result.missed_waypoints = [
            MissedWaypoint(index=m.index, goal=poses[m.index], error_code=m.error_code)
            for m in run.missed
        ]
        if not problem and outcome.status != GoalStatus.STATUS_CANCELED and self.task is task:
            if run.missed and run.stop_on_failure:
                missed = run.missed[-1]
                outcome = Outcome(GoalStatus.STATUS_ABORTED, codes.WAYPOINTS_UNKNOWN,
                                  f'waypoint {missed.index}: {missed.message}')  # fmt: skip
            else:
                outcome = Outcome(GoalStatus.STATUS_SUCCEEDED)
        result.error_code, result.error_msg = outcome.error_code, outcome.message
        self._end(task, handle, outcome)
        return result

    # --- feedback, services, ticks --------------------------------------------------------------

    def _publish_waypoint(self, handle, index: int) -> None:
        handle.publish_feedback(FollowWaypoints.Feedback(current_waypoint=index))

    def _feedback(self) -> None:
        task = self.task
        if task is None or task.navigation is None or task.navigation.done:
            return
        if task.action == 'follow_waypoints':
            self._publish_waypoint(task.handle, task.waypoint)
            return
        numbers = task.navigation.progress()
        if numbers['pose'] is None:
            return
        through = task.action == 'navigate_through_poses'
        feedback = (NavigateThroughPoses if through else NavigateToPose).Feedback()
        pose = numbers['pose']
        feedback.current_pose.header.frame_id = self.frames.map
        feedback.current_pose.header.stamp = time_msg(numbers['t'])
        feedback.current_pose.pose.position.x = float(pose.x)
        feedback.current_pose.pose.position.y = float(pose.y)
        feedback.current_pose.pose.orientation = yaw_quaternion(pose.yaw)
        feedback.navigation_time = _duration(numbers['navigation_time'])
        feedback.estimated_time_remaining = _duration(numbers['estimated_time_remaining'])
        feedback.number_of_recoveries = numbers['number_of_recoveries']
        feedback.distance_remaining = float(numbers['distance_remaining'])
        if through:
            feedback.number_of_poses_remaining = numbers['number_of_poses_remaining']
        task.handle.publish_feedback(feedback)

    def _get_state(self, _request, response):
        active = self.robot.ready()
        response.current_state = State(
            id=State.PRIMARY_STATE_ACTIVE if active else State.PRIMARY_STATE_INACTIVE,
            label='active' if active else 'inactive',
        )
        return response

    def _tick(self) -> None:
        self.robot.tick()
        task = self.task
        if task is not None and task.navigation is not None:
            task.navigation.tick()


def _duration(seconds: float):
    return Duration(seconds=max(0.0, seconds)).to_msg()


def main(args=None) -> int:
    return run_node(Navigator, NODE_NAME, args=args)


__all__ = ['Navigator', 'main']
