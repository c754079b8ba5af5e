"""planner_server: covert paths behind Nav2's planner interface (the shell of
``stealth_nav2.covert_planning``).

    stealth run stealth_nav2 planner_server --ros-args -p scenario:=lgfloor
    ros2 run stealth_nav2 planner_server     # the scene from the map and searchlights topics

It answers as Nav2's ``nav2_planner/planner_server`` does (same node name, actions, result
codes and path), so bt_navigator or nav2_simple_commander's ``getPath`` /
``getPathThroughPoses`` call it unchanged; planner ids: covert (the default: '' and Nav2's
default id GridBased too), dark_path, astar, policy.

## Topics

* subscribes ``map`` (nav_msgs/OccupancyGrid, transient local) and ``searchlights``
  (stealth_interfaces/SearchlightArray, transient local) when no scenario is given;
  ``amcl_pose`` (geometry_msgs/PoseWithCovarianceStamped, transient local, as AMCL); ``/tf``
  (tf2_msgs/TFMessage, as tf2_ros's listener).
* publishes ``plan`` (nav_msgs/Path, depth 1, as Nav2's planner server): each path found.

## Actions

* ``compute_path_to_pose`` (nav2_msgs/action/ComputePathToPose) and
  ``compute_path_through_poses`` (ComputePathThroughPoses): the start is the request's when
  ``use_start``, else the latest ``amcl_pose``; poses in another frame than the map's are
  carried into it over /tf (an empty frame is the map's). Success: the path, ``planning_time``
  (wall time). Failure: aborted with Nav2's ``error_code`` and an ``error_msg`` naming the
  reason (the same line is logged as a warning). Cancelled before planning: canceled.

## Parameters

``stealth_nav2.planner_parameters``: scenario, policy_file, max_planning_time,
path_resolution, dark_path_weight, lights_time_offset, and the task's numbers for a scene
from topics (robot_radius, step_distance, goal_radius, detection_threshold, step_limit,
phase_bins, step_seconds).

A path's poses are lattice nodes (denser with ``path_resolution``), each stamped with the time
to be there (the request's time on the node's clock plus the steps before it), facing the next
pose; the last keeps the goal's orientation.
"""

from __future__ import annotations

import functools
import time

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
from nav_msgs.msg import OccupancyGrid, Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from stealth_interfaces.msg import SearchlightArray
from stealth_node_kit.conversions import quaternion_yaw, seconds, yaw_quaternion
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.qos import kept_qos
from stealth_node_kit.running import StartupNode, run_node
from tf2_msgs.msg import TFMessage

from stealth_nav2.covert_planning import CovertPlanner, Pose, densify
from stealth_nav2.frame_tree import FrameError, FrameTree
from stealth_nav2.plan_errors import PlanError
from stealth_nav2.planner_parameters import PARAMETERS, task_numbers
from stealth_nav2.policy_behaviour import read_policy
from stealth_nav2.scene_source import SceneError, SceneSource, scene_from_scenario

NODE_NAME = 'planner_server'
TF_QOS = QoSProfile(
    depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE
)


