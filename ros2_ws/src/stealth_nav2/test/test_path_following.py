"""The path follower's core: legs from a path (timed or not), pace, holds, replans."""

import math

import pytest
from stealth_env.topic_moves import Limits, MoveOutcome, Pose
from stealth_nav2.path_following import (
    Arrived,
    FollowSettings,
    LegKind,
    Move,
    PathFollower,
    Replan,
    TimedPose,
    is_timed,
    legs_of,
    path_problem,
)

SETTINGS = FollowSettings()
EAST, NORTH = 0.0, math.pi / 2


def untimed(*points, t=5.0):
    """Nav2's planners' way: every pose carries the path's stamp; yaw along the path."""
    poses = []
    for index, (x, y) in enumerate(points):
        nxt = points[min(index + 1, len(points) - 1)]
        prev = points[max(index - 1, 0)]
        a, b = (prev, nxt) if index == len(points) - 1 else ((x, y), nxt)
        poses.append(TimedPose(x, y, math.atan2(b[1] - a[1], b[0] - a[0]), t))
    return poses


def test_an_untimed_straight_run_is_one_drive_then_the_corner():
    poses = untimed((0, 0), (0.5, 0), (1.0, 0), (1.5, 0), (1.5, 0.5), (1.5, 1.0))
    legs = legs_of(poses, Pose(0, 0, 0), SETTINGS)
    assert [(leg.kind, leg.x, leg.y, leg.arrive_by) for leg in legs] == [
        (LegKind.DRIVE, 1.5, 0, None),
        (LegKind.DRIVE, 1.5, 1.0, None),
    ]
    assert (legs[1].x0, legs[1].y0, legs[1].heading) == (1.5, 0, pytest.approx(NORTH))
    assert not is_timed(poses)


def test_timed_runs_merge_only_at_an_even_pace_and_a_later_stamp_at_one_place_is_a_wait():
    poses = [
        TimedPose(0, 0, EAST, 10.0),
        TimedPose(0.5, 0, EAST, 13.0),
        TimedPose(1.0, 0, EAST, 16.0),  # even: merged with the previous
        TimedPose(1.0, 0, EAST, 22.0),  # waits two steps for a beam
        TimedPose(1.5, 0, EAST, 25.0),
        TimedPose(2.0, 0, EAST, 31.0),  # slower: a leg of its own
    ]
    assert is_timed(poses)
    legs = legs_of(poses, Pose(0.02, 0.01, 0.0), SETTINGS)  # joins the path at pose 0
    assert [(leg.kind, leg.x0, leg.x, leg.t0, leg.arrive_by, leg.last) for leg in legs] == [
        (LegKind.WAIT, 0, 0, None, 10.0, 0),  # be at the first pose by its stamp
        (LegKind.DRIVE, 0, 1.0, 10.0, 16.0, 2),
        (LegKind.WAIT, 1.0, 1.0, 16.0, 22.0, 3),
        (LegKind.DRIVE, 1.0, 1.5, 22.0, 25.0, 4),
        (LegKind.DRIVE, 1.5, 2.0, 25.0, 31.0, 5),
    ]
    assert PathFollower(poses, Pose(0, 0, 0), SETTINGS).waits == 1


def test_a_wait_at_a_corner_turns_first_then_holds_to_its_stamp():
    """The covert planner's poses face the next pose elsewhere: at a corner where the plan
    waits, the waiting pose already faces the way out."""
    poses = [
        TimedPose(0, 0, EAST, 0.0),
        TimedPose(0.5, 0, NORTH, 3.0),
        TimedPose(0.5, 0, NORTH, 6.0),  # waits a step, facing north
        TimedPose(0.5, 0.5, NORTH, 9.0),
    ]
    follower = PathFollower(poses, Pose(0, 0, EAST), SETTINGS)
    assert [(leg.kind, leg.arrive_by) for leg in follower.legs] == [
        (LegKind.WAIT, 0.0),  # at the first pose at its stamp (now: no hold)
        (LegKind.DRIVE, 3.0),
        (LegKind.TURN, 6.0),
        (LegKind.DRIVE, 9.0),
    ]
    assert follower.waits == 1
    follower.next_move(now=0.0)
    assert follower.move_ended(MoveOutcome.DONE, '', 2.5, Pose(0.5, 0, EAST)) is None
    assert follower.next_move(now=2.5).goal.hold == pytest.approx(0.5)  # early: hold to 3 s
    assert follower.move_ended(MoveOutcome.DONE, '', 3.0, Pose(0.5, 0, EAST)) is None
    turn = follower.next_move(now=3.0)
    assert turn.goal.heading == pytest.approx(NORTH) and turn.goal.distance == 0
    assert follower.move_ended(MoveOutcome.DONE, '', 4.1, Pose(0.5, 0, NORTH)) is None
    assert follower.next_move(now=4.1).goal.hold == pytest.approx(1.9)  # the rest of the wait


