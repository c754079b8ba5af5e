"""The environment's messages built from the core's values, and poses read back from messages.

Plain functions over message classes (no node, no rclpy), so what the environment publishes can
be checked without a running ROS graph: the simulator's ExecuteMove request for a move;
RLEnvDescription, RLStateReward, StepInfo and EpisodeSummary of the RL loop, and its
GridObservation; SearchlightArray,
the scene's MarkerArray, the visibility and sensed-light OccupancyGrids and the planned Path;
and the check of the simulator's map against the scenario's. Every stamped message is in
frame ``map``.
"""

from __future__ import annotations

import array
import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose2D, PoseStamped
from nav_msgs.msg import OccupancyGrid, Path
import numpy as np
from std_msgs.msg import ColorRGBA
from stealth_core.grid_observation import CHANNELS
from stealth_core.kinematics import Pose
from stealth_interfaces.msg import (
    EpisodeSummary,
    GridObservation,
    RLEnvDescription,
    RLStateReward,
    Searchlight,
    SearchlightArray,
    StepInfo,
)
from stealth_interfaces.srv import ExecuteMove
from stealth_node_kit.conversions import grid_msg, quaternion_yaw, time_msg
from visualization_msgs.msg import Marker, MarkerArray

from stealth_env.episode_flow import PlanarPose
from stealth_env.markers import searchlight_fields
from stealth_env.topic_moves import MoveGoal

MAP_FRAME = 'map'
MARKER_KINDS = {
    'triangle_list': Marker.TRIANGLE_LIST,
    'line_strip': Marker.LINE_STRIP,
    'sphere': Marker.SPHERE,
    'cylinder': Marker.CYLINDER,
    'text': Marker.TEXT_VIEW_FACING,
}
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def float32(value: float) -> float:
    """A value a float32 field accepts (rclpy refuses values beyond float32's range)."""
    return float(min(max(value, -_FLOAT32_MAX), _FLOAT32_MAX))


# --- poses --------------------------------------------------------------------------------------


def pose_of(pose) -> Pose:
    """(x, y, yaw) of a geometry_msgs/Pose."""
    return Pose(pose.position.x, pose.position.y, quaternion_yaw(pose.orientation))


def pose2d_msg(pose: PlanarPose) -> Pose2D:
    return Pose2D(x=float(pose.x), y=float(pose.y), theta=float(pose.yaw))


def move_request(move: MoveGoal) -> ExecuteMove.Request:
    """sim/execute_move's request for a move: GO_TO its target, HOLD, or TURN_TO_HEADING."""
    if move.target is not None:
        x, y = move.target
        return ExecuteMove.Request(kind=ExecuteMove.Request.GO_TO, x=x, y=y)
    if move.hold > 0:
        return ExecuteMove.Request(kind=ExecuteMove.Request.HOLD, seconds=move.hold)
    if move.distance:
        raise ValueError(f'{move}: the simulator has no turn-then-drive move')
    return ExecuteMove.Request(kind=ExecuteMove.Request.TURN_TO_HEADING, heading=move.heading)


# --- the RL loop --------------------------------------------------------------------------------


def description_msg(fields: dict) -> RLEnvDescription:
    """RLEnvDescription of ``StealthTask.description``'s fields."""
    return RLEnvDescription(
        num_actions=float(fields['num_actions']),
        num_states=float(fields['num_states']),
        min_state_range=[float(v) for v in fields['min_state_range']],
        max_state_range=[float(v) for v in fields['max_state_range']],
        max_reward=float(fields['max_reward']),
        reward_range=float(fields['reward_range']),
        stochastic=bool(fields['stochastic']),
        episodic=bool(fields['episodic']),
        title=fields['title'],
    )


def state_reward_msg(state, reward: float = 0.0, terminal: bool = False) -> RLStateReward:
    """A state for the agent: a first state (reward 0), a step's result, or an abort's terminal
    state (reward 0: rl_msgs has no other way to end an episode)."""
    return RLStateReward(state=list(state), reward=reward, terminal=terminal)


def grid_observation_msg(
    grid: np.ndarray,
    layout: str,
    geometry,
    t: float,
    episode: int = 0,
    step: int = 0,
    channel_names=CHANNELS,
) -> GridObservation:
    """GridObservation of a (rows, cols, channels) float32 grid, or a phased grid (layers, rows,
    cols, channels) (``grid_observation``), its layout id, channel names and (resolution,
    origin x, origin y) (``grid_observation.lattice_geometry``), for the state of ``episode``
    and ``step`` (the sensed track's; 0 on the full track's)."""
    grid = np.ascontiguousarray(grid, dtype=np.float32)
    layers, rows, cols, channels = grid.shape if grid.ndim == 4 else (1, *grid.shape)
    message = GridObservation(layout=layout, rows=rows, cols=cols, channels=channels)
    message.layers = layers
    message.episode, message.step = int(episode), int(step)
    message.header.stamp, message.header.frame_id = time_msg(t), MAP_FRAME
    message.channel_names = list(channel_names)
    resolution, x, y = geometry
    message.resolution = float(resolution)
    message.origin = Point(x=float(x), y=float(y), z=0.0)
    message.data = array.array('f', grid.tobytes())
    return message


