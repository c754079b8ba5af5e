"""RL moves through the Simulator: outcomes, closed-loop accuracy, bad input left untouched."""

import dataclasses
import math

import numpy as np
import pytest
from sim_test_maps import angle_error, maze_map
from stealth_core.kinematics import Limits, Pose
from stealth_core.moves import ControllerConfig, MoveKind, MoveOutcome, MoveRequest
from stealth_sim.move_executor import execute_move
from stealth_sim.odometry_noise import MotionNoise
from stealth_sim.simulator import SimConfig, Simulator

START = Pose(3.0, 2.0, 0.0)  # in the maze map's south-west room, 2 m from every wall


def make_sim(seed: int = 0, **changes) -> Simulator:
    return Simulator(maze_map(), dataclasses.replace(SimConfig(seed=seed), **changes), START)


def snapshot(sim: Simulator):
    """Everything a rejected request must leave as it was."""
    return (
        sim.time,
        sim.state,
        sim.odometry_pose,
        sim.estimate,
        sim.estimate_covariance.copy().tolist(),
        sim.localisation_updates,
    )


@pytest.mark.parametrize(
    ('kind', 'direction'),
    [
        (MoveKind.UP, (0, 1)),
        (MoveKind.DOWN, (0, -1)),
        (MoveKind.LEFT, (-1, 0)),
        (MoveKind.RIGHT, (1, 0)),
    ],
)
def test_grid_moves_go_their_step_along_the_map_axes_and_end_at_rest(kind, direction):
    sim = make_sim()
    result = execute_move(sim, MoveRequest(kind, 0.5))
    assert result.outcome == MoveOutcome.DONE and result.message == ''
    truth = sim.ground_truth
    assert truth.x - START.x == pytest.approx(0.5 * direction[0], abs=0.1)
    assert truth.y - START.y == pytest.approx(0.5 * direction[1], abs=0.1)
    assert angle_error(truth.yaw, math.atan2(direction[1], direction[0])) < 0.1
    assert (sim.state.linear, sim.state.angular) == (0.0, 0.0)
    assert result.duration == pytest.approx(sim.time) and result.steps == sim.steps


def test_turn_to_heading_turns_in_place_to_the_estimated_heading():
    sim = make_sim()
    result = execute_move(sim, MoveRequest(MoveKind.TURN_TO_HEADING, heading=-2.5))
    assert result.outcome == MoveOutcome.DONE
    assert angle_error(sim.estimate.yaw, -2.5) < 0.05
    assert math.hypot(sim.ground_truth.x - START.x, sim.ground_truth.y - START.y) < 1e-9


def test_drive_distance_follows_the_current_heading():
    sim = make_sim()
    execute_move(sim, MoveRequest(MoveKind.TURN_TO_HEADING, heading=math.pi / 4))
    before = sim.ground_truth
    result = execute_move(sim, MoveRequest(MoveKind.DRIVE_DISTANCE, 1.0))
    after = sim.ground_truth
    assert result.outcome == MoveOutcome.DONE
    assert math.hypot(after.x - before.x, after.y - before.y) == pytest.approx(1.0, abs=0.1)
    assert angle_error(math.atan2(after.y - before.y, after.x - before.x), math.pi / 4) < 0.1


def test_driving_into_a_wall_bumps_and_stops_at_the_wall():
    sim = make_sim()
    result = execute_move(sim, MoveRequest(MoveKind.LEFT, 5.0))  # the west wall is 2.95 m away
    assert result.outcome == MoveOutcome.BUMPED and 'wall' in result.message
    truth = sim.ground_truth
    radius = sim.config.robot_radius
    assert truth.x == pytest.approx(0.05 + radius, abs=0.01)
    assert sim.footprint.fits(truth.x, truth.y)
    assert not sim.footprint.fits(truth.x - 0.001, truth.y)
    assert (sim.state.linear, sim.state.angular) == (0.0, 0.0)


def test_go_to_reaches_the_point_from_wherever_the_robot_is():
    """GO_TO aims at a fixed point: an offset start (here 0.2 m beside and behind the line a
    grid move would take) is corrected, not carried along as a grid move carries it."""
    sim = make_sim()
    execute_move(sim, MoveRequest(MoveKind.GO_TO, x=3.2, y=1.8))
    target = (3.2, 2.3)
    result = execute_move(sim, MoveRequest(MoveKind.GO_TO, x=target[0], y=target[1]))
    assert result.outcome == MoveOutcome.DONE
    estimate, truth = sim.estimate, sim.ground_truth
    position_tolerance = ControllerConfig().position_tolerance
    assert math.dist((estimate.x, estimate.y), target) <= position_tolerance + 0.01
    assert math.dist((truth.x, truth.y), target) < 0.1  # the estimate's error on top
    assert angle_error(truth.yaw, math.pi / 2) < 0.15  # it drove roughly along +y
    assert (sim.state.linear, sim.state.angular) == (0.0, 0.0)


