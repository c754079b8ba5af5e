"""The back-off recovery's core: a blocked robot backs off (and only a blocked one), straight
backwards on odometry, until it has gone the distance, stalls or runs out of time."""

import math

import pytest
from stealth_env.topic_moves import Command, MoveOutcome, Pose
from stealth_nav2.back_off import BackedOff, BackOff, BackOffSettings, backs_off, nearest_bearing
from stealth_nav2.path_following import FollowSettings, PathFollower, Replan, TimedPose

SETTINGS = BackOffSettings(distance=0.2, speed=0.1, stall_time=1.0)
PERIOD = 0.05  # s between odometry messages


def replan_after(outcome: MoveOutcome, end: Pose) -> Replan:
    """What the follower asks for when a drive east from (0, 0) to (1, 0) ends so."""
    poses = [TimedPose(0, 0, 0.0, 5.0), TimedPose(1.0, 0, 0.0, 5.0)]
    follower = PathFollower(poses, Pose(0, 0, 0), FollowSettings())
    follower.next_move(now=0.0)
    return follower.move_ended(outcome, 'the robot met a wall or unknown space', 2.0, end)


@pytest.mark.parametrize(
    ('outcome', 'end', 'expected'),
    [
        (MoveOutcome.BUMPED, Pose(0.6, 0, 0), True),  # against a wall: back off, then replan
        (MoveOutcome.TIMED_OUT, Pose(0.6, 0, 0), False),  # not against anything: replan
        (MoveOutcome.DONE, Pose(1.0, 0.7, 0), False),  # strayed: replan
    ],
)
def test_only_a_blocked_robot_backs_off_before_replanning(outcome, end, expected):
    replan = replan_after(outcome, end)
    assert isinstance(replan, Replan) and replan.recovery
    assert backs_off(replan, SETTINGS) is expected


def test_a_zero_distance_replans_at_once():
    replan = replan_after(MoveOutcome.BUMPED, Pose(0.6, 0, 0))
    assert not backs_off(replan, BackOffSettings(distance=0.0))


def drive(back_off: BackOff, start: Pose, t: float = 0.0, blocked_after: float = math.inf):
    """A diff-drive robot on perfect odometry under the back-off's commands (it cannot get more
    than ``blocked_after`` metres from ``start``): the commands, the end and its pose."""
    pose, commands = start, []
    for _ in range(2000):
        step = back_off.update(t, pose)
        if isinstance(step, BackedOff):
            return commands, step, pose
        commands.append(step)
        yaw = pose.yaw + step.angular * PERIOD
        x = pose.x + step.linear * PERIOD * math.cos(yaw)
        y = pose.y + step.linear * PERIOD * math.sin(yaw)
        away = math.dist((x, y), start[:2])
        if away > blocked_after:  # stopped where it is blocked
            x = start.x + (x - start.x) * blocked_after / away
            y = start.y + (y - start.y) * blocked_after / away
        pose = Pose(x, y, yaw)
        t += PERIOD
    raise AssertionError('the back-off never ended')


def test_a_blocked_robot_drives_straight_backwards_the_distance_slowly():
    start = Pose(11.45, -2.2, math.pi)  # facing the east corridor's west wall
    commands, end, pose = drive(BackOff(start, 100.0, SETTINGS), start, 100.0)
    assert all(c.linear < 0 and c.angular == 0 for c in commands)  # backwards, no turn
    assert all(abs(c.linear) <= SETTINGS.speed for c in commands)
    assert end.short == '' and SETTINGS.distance <= end.travelled < SETTINGS.distance + 0.01
    assert pose.x > start.x  # away from the wall it faced (west): east
    assert isinstance(commands[0], Command)


def test_a_robot_that_cannot_back_off_stops_short_and_says_why():
    start = Pose(0, 0, 0)
    _, end, _ = drive(BackOff(start, 0.0, SETTINGS), start, 0.0, blocked_after=0.05)
    assert end.short == 'no progress for 1 s'
    assert end.travelled == pytest.approx(0.05)


def test_a_robot_that_does_not_move_gives_up_at_the_time_limit():
    settings = BackOffSettings(distance=0.2, speed=0.1, stall_time=60.0, margin=1.0)
    back_off = BackOff(Pose(0, 0, 0), 0.0, settings)
    assert isinstance(back_off.update(2.9, Pose(0, 0, 0)), Command)
    end = back_off.update(3.1, Pose(0, 0, 0))
    assert end == BackedOff(0.0, 'time limit 3.0 s')


def scan_of_points(points, beams=360):
    """A 360-degree scan (angle_min -pi) seeing the given (x, y) points of the robot's frame."""
    ranges = [math.inf] * beams
    increment = 2 * math.pi / beams
    for x, y in points:
        index = round((math.atan2(y, x) + math.pi) / increment) % beams
        ranges[index] = min(ranges[index], math.hypot(x, y))
    return ranges, -math.pi, increment


def test_the_nearest_return_of_the_scan_gives_the_bearing_to_face():
    # A wall 0.3 m to the right (y = -0.3) and a jut ahead-left 0.5 m away.
    wall = [(x / 10, -0.3) for x in range(-10, 11)]
    ranges, angle_min, increment = scan_of_points([*wall, (0.35, 0.35)])
    assert nearest_bearing(ranges, angle_min, increment) == pytest.approx(-math.pi / 2, abs=0.02)
    ranges, angle_min, increment = scan_of_points([(0.3, 0.2), (2.0, 0.0)])
    assert nearest_bearing(ranges, angle_min, increment) == pytest.approx(
        math.atan2(0.2, 0.3), abs=0.02)  # fmt: skip
    # Returns below range_min or beyond range_max are none; no returns: no bearing.
    assert nearest_bearing(ranges, angle_min, increment, range_min=0.5, range_max=3.0) == (
        pytest.approx(0.0, abs=0.02)
    )
    assert nearest_bearing([math.inf, math.nan], -0.1, 0.1) is None


def test_a_back_off_turns_to_face_the_nearest_obstacle_then_backs_straight_away_from_it():
    """A robot heading south (-y) met a wall beside it on its right (west, x < 0) at its
    front corner: turning to face it (-pi/4 here, its right front), then backing off, takes it
    away from the wall, east, as straight back (north) would not."""
    start = Pose(0.0, 0.0, -math.pi / 2)
    commands, end, pose = drive(BackOff(start, 0.0, SETTINGS, turn=-math.pi / 4), start)
    turning = [c for c in commands if c.angular != 0.0]
    assert turning and all(c.linear == 0.0 and c.angular < 0 for c in turning)
    assert commands.index(turning[-1]) < next(k for k, c in enumerate(commands) if c.linear)
    assert end.short == '' and end.travelled >= SETTINGS.distance
    assert pose.yaw == pytest.approx(-3 * math.pi / 4, abs=SETTINGS.turn_tolerance)
    assert pose.x > 0.13 and pose.y > 0.13  # away from the obstacle at the front right
    straight = BackOff(start, 0.0, SETTINGS)
    _, _, pose = drive(straight, start)
    assert pose.x == pytest.approx(0.0) and pose.y > 0.19  # Nav2's BackUp: straight back


def test_an_obstacle_near_dead_ahead_needs_no_turn():
    back_off = BackOff(Pose(0, 0, 0), 0.0, SETTINGS, turn=0.05)
    assert back_off.turn == 0.0
    assert back_off.update(0.0, Pose(0, 0, 0)).angular == 0.0
