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
* publishes ``plan`` (nav_msgs/Path, depth 1, transient local): each path found. Nav2's
  planner server publishes it volatile; latched, a viewer that joins after the goal still sees
  the path being followed, and volatile readers (RViz's default) match it as before.

## Actions

* ``compute_path_to_pose`` (nav2_msgs/action/ComputePathToPose) and
  ``compute_path_through_poses`` (ComputePathThroughPoses): the start is the request's when
  ``use_start``, else the latest ``amcl_pose``; poses in another frame than the map's are
  carried into it over /tf (an empty frame is the map's); every field is checked first
  (``stealth_nav2.request_poses``). Success: the path, ``planning_time`` (wall time). Failure:
  aborted with Nav2's ``error_code`` and an ``error_msg`` naming the reason (the same line is
  logged as a warning). Goals are accepted as they come and planned one at a time in that
  order on a planning thread (``stealth_nav2.goal_queue``); one that finds max_queued_goals
  waiting is aborted at once (UNKNOWN). A cancelled goal that waits ends canceled at once, the
  one being planned when its planning ends. The goal, cancel and result services keep every
  request (a burst of more than 10 lost the rest with rclpy's default QoS).

## Parameters

``stealth_nav2.planner_parameters``: scenario, policy_file, max_planning_time,
path_resolution, dark_path_weight, max_queued_goals, action_server_result_timeout,
lights_time_offset, and the task's numbers for a scene from topics (robot_radius,
step_distance, goal_radius, detection_threshold, step_limit, phase_bins, step_seconds).

A path's poses are lattice nodes (denser with ``path_resolution``), each stamped with the time
to be there (the request's time on the node's clock plus the steps before it), facing the next
pose; the last keeps the goal's orientation.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
import contextlib
import functools
import time
import traceback

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
from nav_msgs.msg import OccupancyGrid, Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse
from rclpy.exceptions import InvalidHandle
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from stealth_interfaces.msg import SearchlightArray
from stealth_node_kit.conversions import seconds, yaw_quaternion
from stealth_node_kit.log_throttle import Throttle
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.qos import every_request_qos, kept_qos
from stealth_node_kit.running import StartupNode, run_node
from tf2_msgs.msg import TFMessage

from stealth_nav2.covert_planning import CovertPlanner, Pose, densify
from stealth_nav2.frame_tree import FrameError, FrameTree
from stealth_nav2.goal_queue import GoalQueue
from stealth_nav2.plan_errors import PlanError
from stealth_nav2.planner_parameters import PARAMETERS, task_numbers
from stealth_nav2.policy_behaviour import read_policy
from stealth_nav2.request_poses import (
    TRANSFORM_FIELDS,
    goal_label,
    planar_pose,
    point,
    request_pose,
)
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
        self._bad_tf_log = Throttle(5.0)
        self.create_subscription(TFMessage, '/tf', self._on_tf, TF_QOS)
        self.plan_publisher = self.create_publisher(Path, 'plan', latched)
        self._serve_actions(values)
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

    def _serve_actions(self, values) -> None:
        """The two actions, one goal planned at a time on a thread of its own: goals are
        accepted (and queued) while one is planned. Their request services keep every request
        (``every_request_qos``: rclpy's default kept 10, and the rest of a burst were never
        answered); a result is kept action_server_result_timeout s after its goal ended."""
        self.queue = GoalQueue(values['max_queued_goals'])
        self._refusals, self._refusal_log = 0, Throttle(1.0)
        self._planning = ThreadPoolExecutor(max_workers=1, thread_name_prefix='planning')
        self._planned = self.create_guard_condition(lambda: None)  # wakes the executor
        requests = every_request_qos()
        for action_type, name in (
            (ComputePathToPose, 'compute_path_to_pose'),
            (ComputePathThroughPoses, 'compute_path_through_poses'),
        ):
            ActionServer(
                self, action_type, name, functools.partial(self._execute, action_type),
                handle_accepted_callback=functools.partial(self._on_accepted, action_type),
                cancel_callback=self._cancel,
                goal_service_qos_profile=requests,
                result_service_qos_profile=requests,
                cancel_service_qos_profile=requests,
                result_timeout=values['action_server_result_timeout'],
            )  # fmt: skip

    def destroy_node(self) -> None:
        planning = getattr(self, '_planning', None)
        if planning is not None:  # a plan under way ends on its own; none starts
            planning.shutdown(wait=False, cancel_futures=True)
        super().destroy_node()

    # --- parameters -----------------------------------------------------------------------

    def _validate_parameters(self, changes) -> SetParametersResult:
        """rclpy checks types, ranges and read-only; this refuses nan and inf, and applies."""
        reason = non_finite(changes)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        for change in changes:
            if change.name == 'dark_path_weight':
                self.planner.dark_path_weight = float(change.value)
            elif change.name == 'max_queued_goals':
                self.queue.capacity = change.value
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
            p, q = transform.transform.translation, transform.transform.rotation
            try:
                pose = planar_pose((p.x, p.y, p.z), (q.x, q.y, q.z, q.w), TRANSFORM_FIELDS)
            except ValueError as error:  # kept out of the tree: it would carry nan into poses
                if self._bad_tf_log():
                    self.get_logger().warn(
                        f'/tf: transform {transform.header.frame_id!r} -> '
                        f'{transform.child_frame_id!r} ignored: {error}'
                    )
                continue
            self.frames.update(transform.header.frame_id, transform.child_frame_id, pose)

    # --- requests -------------------------------------------------------------------------

    def _on_accepted(self, action_type, goal_handle) -> None:
        """Queue an accepted goal (``goal_queue``) and start it when nothing else runs; when
        max_queued_goals already wait, end it at once (``_refuse``)."""
        if self.queue.full:
            goal_handle.execute(functools.partial(self._refuse, action_type))
        elif self.queue.arrive(goal_handle):
            goal_handle.execute()

    def _cancel(self, goal_handle) -> CancelResponse:
        """Accept every cancel: a waiting goal leaves the queue and ends CANCELED now, the one
        being planned when its planning ends (its path is dropped)."""
        if self.queue.withdraw(goal_handle):
            goal_handle.execute()
        return CancelResponse.ACCEPT

    def _refuse(self, action_type, goal_handle):
        """A goal that found max_queued_goals waiting: aborted, UNKNOWN, saying so (logged at
        most once a second, with the count)."""
        result = action_type.Result()
        result.error_code = action_type.Result.UNKNOWN
        result.error_msg = (
            f'the planner server is busy: {len(self.queue)} goals are waiting already '
            f'(max_queued_goals {self.queue.capacity}); send it again once one is answered'
        )
        self._refusals += 1
        if self._refusal_log():
            self.get_logger().warn(f'{result.error_msg} ({self._refusals} refused so far)')
        goal_handle.abort()
        return result

    async def _execute(self, action_type, goal_handle):
        """One request, then the next waiting goal's turn."""
        try:
            return await self._serve(action_type, goal_handle)
        finally:
            following = self.queue.finish(goal_handle)
            if following is not None:
                following.execute()

    async def _serve(self, action_type, goal_handle):
        """The path, or aborted with Nav2's error code and the reason. The inputs (scene,
        start, goals in the map) are read here, on the executor's thread; the planning and the
        path message are made on the planning thread, while this thread goes on taking goals,
        cancels and messages."""
        result = action_type.Result()
        if goal_handle.is_cancel_requested:
            goal_handle.canceled()
            return result
        request = goal_handle.request
        started = time.perf_counter()
        now = self.get_clock().now()
        planner_id = request.planner_id
        goals = list(request.goals) if action_type is ComputePathThroughPoses else [request.goal]
        try:
            if not goals:  # Nav2 says so before it looks for the start
                raise PlanError('NO_VIAPOINTS_GIVEN', 'no goals given: expected at least one pose')
            scene = self._scene()
            start = self._start(request, scene.frame_id)
            targets = [
                self._in_frame(goal, scene.frame_id, 'GOAL', goal_label(k, len(goals)))
                for k, goal in enumerate(goals)
            ]
            limit = self._value('max_planning_time') or None
            t = seconds(now.to_msg()) - self._value('lights_time_offset')
            job = self._planning.submit(
                self._plan_path, scene, start, targets, planner_id, t, limit, now,
                self._value('path_resolution'),
            )  # fmt: skip
            job.add_done_callback(self._on_planned)
            path = await _Finished(job)
        except PlanError as error:
            return self._abort(goal_handle, result, error.code, str(error), planner_id, goals)
        except Exception as error:  # a bug: answered as Nav2 does (UNKNOWN), the traceback kept
            self.get_logger().error(
                f'planning failed: {"".join(traceback.format_exception(error)).rstrip()}'
            )
            reason = f'the planner failed: {type(error).__name__}: {error}'
            return self._abort(goal_handle, result, 'UNKNOWN', reason, planner_id, goals)
        if goal_handle.is_cancel_requested:
            goal_handle.canceled()
            return result
        result.path = path
        result.planning_time = _duration(time.perf_counter() - started)
        self.plan_publisher.publish(path)
        goal_handle.succeed()
        return result

    def _on_planned(self, _job) -> None:
        """A planning job's done callback (on the planning thread): wake the executor, whose
        task awaiting the job then runs again; once the node is destroyed none waits."""
        with contextlib.suppress(InvalidHandle):
            self._planned.trigger()

    def _plan_path(self, scene, start, targets, planner_id, t, limit, now, resolution) -> Path:
        """On the planning thread: the plan's Path message (PlanError when there is none)."""
        plan = self.planner.plan_through(scene, start, targets, planner_id, t, limit)
        return _path_msg(plan, scene.frame_id, now, resolution)

    def _abort(self, goal_handle, result, code: str, reason: str, planner_id: str, goals):
        self.get_logger().warn(
            f'{planner_id or "covert"} plugin failed to plan to {_where(goals)}: "{reason}"'
        )
        result.error_code = getattr(type(result), code)
        result.error_msg = reason
        goal_handle.abort()
        return result

    def _scene(self):
        try:
            return self.source.current()
        except SceneError as error:
            raise PlanError('UNKNOWN', str(error)) from None

    def _start(self, request, frame: str) -> Pose:
        if request.use_start:
            return self._in_frame(request.start, frame, 'START', 'start')
        if self._robot is None:
            raise PlanError(
                'TF_ERROR',
                'no start: use_start is false and nothing has arrived on '
                f'{self.resolve_topic_name("amcl_pose")} (geometry_msgs/'
                'PoseWithCovarianceStamped) yet',
            )
        robot = PoseStamped(header=self._robot.header, pose=self._robot.pose.pose)
        return self._in_frame(robot, frame, 'START', 'start (amcl_pose)')

    def _in_frame(self, stamped: PoseStamped, frame: str, role: str, what: str) -> Pose:
        """The pose in the scene's frame: {role}_OUTSIDE_MAP naming a field that is no
        number or rotation (``request_poses``), TF_ERROR naming the frame when it cannot be
        carried into the scene's."""
        p, q = stamped.pose.position, stamped.pose.orientation
        pose = request_pose(role, what, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
        source = stamped.header.frame_id or frame
        try:
            return Pose(*self.frames.transform(pose, source, frame))
        except FrameError as error:
            raise PlanError('TF_ERROR', f'{what} in frame {source!r}: {error}') from None


def _path_msg(plan, frame: str, now, resolution: float) -> Path:
    """The plan as a Path stamped from ``now``, densified to ``resolution`` m (0: nodes)."""
    poses, times = densify(plan.poses, plan.times, resolution)
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


class _Finished:
    """Awaitable on rclpy's executor: the result of a job on another thread (its exception
    raised). rclpy runs a waiting task again whenever the executor wakes; the job's done
    callback triggers a guard condition to wake it."""

    def __init__(self, job):
        self.job = job

    def __await__(self):
        while not self.job.done():
            yield
        return self.job.result()


def _where(goals) -> str:
    if not goals:
        return 'no goal'
    p = goals[-1].pose.position
    return point(p.x, p.y)


def _duration(elapsed: float) -> Duration:
    whole = int(elapsed)
    return Duration(sec=whole, nanosec=int((elapsed - whole) * 1e9))


def main(args=None) -> int:
    return run_node(PlannerServer, NODE_NAME, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