def test_a_turn_in_place_and_the_goal_orientation_are_turns():
    poses = [
        TimedPose(0, 0, EAST, 0.0),
        TimedPose(0, 0, NORTH, 0.0),  # a turn action of an exposure scenario
        TimedPose(0, 0.5, math.pi, 0.0),  # the goal, to be faced west
    ]
    legs = legs_of(poses, Pose(0, 0, EAST), SETTINGS)
    assert [(leg.kind, round(leg.heading, 3)) for leg in legs] == [
        (LegKind.TURN, round(NORTH, 3)),
        (LegKind.DRIVE, round(NORTH, 3)),
        (LegKind.TURN, round(math.pi, 3)),
    ]


def test_a_robot_away_from_the_first_pose_drives_onto_the_path():
    poses = untimed((0, 0), (0.5, 0))
    legs = legs_of(poses, Pose(-1.0, 0, 0), SETTINGS)
    assert [(leg.kind, leg.x0, leg.x, leg.t0) for leg in legs] == [
        (LegKind.DRIVE, -1.0, 0.5, None),  # straight through pose 0: one drive
    ]


@pytest.mark.parametrize(
    ('poses', 'problem'),
    [
        ([], 'the path has no poses'),
        ([TimedPose(0, math.nan, 0, 0)], 'pose 0 of the path is not finite'),
        (
            [TimedPose(0, 0, 0, 5.0), TimedPose(1, 0, 0, 4.0)],
            'pose 1 of the path is stamped 4.000 s, before pose 0 (5.000 s)',
        ),
    ],
)
def test_paths_that_cannot_be_followed_say_why(poses, problem):
    assert problem in path_problem(poses)
    if poses:
        with pytest.raises(ValueError, match='pose'):
            PathFollower(poses, Pose(0, 0, 0), SETTINGS)


def test_a_timed_drive_is_paced_to_its_stamp_and_an_early_arrival_holds():
    limits = Limits(max_linear_speed=0.5, max_angular_speed=1.5, max_linear_accel=1.0)
    settings = FollowSettings(limits=limits)
    poses = [TimedPose(0, 0, EAST, 100.0), TimedPose(1.0, 0, EAST, 106.0)]
    follower = PathFollower(poses, Pose(0, 0, EAST), settings)
    move = follower.next_move(now=100.0)
    assert isinstance(move, Move)
    assert move.goal.target == (1.0, 0)
    # 6 s for 1 m, less the 0.5 s of speed ramps: 1 / 5.5 m/s.
    assert move.limits.max_linear_speed == pytest.approx(1 / 5.5)
    assert follower.move_ended(MoveOutcome.DONE, '', 104.0, Pose(1.0, 0, EAST)) is None
    hold = follower.next_move(now=104.0)
    assert hold.goal.hold == pytest.approx(2.0)
    assert follower.move_ended(MoveOutcome.DONE, '', 106.0, Pose(1.0, 0, EAST)) is None
    assert follower.next_move(now=106.0) == Arrived(0.0)


def test_a_drive_that_cannot_be_on_time_runs_at_the_limit():
    poses = [TimedPose(0, 0, EAST, 0.0), TimedPose(3.0, 0, EAST, 1.0)]
    follower = PathFollower(poses, Pose(0, 0, EAST), SETTINGS)
    assert follower.next_move(now=0.0).limits == SETTINGS.limits


def test_an_untimed_path_runs_at_the_limit_without_holds():
    follower = PathFollower(untimed((0, 0), (1, 0)), Pose(0, 0, 0), SETTINGS)
    move = follower.next_move(now=0.0)
    assert move.limits == SETTINGS.limits
    assert follower.move_ended(MoveOutcome.DONE, '', 3.0, Pose(1, 0, 0)) is None
    assert follower.next_move(now=3.0) == Arrived(0.0)


