"""The environment's messages from the core's values, without a node."""

import math

from geometry_msgs.msg import Pose as PoseMsg
from nav_msgs.msg import OccupancyGrid
import numpy as np
import pytest
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import load_scenario
from stealth_core.task import EpisodeSummaryFields, StealthTask
from stealth_env.env_messages import (
    MAP_FRAME,
    MARKER_KINDS,
    description_msg,
    float32,
    grid_msg,
    map_mismatch,
    marker_array_msg,
    move_request,
    path_msg,
    pose2d_msg,
    pose_of,
    searchlight_array_msg,
    state_reward_msg,
    step_info_msg,
    summary_msg,
    visibility_grid_msg,
)
from stealth_env.episode_flow import EpisodeFlow, PlanarPose
from stealth_env.markers import WallMap, scene_markers, searchlight_fields
from stealth_env.topic_moves import MoveGoal, go_to, hold_goal
from stealth_interfaces.srv import ExecuteMove
from stealth_node_kit.conversions import time_msg, yaw_quaternion
from visualization_msgs.msg import Marker

FLOAT32_MAX = float(np.finfo(np.float32).max)


@pytest.fixture(scope='module')
def maze():
    return load_scenario('simple-maze')


def test_moves_become_the_simulators_requests():
    request = move_request(go_to(1.5, -2.0))
    assert (request.kind, request.x, request.y) == (ExecuteMove.Request.GO_TO, 1.5, -2.0)
    request = move_request(hold_goal(0.75))
    assert (request.kind, request.seconds) == (ExecuteMove.Request.HOLD, 0.75)
    request = move_request(MoveGoal(math.pi / 2))
    assert (request.kind, request.heading) == (ExecuteMove.Request.TURN_TO_HEADING, math.pi / 2)
    with pytest.raises(ValueError, match='turn-then-drive'):
        move_request(MoveGoal(0.0, 1.0))  # the drive home's moves are the topics robot's only


def test_poses_read_back_and_written_out():
    message = PoseMsg()
    message.position.x, message.position.y = 2.0, -1.0
    message.orientation = yaw_quaternion(-2.5)
    x, y, yaw = pose_of(message)
    assert (x, y) == (2.0, -1.0) and yaw == pytest.approx(-2.5)
    pose = pose2d_msg(PlanarPose(np.float64(1.0), 2, 3.0))
    assert (pose.x, pose.y, pose.theta) == (1.0, 2.0, 3.0)


def test_float32_fields_are_clamped_to_their_range():
    assert float32(1.5) == 1.5
    assert float32(math.inf) == FLOAT32_MAX and float32(-1e300) == -FLOAT32_MAX


def test_the_description_and_states(maze):
    task = StealthTask(maze)
    fields = task.description(stochastic=True)
    message = description_msg(fields)
    assert message.num_actions == task.num_actions and message.title == task.title
    assert list(message.min_state_range) == pytest.approx(task.state_bounds()[0])
    assert list(message.max_state_range) == pytest.approx(task.state_bounds()[1])
    assert message.stochastic and message.episodic
    first = state_reward_msg((1.5, 1.5))
    assert (list(first.state), first.reward, first.terminal) == ([1.5, 1.5], 0.0, False)
    last = state_reward_msg((2.0, 1.5), 0.0, terminal=True)
    assert last.terminal and list(last.state) == [2.0, 1.5]


def test_step_info_of_a_step_report(maze):
    task = StealthTask(maze)
    flow = EpisodeFlow(task)
    token, _ = flow.begin_reset()
    flow.reset_done(token)
    assert flow.accept_action(3) is None
    estimate, truth = PlanarPose(2.0, 1.5, 0.1), PlanarPose(2.02, 1.49, 0.05)
    report = flow.finish_move(flow.token, estimate, truth, 3.25)
    stamp = time_msg(3.25)
    info = step_info_msg(report, list(report.state), report.reward, stamp)
    assert (info.episode, info.step, info.action) == (0, 1, 3)
    assert list(info.state) == list(report.state) and info.reward == report.reward
    assert info.terminal == report.terminal and info.detected == report.judgement.detected
    assert info.distance_to_goal == pytest.approx(report.judgement.distance_to_goal)
    assert (info.estimated_pose.x, info.estimated_pose.y) == (2.0, 1.5)
    assert (info.true_pose.x, info.true_pose.y, info.true_pose.theta) == (2.02, 1.49, 0.05)
    assert info.header.stamp == stamp and info.header.frame_id == MAP_FRAME
    unknown = step_info_msg(report, list(report.state), report.reward, stamp, truth_known=False)
    assert all(math.isnan(v) for v in (unknown.true_pose.x, unknown.true_pose.theta))
    assert unknown.estimated_pose == info.estimated_pose


