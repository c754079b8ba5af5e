"""The simulator's lockstep at real_time_factor 0 (stealth_sim.lockstep): a control period per
answer on cmd_vel, never stalled by a subscriber that does not answer, never one period behind
a controller that was late once."""

from stealth_sim.lockstep import Lockstep

WAIT = 0.25  # s of wall time: one control period (a binary fraction: exact sums)


def sent(now: float = 0.0) -> Lockstep:
    """A lockstep whose latest odometry went out at ``now`` after an answered period."""
    lockstep = Lockstep(WAIT)
    assert lockstep.command()  # the first command after time stood still goes at once
    lockstep.sent(now)
    return lockstep


def test_the_first_command_after_time_stood_still_lets_a_period_go_by_at_once():
    lockstep = Lockstep(WAIT)
    assert not lockstep.waited_out(100.0)  # nothing awaited: no period on the wall clock
    assert lockstep.command()


def test_each_answer_lets_one_period_go_by_and_a_second_command_does_not():
    lockstep = sent()
    assert lockstep.command()
    lockstep.sent(0.001)
    assert lockstep.command()
    assert not lockstep.command()  # a second publisher's command for the same odometry
    assert not lockstep.waited_out(10.0)  # answered: nothing overdue


def test_a_silent_subscriber_gets_a_period_per_period_of_wall_time():
    lockstep = sent(0.0)
    assert not lockstep.waited_out(WAIT / 2)
    assert lockstep.waited_out(WAIT)
    assert not lockstep.waited_out(WAIT * 1.5)  # this wait is over: once per odometry
    for period in range(1, 5):
        lockstep.sent(period * WAIT)
        assert not lockstep.waited_out(period * WAIT + WAIT / 2)
        assert lockstep.waited_out((period + 1) * WAIT)


def test_a_controller_late_once_gets_its_late_answer_taken_as_late():
    """Its answer to the period that went by without it does not count for the next one, so
    the controller decides on the latest odometry again."""
    lockstep = sent(0.0)
    assert lockstep.waited_out(WAIT)  # it fell behind
    lockstep.sent(WAIT)
    assert not lockstep.command()  # the late answer to the first odometry
    assert lockstep.command()  # the answer to the latest: on
    lockstep.sent(WAIT + 0.01)
    assert lockstep.command()  # in step again


def test_a_controller_silent_between_its_moves_owes_at_most_one_answer():
    """Silent for several periods (between moves): at most its first command is taken as a
    late one, after which the next wait lets a period go by and it owes nothing more."""
    lockstep = sent(0.0)
    for period in range(1, 6):
        assert lockstep.waited_out(period * WAIT)
        lockstep.sent(period * WAIT)
    assert lockstep.owed == 1
    assert not lockstep.command()  # taken as the late one
    assert lockstep.waited_out(6 * WAIT)
    lockstep.sent(6 * WAIT)
    assert lockstep.owed == 0
    assert lockstep.command()


def test_a_restart_forgets_what_was_owed():
    lockstep = sent(0.0)
    assert lockstep.waited_out(WAIT)
    lockstep.restart()  # time stood still, or a move or reset placed the robot
    assert lockstep.command()
