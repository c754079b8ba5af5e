"""The simulator's lockstep at real_time_factor 0 (stealth_sim.lockstep): a control period per
answer on cmd_vel, patient with a controller that answered the last period, never stalled by a
subscriber that does not answer, never one period behind a controller that was late once."""

from stealth_sim.lockstep import Lockstep

WAIT = 0.25  # s of wall time: one control period (a binary fraction: exact sums)
PATIENCE = 1.0  # s: the wait for a controller that answered the last period


def sent(now: float = 0.0) -> Lockstep:
    """A lockstep whose latest odometry went out at ``now`` after an answered period."""
    lockstep = Lockstep(WAIT, PATIENCE)
    assert lockstep.command()  # the first command after time stood still goes at once
    lockstep.sent(now)
    return lockstep


def test_the_first_command_after_time_stood_still_lets_a_period_go_by_at_once():
    lockstep = Lockstep(WAIT, PATIENCE)
    assert not lockstep.waited_out(100.0)  # nothing awaited: no period on the wall clock
    assert lockstep.command()


def test_each_answer_lets_one_period_go_by_and_a_second_command_does_not():
    lockstep = sent()
    assert lockstep.command()
    lockstep.sent(0.001)
    assert lockstep.command()
    assert not lockstep.command()  # a second publisher's command for the same odometry
    assert not lockstep.waited_out(10.0)  # answered: nothing overdue


def test_a_controller_slow_to_answer_is_waited_for():
    """On a busy machine an answer may come hundreds of milliseconds late: no period goes by
    under the last command (the robot driven on past where the controller meant to stop)."""
    lockstep = sent(0.0)
    for period in range(1, 4):
        assert not lockstep.waited_out(period * PATIENCE - 0.125)
        assert lockstep.command()
        lockstep.sent(period * PATIENCE)
    assert lockstep.owed == 0


def test_a_silent_subscriber_gets_a_period_per_period_of_wall_time():
    """Once the patience for the last answer is spent."""
    lockstep = sent(0.0)
    assert not lockstep.waited_out(WAIT)
    assert lockstep.waited_out(PATIENCE)
    assert not lockstep.waited_out(PATIENCE + WAIT / 2)  # this wait is over: once per odometry
    for period in range(1, 5):
        now = PATIENCE + (period - 1) * WAIT
        lockstep.sent(now)
        assert not lockstep.waited_out(now + WAIT / 2)
        assert lockstep.waited_out(now + WAIT)


def test_a_controller_late_once_gets_its_late_answer_taken_as_late():
    """Its answer to the period that went by without it does not count for the next one, so
    the controller decides on the latest odometry again."""
    lockstep = sent(0.0)
    assert lockstep.waited_out(PATIENCE)  # it fell behind
    lockstep.sent(PATIENCE)
    assert not lockstep.command()  # the late answer to the first odometry
    assert lockstep.command()  # the answer to the latest: on
    lockstep.sent(PATIENCE + 0.0625)
    assert lockstep.command()  # in step again


def test_a_controller_silent_between_its_moves_owes_at_most_one_answer():
    """Silent for several periods (between moves): at most its first command is taken as a
    late one, after which the next wait lets a period go by and it owes nothing more."""
    lockstep = sent(0.0)
    now = PATIENCE
    for _ in range(5):
        assert lockstep.waited_out(now)
        lockstep.sent(now)
        now += WAIT
    assert lockstep.owed == 1
    assert not lockstep.command()  # taken as the late one
    assert lockstep.waited_out(now)
    lockstep.sent(now)
    assert lockstep.owed == 0
    assert lockstep.command()


def test_a_restart_forgets_what_was_owed():
    lockstep = sent(0.0)
    assert lockstep.waited_out(PATIENCE)
    lockstep.restart()  # time stood still, or a move or reset placed the robot
    assert lockstep.command()
