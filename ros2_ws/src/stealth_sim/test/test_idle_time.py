"""The simulator node's time between moves (stealth_sim.idle_time): never on wall time alone in
training, so a seeded run of moves is the same whatever the load."""

import pytest
from sim_test_maps import maze_map
from stealth_core.kinematics import Pose
from stealth_core.moves import ControllerConfig, MoveKind, MoveRequest
from stealth_sim.idle_time import MAX_CATCH_UP, IdleTick, idle_tick
from stealth_sim.move_executor import execute_move
from stealth_sim.simulator import SimConfig, Simulator

PERIOD = 0.02  # s: the node's idle_period


def tick(sim_time=10.0, due=10.1, *, factor=0.0, commanded=False, moving=False, held=False):
    return idle_tick(
        sim_time,
        due,
        real_time_factor=factor,
        commanded=commanded,
        moving=moving,
        held=held,
        idle_period=PERIOD,
    )


def test_a_move_can_end_within_the_stopped_speed_but_not_at_zero():
    """Why the node holds the robot a move left: its braking ends below stopped_speed, not
    always at exactly zero (here 0.2 mm/s), and an idle step would take that up."""
    sim = Simulator(maze_map(), SimConfig(), Pose(3.0, 2.0, 0.0))
    execute_move(sim, MoveRequest(MoveKind.GO_TO, x=3.5, y=2.0))
    assert 0.0 < abs(sim.state.linear) <= ControllerConfig().stopped_speed


@pytest.mark.parametrize('moving', [False, True])
@pytest.mark.parametrize('due', [10.0, 10.1, 10.0 + MAX_CATCH_UP + 5.0])
def test_in_training_time_stands_still_between_moves_however_late_the_next_move(moving, due):
    """A robot a move or reset left in place (held), at rest or with a residual speed: no step,
    however much wall time passed (due), and the pacer is re-anchored."""
    assert tick(due=due, moving=moving, held=True) == IdleTick(10.0, True)
    if not moving:  # at rest and never driven: the same
        assert tick(due=due) == IdleTick(10.0, True)


@pytest.mark.parametrize('due', [10.0, 10.1, 10.0 + MAX_CATCH_UP + 5.0])
def test_under_cmd_vel_at_factor_0_time_flows_in_lockstep_whatever_the_wall_clock(due):
    """No step on the tick's own: the lockstep lets periods go by (stealth_sim.lockstep)."""
    lockstep = IdleTick(10.0, True, lockstep=True)
    assert tick(due=due, commanded=True) == lockstep
    assert tick(due=due, commanded=True, held=True) == lockstep
    # The command expired while the robot still coasts (not held: a cmd_vel drove it): it brakes.
    assert tick(due=due, moving=True) == lockstep


def test_with_a_real_time_factor_time_follows_the_wall_clock():
    assert tick(due=10.2, factor=20.0, held=True) == IdleTick(10.2, False)
    assert tick(due=10.2, factor=1.0) == IdleTick(10.2, False)


def test_a_tick_that_fell_behind_does_not_race_to_catch_up():
    late = 10.0 + MAX_CATCH_UP + 1.0
    assert tick(due=late, factor=1.0, commanded=True) == IdleTick(10.0 + PERIOD, True)
    assert tick(due=late, factor=20.0) == IdleTick(10.0 + PERIOD * 20.0, True)