def step_info_msg(
    report, state: list, reward: float, stamp: Time, truth_known: bool = True
) -> StepInfo:
    """StepInfo of an ``EpisodeFlow`` StepReport. truth_known False: no ground truth is
    published, the step was judged on the estimate and ``true_pose`` is NaN."""
    judgement = report.judgement
    info = StepInfo(
        episode=report.episode,
        step=report.step,
        action=report.action,
        state=state,
        reward=reward,
        visibility=float32(judgement.visibility),
        distance_to_goal=float32(judgement.distance_to_goal),
        detected=judgement.detected,
        terminal=report.terminal,
        estimated_pose=pose2d_msg(report.estimate),
        true_pose=pose2d_msg(report.truth if truth_known else PlanarPose(*[math.nan] * 3)),
    )
    info.header.stamp, info.header.frame_id = stamp, MAP_FRAME
    return info


def summary_msg(summary, stamp: Time) -> EpisodeSummary:
    """EpisodeSummary of the core's EpisodeSummaryFields."""
    message = EpisodeSummary(
        episode=summary.episode,
        outcome=summary.outcome,
        steps=summary.steps,
        total_reward=float32(summary.total_reward),
        peak_visibility=float32(summary.peak_visibility),
        accumulated_visibility=float32(summary.accumulated_visibility),
        path_length=float32(summary.path_length),
        final_distance_to_goal=float32(summary.final_distance_to_goal),
        goal=summary.goal,
    )
    message.header.stamp, message.header.frame_id = stamp, MAP_FRAME
    return message


# --- the scene ----------------------------------------------------------------------------------


def searchlight_array_msg(lights, t: float) -> SearchlightArray:
    """The lights at time t (s of the episode's clock)."""
    stamp = time_msg(t)
    lights_msg = SearchlightArray()
    lights_msg.header.stamp, lights_msg.header.frame_id = stamp, MAP_FRAME
    for light in lights:
        fields = searchlight_fields(light, t)
        x, y = fields.pop('position')
        waypoints = [Point(x=float(px), y=float(py)) for px, py in fields.pop('waypoints')]
        message = Searchlight(
            position=Point(x=float(x), y=float(y)), waypoints=waypoints, **fields
        )
        message.header.stamp, message.header.frame_id = stamp, MAP_FRAME
        lights_msg.lights.append(message)
    return lights_msg


def marker_array_msg(specs, t: float) -> MarkerArray:
    """The scene: a DELETEALL (stale markers of an earlier scene go), then every marker."""
    stamp = time_msg(t)
    clear = Marker(action=Marker.DELETEALL)
    clear.header.stamp, clear.header.frame_id = stamp, MAP_FRAME
    markers = [clear]
    for spec in specs:
        marker = Marker(ns=spec.namespace, id=spec.id, type=MARKER_KINDS[spec.kind])
        marker.action = Marker.ADD
        marker.header.stamp, marker.header.frame_id = stamp, MAP_FRAME
        marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = spec.position
        marker.pose.orientation.w = 1.0
        marker.scale.x, marker.scale.y, marker.scale.z = (float(v) for v in spec.scale)
        marker.color = _colour(spec.color)
        marker.points = [Point(x=p[0], y=p[1], z=p[2]) for p in spec.points]
        marker.colors = [_colour(c) for c in spec.colors]
        marker.text = spec.text
        markers.append(marker)
    return MarkerArray(markers=markers)


def _colour(rgba) -> ColorRGBA:
    return ColorRGBA(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))


def visibility_grid_msg(occupancy, levels: np.ndarray, t: float) -> OccupancyGrid:
    """The lit area (``markers.visibility_levels``) at time t on the map's grid, as a costmap."""
    return grid_msg(levels, occupancy.resolution, occupancy.origin, t)


def path_msg(points) -> Path:
    """nav_msgs/Path through (x, y) points of the map frame."""
    plan = Path()
    plan.header.frame_id = MAP_FRAME
    for x, y in points:
        pose = PoseStamped()
        pose.header.frame_id = MAP_FRAME
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        pose.pose.orientation.w = 1.0
        plan.poses.append(pose)
    return plan


def map_mismatch(occupancy, grid: OccupancyGrid) -> str:
    """How a nav_msgs/OccupancyGrid differs from a map ('' when it does not)."""
    info = grid.info
    x, y, _ = occupancy.origin
    origin = info.origin.position
    theirs = (info.width, info.height, info.resolution, origin.x, origin.y)
    ours = (occupancy.width, occupancy.height, occupancy.resolution, x, y)
    if theirs[:2] != ours[:2] or not np.allclose(theirs[2:], ours[2:], rtol=0, atol=1e-6):
        return f'{_grid_text(*theirs)}, expected {_grid_text(*ours)}'
    different = int(np.count_nonzero(np.asarray(grid.data) != occupancy.data.ravel()))
    return f'{different} cells differ' if different else ''


def _grid_text(width, height, resolution, x, y) -> str:
    return f'{width} x {height} cells of {resolution:g} m from ({x:g}, {y:g})'
