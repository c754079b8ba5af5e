"""A goal's planner, frame, via poses and FollowWaypoints' order, decided without rclpy."""

import math

import pytest
from stealth_core.kinematics import Pose
from stealth_nav2.navigation_goals import (
    PLANNER_IDS,
    Frames,
    ViaPoses,
    WaypointRun,
    goal_in_map,
    navigator_code,
    planner_for,
)


def test_behavior_tree_selects_the_planner_or_is_refused_naming_the_choices():
    assert planner_for('', 'covert', PLANNER_IDS) == ('covert', '')
    assert planner_for('policy', 'covert', PLANNER_IDS) == ('policy', '')
    planner, problem = planner_for('/opt/bt/navigate.xml', 'covert', PLANNER_IDS)
    assert planner == ''
    assert problem == (
        "behavior_tree '/opt/bt/navigate.xml': this navigator runs no behaviour trees; give '' "
        '(the planner_id parameter, covert) or a planner id: covert, dark_path, astar, policy'
    )


def test_codes_of_the_two_navigators():
    assert navigator_code(9002, through_poses=False) == 9002
    assert navigator_code(9002, through_poses=True) == 9102


def test_goals_in_the_odom_and_robot_frames_go_through_the_robots_pose():
    frames = Frames()
    estimate = Pose(10.0, 5.0, math.pi / 2)  # map
    odom = Pose(1.0, 0.0, 0.0)  # the same instant, in odom: odom is turned 90 degrees
    assert goal_in_map('map', Pose(1, 2, 0), frames, None, None) == (Pose(1, 2, 0), '')
    ahead, problem = goal_in_map('base_link', Pose(1.0, 0.0, 0.0), frames, estimate, odom)
    assert problem == ''
    assert ahead == pytest.approx((10.0, 6.0, math.pi / 2))
    beside, problem = goal_in_map('odom', Pose(2.0, 0.0, 0.0), frames, estimate, odom)
    assert beside == pytest.approx((10.0, 6.0, math.pi / 2))


@pytest.mark.parametrize(
    ('frame', 'estimate', 'problem'),
    [
        ('', Pose(0, 0, 0), "header.frame_id '': expected 'map' (or 'odom', 'base_link', "),
        ('camera', Pose(0, 0, 0), "header.frame_id 'camera': expected 'map'"),
        ('odom', None, "frame 'odom': no pose of the robot yet to transform it to 'map'"),
    ],
)
def test_a_goal_in_a_frame_it_cannot_transform_is_refused_by_name(frame, estimate, problem):
    odom = None if estimate is None else Pose(0, 0, 0)
    goal, why = goal_in_map(frame, Pose(1, 1, 0), Frames(), estimate, odom)
    assert goal is None
    assert problem in why


def test_via_poses_are_passed_in_order_never_the_goal():
    via = ViaPoses([Pose(1, 0, 0), Pose(2, 0, 0), Pose(3, 0, 0)], radius=0.5)
    assert not via.passed(Pose(2.0, 0, 0))  # the next one is (1, 0): not reached yet
    assert via.passed(Pose(1.2, 0, 0))
    assert len(via.poses) == 2
    via.passed(Pose(2.1, 0, 0))
    assert not via.passed(Pose(3.0, 0, 0))
    assert via.poses == [Pose(3, 0, 0)]


def test_waypoints_loop_from_goal_index_and_stop_or_go_on_after_a_failure():
    run = WaypointRun(3, goal_index=1, loops=1, stop_on_failure=False)
    order = [run.index]
    while not run.finished(succeeded=run.index != 2, error_code=208, message='no route'):
        order.append(run.index)
    assert order == [1, 2, 0, 1, 2]
    assert [(m.index, m.error_code) for m in run.missed] == [(2, 208), (2, 208)]
    stopping = WaypointRun(3, goal_index=0, loops=0, stop_on_failure=True)
    assert not stopping.finished(True)
    assert stopping.finished(False, 105, 'blocked')
    assert stopping.missed[0].index == 1


@pytest.mark.parametrize(
    ('count', 'index', 'problem'),
    [(0, 0, 'poses: no waypoints given'),
     (2, 2, 'goal_index 2: expected less than the 2 waypoints')],
)  # fmt: skip
def test_waypoint_requests_that_cannot_run_say_why(count, index, problem):
    assert WaypointRun(count, index, 0, True).problem() == problem