def test_the_episode_summary():
    fields = EpisodeSummaryFields(
        7, EpisodeOutcome.DETECTED, 12, -3.5, 1.2, 4.0, 5.5, math.inf, 'hard'
    )
    message = summary_msg(fields, time_msg(10.0))
    assert (message.episode, message.outcome, message.steps, message.goal) == (
        7,
        EpisodeOutcome.DETECTED,
        12,
        'hard',
    )
    assert message.total_reward == -3.5 and message.path_length == 5.5
    assert message.final_distance_to_goal == FLOAT32_MAX  # inf does not fit a float32 field
    assert message.header.stamp.sec == 10 and message.header.frame_id == MAP_FRAME


def test_searchlights_and_markers_of_the_scene(maze):
    t = 2.5
    lights = searchlight_array_msg(maze.lights, t)
    assert len(lights.lights) == len(maze.lights) > 0
    assert lights.header.frame_id == MAP_FRAME and lights.header.stamp == time_msg(t)
    for message, light in zip(lights.lights, maze.lights, strict=True):
        fields = searchlight_fields(light, t)
        assert (message.position.x, message.position.y) == pytest.approx(fields['position'])
        assert len(message.waypoints) == len(fields['waypoints'])
        assert message.header.frame_id == MAP_FRAME
    specs = scene_markers(maze, 'easy', t, WallMap.of(maze.map))
    markers = marker_array_msg(specs, t).markers
    assert markers[0].action == Marker.DELETEALL and len(markers) == len(specs) + 1
    for marker, spec in zip(markers[1:], specs, strict=True):
        assert (marker.ns, marker.id, marker.type) == (spec.namespace, spec.id,
                                                       MARKER_KINDS[spec.kind])  # fmt: skip
        assert marker.action == Marker.ADD and len(marker.points) == len(spec.points)
        assert marker.color.a == pytest.approx(spec.color[3])
        assert marker.header.stamp == time_msg(t)


def test_the_visibility_grid_and_the_planned_path(maze):
    occupancy = maze.map
    levels = np.zeros((occupancy.height, occupancy.width), dtype=np.int8)
    levels[0, :3] = (0, 50, 100)
    grid = visibility_grid_msg(occupancy, levels, 4.0)
    assert (grid.info.width, grid.info.height) == (occupancy.width, occupancy.height)
    assert grid.info.resolution == pytest.approx(occupancy.resolution)
    assert list(grid.data[:3]) == [0, 50, 100] and len(grid.data) == levels.size
    assert grid.info.map_load_time == grid.header.stamp == time_msg(4.0)
    plan = path_msg([(1.5, 1.5), (2.0, 1.5)])
    assert [(p.pose.position.x, p.pose.position.y) for p in plan.poses] == [
        (1.5, 1.5),
        (2.0, 1.5),
    ]
    assert plan.header.frame_id == MAP_FRAME and plan.poses[0].pose.orientation.w == 1.0


def test_a_grid_of_levels_keeps_its_rows_cells_origin_and_unknowns():
    levels = np.array([[-1, 0, 100], [50, -1, -1]], dtype=np.int8)  # row 0 the southernmost
    grid = grid_msg(levels, 0.5, (-0.25, -0.75, 0.0), 2.0)
    assert (grid.info.width, grid.info.height, grid.info.resolution) == (3, 2, 0.5)
    assert list(grid.data) == [-1, 0, 100, 50, -1, -1]
    origin = grid.info.origin
    assert (origin.position.x, origin.position.y, origin.orientation.w) == (-0.25, -0.75, 1.0)
    assert grid.header.frame_id == MAP_FRAME and grid.header.stamp == time_msg(2.0)


def test_the_simulators_map_is_checked_against_the_scenarios(maze):
    occupancy = maze.map

    def grid_of(width, height, data):
        grid = OccupancyGrid()
        grid.info.width, grid.info.height = width, height
        grid.info.resolution = float(occupancy.resolution)
        grid.info.origin.position.x, grid.info.origin.position.y = occupancy.origin[:2]
        grid.data = [int(v) for v in data]
        return grid

    same = occupancy.data.ravel()
    assert map_mismatch(occupancy, grid_of(occupancy.width, occupancy.height, same)) == ''
    changed = same.copy()
    changed[:3] = 100 - np.clip(changed[:3], 0, 100)
    assert map_mismatch(occupancy, grid_of(occupancy.width, occupancy.height, changed)) == (
        '3 cells differ'
    )
    smaller = grid_of(occupancy.width - 1, occupancy.height, same[: -occupancy.height])
    assert map_mismatch(occupancy, smaller).endswith(
        f'expected {occupancy.width} x {occupancy.height} cells of 0.05 m from (0, 0)'
    )
