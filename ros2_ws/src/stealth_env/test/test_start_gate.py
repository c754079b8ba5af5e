"""The environment's start decision (start_gate): no ROS."""

from stealth_env.start_gate import WAITING_LOG_PERIOD, StartGate

ALL_THERE = {'the robot': True, 'an agent': True}


def test_an_episode_starts_once_everything_was_there_for_the_start_delay():
    gate = StartGate(now=0.0)
    assert gate.check(1.0, ALL_THERE, start_delay=0.5) == (False, None)
    assert gate.check(1.4, ALL_THERE, start_delay=0.5) == (False, None)
    assert gate.check(1.5, ALL_THERE, start_delay=0.5) == (True, None)


def test_something_missing_starts_the_wait_again():
    gate = StartGate(now=0.0)
    gate.check(1.0, ALL_THERE, start_delay=0.5)
    assert gate.check(1.2, {'the robot': True, 'an agent': False}, start_delay=0.5)[0] is False
    assert gate.check(1.5, ALL_THERE, start_delay=0.5) == (False, None)  # the wait began at 1.5
    assert gate.check(2.0, ALL_THERE, start_delay=0.5) == (True, None)


def test_a_failed_reset_holds_the_start_until_its_retry_time():
    gate = StartGate(now=0.0)
    gate.retry_at(5.0)
    assert gate.check(1.0, ALL_THERE, start_delay=0.0) == (False, None)
    assert gate.check(4.9, ALL_THERE, start_delay=0.0) == (False, None)
    assert gate.check(5.0, ALL_THERE, start_delay=0.0) == (True, None)


def test_what_is_missing_is_said_once_a_period():
    gate = StartGate(now=0.0)
    needs = {'the robot: sim/execute_move': False, 'an agent': False, 'the readers': True}
    assert gate.check(1.0, needs, start_delay=0.0) == (False, None)  # not yet a period
    line = gate.check(WAITING_LOG_PERIOD, needs, start_delay=0.0)[1]
    assert line == 'still waiting for the robot: sim/execute_move and an agent'
    assert gate.check(WAITING_LOG_PERIOD + 1, needs, start_delay=0.0) == (False, None)
    assert gate.check(2 * WAITING_LOG_PERIOD, needs, start_delay=0.0)[1] == line