def test_go_to_where_the_robot_already_is_does_nothing():
    sim = make_sim()
    estimate = sim.estimate
    result = execute_move(sim, MoveRequest(MoveKind.GO_TO, x=estimate.x + 0.005, y=estimate.y))
    assert result.outcome == MoveOutcome.DONE
    assert sim.ground_truth == START and result.duration == pytest.approx(sim.time)
    assert result.steps <= 1


def test_go_to_a_point_behind_a_wall_bumps_at_the_wall():
    sim = make_sim()
    result = execute_move(sim, MoveRequest(MoveKind.GO_TO, x=-2.0, y=2.0))  # beyond the west wall
    assert result.outcome == MoveOutcome.BUMPED
    assert sim.ground_truth.x == pytest.approx(0.05 + sim.config.robot_radius, abs=0.01)


def test_a_move_that_runs_out_of_time_reports_it_and_still_ends_at_rest():
    sim = make_sim()
    controller = ControllerConfig(time_limit_factor=0.0, time_limit_margin=0.5)
    result = execute_move(sim, MoveRequest(MoveKind.UP, 2.0), controller=controller)
    assert result.outcome == MoveOutcome.TIMED_OUT and '0.5 s' in result.message
    assert (sim.state.linear, sim.state.angular) == (0.0, 0.0)


def test_a_hold_lets_time_pass_with_the_robot_where_it_stopped():
    sim = make_sim()
    execute_move(sim, MoveRequest(MoveKind.UP, 0.5))
    before = snapshot(sim)
    result = execute_move(sim, MoveRequest(MoveKind.HOLD, seconds=3.0))
    steps = round(3.0 / sim.config.physics_dt)
    assert (result.outcome, result.message, result.steps) == (MoveOutcome.DONE, '', steps)
    assert result.duration == pytest.approx(3.0) and sim.time == pytest.approx(before[0] + 3.0)
    assert (sim.state.linear, sim.state.angular) == (0.0, 0.0)
    # The move left it within 1 mm/s of rest: braking that takes it nowhere measurable.
    assert math.dist(sim.ground_truth[:2], before[1].pose[:2]) < 1e-4
    assert snapshot(sim)[4:] == before[4:]  # no filter update: it did not move


def test_standing_still_refuses_a_moving_robot():
    sim = make_sim()
    sim.step(0.5, 0.0)
    with pytest.raises(ValueError, match='moving'):
        sim.stand_still(10)


@pytest.mark.parametrize(
    ('move', 'fragment'),
    [
        (MoveRequest(MoveKind.UP, math.nan), 'distance'),
        (MoveRequest(MoveKind.DRIVE_DISTANCE, math.inf), 'distance'),
        (MoveRequest(MoveKind.DOWN, -0.5), 'distance'),
        (MoveRequest(MoveKind.RIGHT, 0.0), 'distance'),
        (MoveRequest(MoveKind.LEFT, 1e6), 'diagonal'),
        (MoveRequest(MoveKind.TURN_TO_HEADING, heading=math.nan), 'heading'),
        (MoveRequest(MoveKind.GO_TO, x=math.nan, y=2.0), 'finite point'),
        (MoveRequest(MoveKind.GO_TO, x=3.0, y=math.inf), 'finite point'),
        (MoveRequest(MoveKind.GO_TO, x=3.0, y=1e6), 'diagonal'),
        (MoveRequest(MoveKind.HOLD, seconds=0.0), 'seconds'),
        (MoveRequest(MoveKind.HOLD, seconds=-1.0), 'seconds'),
        (MoveRequest(MoveKind.HOLD, seconds=math.nan), 'seconds'),
        (MoveRequest(MoveKind.HOLD, seconds=601.0), 'at most 600'),
        (MoveRequest(17, 0.5), 'kind'),
    ],
)
def test_bad_moves_are_rejected_with_a_reason_and_touch_nothing(move, fragment):
    sim = make_sim()
    execute_move(sim, MoveRequest(MoveKind.UP, 0.5))
    before = snapshot(sim)
    result = execute_move(sim, move)
    assert result.outcome == MoveOutcome.REJECTED and fragment in result.message
    assert snapshot(sim) == before and result.duration == 0.0


@pytest.mark.parametrize(
    ('pose', 'covariance', 'fragment'),
    [
        (Pose(-1.0, 2.0, 0.0), None, 'outside the map'),
        (Pose(3.0, 4.0, 0.0), None, 'inside a wall'),  # the wall across y = 4.0
        (Pose(0.1, 2.0, 0.0), None, 'inside a wall'),  # the disc overlaps the west wall
        (Pose(3.0, 2.0, math.nan), None, 'yaw'),
        (Pose(3.0, 2.0, 0.0), np.diag([0.1, -0.1, 0.1]), 'covariance'),
    ],
)
def test_bad_resets_are_rejected_with_a_reason_and_touch_nothing(pose, covariance, fragment):
    sim = make_sim()
    execute_move(sim, MoveRequest(MoveKind.UP, 0.5))
    before = snapshot(sim)
    with pytest.raises(ValueError, match=fragment):
        sim.reset(pose, covariance)
    assert snapshot(sim) == before