class PlannerServer(StartupNode):
    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)

    def set_up(self) -> None:
        values = declare_parameters(self, PARAMETERS)
        self.add_on_set_parameters_callback(self._validate_parameters)
        policy = None
        try:
            scene = scene_from_scenario(values['scenario']) if values['scenario'] else None
            if values['policy_file']:
                policy = read_policy(values['policy_file'])
        except (SceneError, PlanError) as error:
            raise StartupError(str(error)) from None
        self.planner = CovertPlanner(task_numbers(values), values['dark_path_weight'], policy)
        latched = kept_qos(1)
        self.source = SceneSource(
            scene,
            map_topic=self.resolve_topic_name('map'),
            lights_topic=self.resolve_topic_name('searchlights'),
        )
        if scene is None:
            self.create_subscription(OccupancyGrid, 'map', self._on_map, latched)
            self.create_subscription(SearchlightArray, 'searchlights', self._on_lights, latched)
        self._robot: PoseWithCovarianceStamped | None = None
        self.create_subscription(
            PoseWithCovarianceStamped, 'amcl_pose', self._on_robot, kept_qos(5)
        )
        self.frames = FrameTree()
        self.create_subscription(TFMessage, '/tf', self._on_tf, TF_QOS)
        self.plan_publisher = self.create_publisher(Path, 'plan', 1)
        for action_type, name in (
            (ComputePathToPose, 'compute_path_to_pose'),
            (ComputePathThroughPoses, 'compute_path_through_poses'),
        ):
            execute = functools.partial(self._execute, action_type)
            ActionServer(self, action_type, name, execute, cancel_callback=self._cancel)
        if scene is not None:
            started = time.perf_counter()
            self.planner.prepare(scene)
            self.get_logger().info(
                f'scene: {scene.source}, lattice model built in '
                f'{time.perf_counter() - started:.2f} s; planner ids: covert (default), '
                'dark_path, astar, policy (GridBased: covert)'
            )
        else:
            self.get_logger().info(
                f'scene: waiting for {self.source.map_topic} and {self.source.lights_topic}'
            )

    # --- parameters -----------------------------------------------------------------------

    def _validate_parameters(self, changes) -> SetParametersResult:
        """rclpy checks types, ranges and read-only; this refuses nan and inf, and applies."""
        reason = non_finite(changes)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        for change in changes:
            if change.name == 'dark_path_weight':
                self.planner.dark_path_weight = float(change.value)
        return SetParametersResult(successful=True)

    def _value(self, name: str):
        return self.get_parameter(name).value

    # --- inputs ---------------------------------------------------------------------------

    def _on_map(self, message: OccupancyGrid) -> None:
        self._update(self.source.update_map, message, self.source.map_topic)

    def _on_lights(self, message: SearchlightArray) -> None:
        self._update(self.source.update_lights, message, self.source.lights_topic)

    def _update(self, update, message, topic: str) -> None:
        try:
            update(message)
        except SceneError as error:
            self.get_logger().warn(f'{topic}: message ignored: {error}')

    def _on_robot(self, message: PoseWithCovarianceStamped) -> None:
        self._robot = message

    def _on_tf(self, message: TFMessage) -> None:
        for transform in message.transforms:
            t = transform.transform
            pose = Pose(t.translation.x, t.translation.y, quaternion_yaw(t.rotation))
            self.frames.update(transform.header.frame_id, transform.child_frame_id, pose)

    # --- requests -------------------------------------------------------------------------

    def _cancel(self, _goal_handle) -> CancelResponse:
        return CancelResponse.ACCEPT

    def _execute(self, action_type, goal_handle):
        """One request: the path, or aborted with Nav2's error code and the reason."""
        through = action_type is ComputePathThroughPoses
        result = action_type.Result()
        request = goal_handle.request
        started = time.perf_counter()
        now = self.get_clock().now()
        if goal_handle.is_cancel_requested:
            goal_handle.canceled()
            return result
        planner_id = request.planner_id
        goals = list(request.goals) if through else [request.goal]
        try:
            if not goals:  # Nav2 says so before it looks for the start
                raise PlanError('NO_VIAPOINTS_GIVEN', 'no goals given: expected at least one pose')
            scene = self._scene()
            start = self._start(request, scene.frame_id)
            targets = [self._in_frame(goal, scene.frame_id, 'goal') for goal in goals]
            limit = self._value('max_planning_time') or None
            t = seconds(now.to_msg()) - self._value('lights_time_offset')
            plan = self.planner.plan_through(scene, start, targets, planner_id, t, limit)
        except PlanError as error:
            self.get_logger().warn(
                f'{planner_id or "covert"} plugin failed to plan to {_where(goals)}: "{error}"'
            )
            result.error_code = getattr(action_type.Result, error.code)
            result.error_msg = str(error)
            goal_handle.abort()
            return result
        result.path = self._path_msg(plan, scene.frame_id, now)
        result.planning_time = _duration(time.perf_counter() - started)
        self.plan_publisher.publish(result.path)
        goal_handle.succeed()
        return result

    def _scene(self):
        try:
            return self.source.current()
        except SceneError as error:
            raise PlanError('UNKNOWN', str(error)) from None

    def _start(self, request, frame: str) -> Pose:
        if request.use_start:
            return self._in_frame(request.start, frame, 'start')
        if self._robot is None:
            raise PlanError(
                'TF_ERROR',
                'no start: use_start is false and nothing has arrived on '
                f'{self.resolve_topic_name("amcl_pose")} (geometry_msgs/'
                'PoseWithCovarianceStamped) yet',
            )
        robot = PoseStamped(header=self._robot.header, pose=self._robot.pose.pose)
        return self._in_frame(robot, frame, 'start (amcl_pose)')

    def _in_frame(self, stamped: PoseStamped, frame: str, what: str) -> Pose:
        """The pose in the scene's frame; TF_ERROR naming the frame when it cannot be."""
        p = stamped.pose
        pose = Pose(p.position.x, p.position.y, quaternion_yaw(p.orientation))
        source = stamped.header.frame_id or frame
        try:
            return Pose(*self.frames.transform(pose, source, frame))
        except FrameError as error:
            raise PlanError('TF_ERROR', f'{what} in frame {source!r}: {error}') from None

    def _path_msg(self, plan, frame: str, now) -> Path:
        poses, times = densify(plan.poses, plan.times, self._value('path_resolution'))
        path = Path()
        path.header.frame_id, path.header.stamp = frame, now.to_msg()
        base = now.nanoseconds
        for (x, y, yaw), offset in zip(poses, times, strict=True):
            pose = PoseStamped()
            pose.header.frame_id = frame
            pose.header.stamp = Time(
                nanoseconds=base + round(offset * 1e9), clock_type=now.clock_type
            ).to_msg()
            pose.pose.position.x, pose.pose.position.y = float(x), float(y)
            pose.pose.orientation = yaw_quaternion(float(yaw))
            path.poses.append(pose)
        return path


def _where(goals) -> str:
    if not goals:
        return 'no goal'
    p = goals[-1].pose.position
    return f'({p.x:.2f}, {p.y:.2f})'


def _duration(elapsed: float) -> Duration:
    whole = int(elapsed)
    return Duration(sec=whole, nanosec=int((elapsed - whole) * 1e9))


def main(args=None) -> int:
    return run_node(PlannerServer, NODE_NAME, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
