"""When the environment gives up on a robot it drives over topics (stealth_env.robot_watch):
odometry silence on the robot's clock, a /clock that stops in wall time, and never a silence
counted from before the robot had something to do."""

from stealth_env.robot_watch import ClockWatch, Silence, silence_reason


def reason(sim_time=True, clock_silent=0.0, odom_silent=0.0):
    return silence_reason(
        sim_time=sim_time,
        clock_silent=clock_silent,
        clock_timeout=10.0,
        odom_silent=odom_silent,
        move_timeout=60.0,
    )


def test_a_stopped_clock_is_named_with_how_long_it_has_been_silent():
    assert reason(clock_silent=12.34) == (
        '/clock has not advanced for 12.3 s of wall time (clock_timeout 10 s: is the simulator '
        'running, or paused?)'
    )
    assert reason(clock_silent=9.9) == ''
    # Off simulated time the wall clock is the robot's: /clock is no one's business.
    assert reason(sim_time=False, clock_silent=1000.0) == ''


def test_odometry_silence_is_counted_on_the_robots_clock():
    assert reason(odom_silent=61.0) == (
        'no odom for move_timeout 60 s of simulated time (is the robot running?)'
    )
    assert reason(sim_time=False, odom_silent=61.0) == (
        'no odom for move_timeout 60 s (is the robot running?)'
    )
    assert reason(odom_silent=59.0) == ''
    # A stopped clock is the cause to name when both are silent.
    assert reason(clock_silent=11.0, odom_silent=61.0).startswith('/clock has not advanced')


def test_silence_counts_from_the_latest_sign_of_life():
    silence = Silence()
    silence.heard(5.0)
    assert silence.silent_for(7.5) == 2.5


def test_a_clock_standing_still_while_the_robot_has_nothing_to_do_is_no_silence():
    """A simulator in lockstep holds its clock between moves; silence counts only from when
    the robot was given something to do, and a clock that advances is heard."""
    watch = ClockWatch()
    watch.observe(1_000, wall=0.0, waiting=False)
    watch.observe(1_000, wall=50.0, waiting=False)  # idle: standing still is fine
    watch.observe(1_000, wall=50.1, waiting=True)  # a move: from now on it must advance
    assert abs(watch.silence.silent_for(52.0) - 2.0) < 1e-9
    watch.observe(2_000, wall=53.0, waiting=True)  # it advanced
    assert watch.silence.silent_for(54.0) == 1.0
    watch.observe(2_000, wall=70.0, waiting=True)  # stopped since 53
    assert watch.silence.silent_for(70.0) == 17.0
