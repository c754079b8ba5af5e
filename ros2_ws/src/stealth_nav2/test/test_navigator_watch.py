"""The navigator's watch on odom and amcl_pose going silent."""

from stealth_core.kinematics import Pose
from stealth_nav2.sensor_watch import SensorWatch


def test_odom_silence_is_noticed_after_the_timeout():
    watch = SensorWatch(timeout=2.0, travel=1.0)
    watch.restart(100.0)
    assert watch.silent(101.0) == ''
    assert watch.silent(102.5) == 'no odom for 2 s (is the robot running?)'
    watch.odom(102.6, Pose(0, 0, 0))
    watch.estimate(102.6)
    assert watch.silent(104.0) == ''
    assert watch.silent(104.7, '/robot/odom') == 'no /robot/odom for 2 s (is the robot running?)'


def test_amcl_pose_silence_counts_only_once_the_robot_drove_on():
    watch = SensorWatch(timeout=2.0, travel=1.0)
    watch.restart(0.0)
    watch.odom(0.0, Pose(0, 0, 0))
    watch.estimate(0.0)
    for t in range(1, 30):  # holding still for a moving light: no amcl_pose, not silent
        watch.odom(float(t), Pose(0, 0, 0))
        assert watch.silent(float(t)) == ''
    for step in range(1, 4):  # drives 1.5 m with no amcl_pose
        watch.odom(29.0 + step, Pose(0.5 * step, 0, 0))
    assert watch.silent(32.0) == (
        'no amcl_pose for 32.0 s while the robot drove 1.5 m on odom (is the localisation '
        'running?)'
    )
    watch.estimate(32.0)
    assert watch.silent(32.1) == ''


def test_no_amcl_pose_at_all_is_noticed_after_the_timeout():
    watch = SensorWatch(timeout=2.0, travel=1.0)
    watch.restart(10.0)
    watch.odom(12.5, Pose(0, 0, 0))
    assert watch.silent(12.5) == 'no amcl_pose for 2 s (is the localisation running?)'


def test_going_back_and_forth_by_a_wall_is_not_travel_for_the_localisation():
    """AMCL updates on displacement (update_min_d): backing off 0.2 m and meeting the wall again,
    over and over, moves it nowhere, so its silence then is no failure; once the robot is a
    metre from where the last amcl_pose found it, it is."""
    watch = SensorWatch(timeout=2.0, travel=1.0)
    watch.restart(0.0)
    watch.odom(0.0, Pose(5.0, 0, 0))
    watch.estimate(0.0)
    t = 0.0
    for _ in range(10):  # 4 m driven, never more than 0.2 m from where it was
        for x in (4.8, 5.0):
            t += 0.5
            watch.odom(t, Pose(x, 0, 0))
    assert watch.silent(t) == ''
    watch.odom(t + 0.5, Pose(6.2, 0, 0))
    assert watch.silent(t + 0.5) == (
        f'no amcl_pose for {t + 0.5:.1f} s while the robot drove 1.2 m on odom (is the '
        'localisation running?)'
    )