@pytest.mark.parametrize(
    ('outcome', 'now', 'end', 'reason'),
    [
        (MoveOutcome.BUMPED, 2.0, Pose(0.5, 0, 0), 'blocked: the robot met a wall'),
        (MoveOutcome.TIMED_OUT, 2.0, Pose(0.5, 0, 0), 'the move timed out'),
        (MoveOutcome.DONE, 2.0, Pose(1.0, 0.7, 0), 'strayed: ended 0.70 m from the path'),
        (MoveOutcome.DONE, 9.0, Pose(1.0, 0, 0), '4.0 s late at pose 1 of the path'),
    ],
)
def test_blocked_timed_out_strayed_or_late_asks_for_a_new_plan(outcome, now, end, reason):
    poses = [TimedPose(0, 0, EAST, 0.0), TimedPose(1.0, 0, EAST, 5.0)]
    follower = PathFollower(poses, Pose(0, 0, EAST), SETTINGS)
    follower.next_move(now=0.0)
    message = 'the robot met a wall or unknown space and stopped'
    result = follower.move_ended(outcome, message, now, end)
    assert isinstance(result, Replan)
    assert reason in result.reason
    assert result.recovery == ('late' not in reason)  # behind schedule: a plain replan


def test_a_leg_that_runs_late_asks_for_a_plan_while_it_runs_but_never_the_first():
    poses = [TimedPose(0, 0, EAST, 0.0), TimedPose(1.0, 0, EAST, 3.0), TimedPose(1, 1, NORTH, 6.0)]
    follower = PathFollower(poses, Pose(0, 0, EAST), SETTINGS)
    follower.next_move(now=0.0)
    assert follower.behind(now=10.0) is None  # the plan's first leg always finishes
    assert follower.move_ended(MoveOutcome.DONE, '', 3.0, Pose(1.0, 0, EAST)) is None
    follower.next_move(now=3.0)
    # The turn and the 1 m drive need 5.05 s at the limits, more than the 3 s the stamps give:
    # due at 8.05 s, late after 9.55 s.
    assert follower.behind(now=9.5) is None
    late = follower.behind(now=9.6)
    assert isinstance(late, Replan) and not late.recovery
    assert late.reason.startswith('3.6 s behind pose 2 of the path, 1.6 s more than the robot')


def test_stamps_the_robot_cannot_keep_are_followed_as_fast_as_it_can():
    """A static scene's nominal 1 s a step: late by the stamps, on time by the robot."""
    poses = [TimedPose(0, 0, EAST, 0.0), TimedPose(0.5, 0, EAST, 1.0), TimedPose(0.5, 0.5, 0, 2.0)]
    follower = PathFollower(poses, Pose(0, 0, EAST), SETTINGS)
    follower.next_move(now=0.0)
    assert follower.move_ended(MoveOutcome.DONE, '', 2.0, Pose(0.5, 0, EAST)) is None
    follower.next_move(now=2.0)
    assert follower.move_ended(MoveOutcome.DONE, '', 6.0, Pose(0.5, 0.5, NORTH)) is None


def test_a_path_late_on_arrival_allows_that_much_more_lateness():
    poses = [TimedPose(0, 0, EAST, 0.0), TimedPose(1.0, 0, EAST, 5.0)]
    follower = PathFollower(poses, Pose(0, 0, EAST), SETTINGS, now=2.0)  # planning took 2 s
    follower.next_move(now=2.0)
    assert follower.move_ended(MoveOutcome.DONE, '', 8.0, Pose(1.0, 0, 0)) is None
    late = PathFollower(poses, Pose(0, 0, EAST), SETTINGS, now=0.0)
    late.next_move(now=0.0)
    assert isinstance(late.move_ended(MoveOutcome.DONE, '', 8.0, Pose(1.0, 0, 0)), Replan)


def test_progress_distance_time_and_how_far_off_the_path():
    poses = [
        TimedPose(0, 0, EAST, 10.0),
        TimedPose(1.0, 0, EAST, 16.0),
        TimedPose(1.0, 1.0, NORTH, 22.0),
    ]
    follower = PathFollower(poses, Pose(0, 0, EAST), SETTINGS)
    follower.next_move(now=10.0)
    here = Pose(0.4, 0.1, EAST)
    assert follower.distance_remaining(here) == pytest.approx(math.dist((0.4, 0.1), (1, 0)) + 1)
    assert follower.time_remaining(here, now=12.0) == pytest.approx(10.0)
    assert follower.off_path(here) == pytest.approx(0.1)
    assert follower.off_path(Pose(-0.3, 0.4, 0)) == pytest.approx(0.5)  # from the leg's start
