"""The back-off recovery's core: a blocked robot backs off (and only a blocked one), straight
backwards on odometry, until it has gone the distance, stalls or runs out of time."""

import math

import pytest
from stealth_env.topic_moves import Command, MoveOutcome, Pose
from stealth_nav2.back_off import BackedOff, BackOff, BackOffSettings, backs_off
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


def drive(back_off: BackOff, start: Pose, t: float, blocked_after: float = math.inf):
    """Integrate the commands on a robot facing start.yaw (it cannot go more than
    ``blocked_after`` metres back); the commands and the end."""
    pose, commands = start, []
    for _ in range(1000):
        step = back_off.update(t, pose)
        if isinstance(step, BackedOff):
            return commands, step, pose
        commands.append(step)
        back = min(back_off.travelled(pose) - step.linear * PERIOD, blocked_after)
        pose = Pose(start.x - back * math.cos(start.yaw), start.y - back * math.sin(start.yaw),
                    start.yaw)  # fmt: skip
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