@pytest.mark.parametrize('command', [(math.nan, 0.0), (0.0, math.inf), (-math.inf, 1.0)])
def test_non_finite_velocity_commands_are_rejected_and_touch_nothing(command):
    sim = make_sim()
    before = snapshot(sim)
    with pytest.raises(ValueError, match='finite'):
        sim.step(*command)
    assert snapshot(sim) == before


def test_reset_teleports_stops_and_restarts_odometry_and_localisation():
    sim = make_sim()
    execute_move(sim, MoveRequest(MoveKind.UP, 1.0))
    target = Pose(8.5, 6.0, 1.0)
    sim.reset(target, np.diag([0.04, 0.04, 0.01]))
    assert sim.ground_truth == target and sim.odometry_pose == target
    assert (sim.state.linear, sim.state.angular) == (0.0, 0.0)
    assert math.hypot(sim.estimate.x - 8.5, sim.estimate.y - 6.0) < 0.05
    assert sim.estimate_covariance[0, 0] == pytest.approx(0.04, rel=0.3)


def test_an_initial_estimate_moves_the_belief_not_the_robot():
    sim = make_sim()
    truth = sim.ground_truth
    sim.set_initial_estimate(Pose(3.3, 2.2, 0.1), np.diag([0.05, 0.05, 0.02]))
    assert sim.ground_truth == truth
    assert math.hypot(sim.estimate.x - 3.3, sim.estimate.y - 2.2) < 0.05
    for _ in range(4):  # the scans pull the belief back to the truth
        execute_move(sim, MoveRequest(MoveKind.RIGHT, 0.5))
        execute_move(sim, MoveRequest(MoveKind.LEFT, 0.5))
    error = math.hypot(sim.estimate.x - sim.ground_truth.x, sim.estimate.y - sim.ground_truth.y)
    assert error < 0.1


def test_a_seed_fixes_every_move_and_published_scans_do_not_disturb_it():
    def run(seed: int, publish_scans: bool):
        sim = make_sim(seed=seed)

        def publish(s: Simulator):
            if publish_scans and s.steps % 10 == 0:
                s.scan()

        moves = [MoveRequest(k, 0.5) for k in (MoveKind.UP, MoveKind.RIGHT, MoveKind.DOWN)]
        return [(execute_move(sim, m, publish), sim.estimate, sim.ground_truth) for m in moves]

    assert run(42, False) == run(42, True)
    assert run(42, False) != run(43, False)


def test_the_step_hook_sees_every_physics_step():
    sim = make_sim()
    seen = []
    result = execute_move(
        sim, MoveRequest(MoveKind.RIGHT, 0.5), on_step=lambda s: seen.append(s.time)
    )
    assert len(seen) == result.steps and seen[-1] == sim.time
    assert np.allclose(np.diff(seen), sim.config.physics_dt)


def test_runtime_reconfiguration_takes_limits_and_noise_but_not_the_layout():
    sim = make_sim()
    faster = dataclasses.replace(
        sim.config, limits=dataclasses.replace(sim.config.limits, max_linear_speed=1.0)
    )
    sim.reconfigure(faster)
    assert sim.config.limits.max_linear_speed == 1.0
    with pytest.raises(ValueError, match='robot_radius'):
        sim.reconfigure(dataclasses.replace(faster, robot_radius=0.3))


def test_without_noise_the_odometry_is_the_ground_truth_after_any_moves():
    sim = make_sim(odometry_noise=MotionNoise(0.0, 0.0, 0.0, 0.0))
    for kind in (MoveKind.UP, MoveKind.RIGHT, MoveKind.TURN_TO_HEADING, MoveKind.DOWN):
        execute_move(sim, MoveRequest(kind, 0.5, heading=2.0))
        assert sim.odometry_pose == pytest.approx(sim.ground_truth, abs=1e-9)


def test_a_coarse_physics_step_finishes_moves_in_few_steps_without_overshooting():
    # A fast robot at 0.1 s steps: the braking curve of the step covers the last stretch in
    # one step instead of a proportional tail, and never asks for more than it can brake.
    sim = make_sim(
        physics_dt=0.1,
        limits=Limits(5.0, 10.0, 20.0, 50.0),
        odometry_noise=MotionNoise(0.0, 0.0, 0.0, 0.0),
    )
    for kind, target in ((MoveKind.RIGHT, (3.5, 2.0)), (MoveKind.UP, (3.5, 2.5))):
        result = execute_move(sim, MoveRequest(kind, 0.5))
        assert result.outcome == MoveOutcome.DONE and result.steps <= 12
        truth = sim.ground_truth
        assert math.hypot(truth.x - target[0], truth.y - target[1]) < 0.02
        assert (sim.state.linear, sim.state.angular) == (0.0, 0.0)
