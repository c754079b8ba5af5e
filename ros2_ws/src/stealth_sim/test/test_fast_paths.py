"""A move's fast path against the reference it replaces: same seed, same results.

The fast path (``fast_move``) repeats the reference's floating-point operations in the same order
and draws the same random numbers in the same order, so whole walks must agree exactly: every
outcome, pose, odometry, estimate, covariance, step count and everything a step hook sees.
"""

import dataclasses

import pytest
from sim_test_maps import maze_map
from stealth_sim.kinematics import Limits, Pose
from stealth_sim.localisation import FilterConfig
from stealth_sim.move_executor import ControllerConfig, Move, MoveKind, Outcome, execute_move
from stealth_sim.odometry_noise import MotionNoise
from stealth_sim.simulator import SimConfig, Simulator

START = Pose(3.0, 2.0, 0.0)
TRAINING = SimConfig(physics_dt=0.04, filter=FilterConfig(particles=200))
MOVES = [
    Move(MoveKind.UP, 0.5),
    Move(MoveKind.LEFT, 0.5),
    Move(MoveKind.TURN_TO_HEADING, heading=-2.5),
    Move(MoveKind.DRIVE_DISTANCE, 1.0),
    Move(MoveKind.RIGHT, 0.5),
    Move(MoveKind.DOWN, 3.0),  # into the bottom wall: BUMPED
    Move(MoveKind.DOWN, 0.5),  # pushing against it again
    Move(MoveKind.UP, 0.7),
    Move(MoveKind.UP, float('nan')),  # rejected
    Move(MoveKind.GO_TO, x=3.5, y=1.0),  # turn to face it, drive there
    Move(MoveKind.GO_TO, x=3.5, y=1.005),  # there already: DONE at once
    Move(MoveKind.GO_TO, x=3.5, y=-2.0),  # through the bottom wall: BUMPED
    Move(MoveKind.GO_TO, x=float('inf'), y=1.0),  # rejected
    Move(MoveKind.GO_TO, x=2.0, y=1.5),
]


def walk(config, reference, moves=MOVES, seen=None, controller=None):
    """Everything observable after each move of a seeded walk."""
    sim = Simulator(maze_map(), config, START, reference=reference)
    on_step = None if seen is None else (lambda s: seen.append((s.time, s.state, s.estimate)))
    record = []
    for move in moves:
        result = execute_move(sim, move, on_step, controller or ControllerConfig())
        record.append(
            (
                result,
                sim.state,
                sim.odometry_pose,
                sim.estimate,
                sim.estimate_covariance.tolist(),
                (sim.time, sim.steps, sim.bumps, sim.localisation_updates),
            )
        )
    return record


@pytest.mark.parametrize(
    'config',
    [
        TRAINING,
        SimConfig(),
        dataclasses.replace(TRAINING, seed=11, odometry_noise=MotionNoise(0.2, 0.05, 0.1, 0.05)),
        dataclasses.replace(TRAINING, odometry_noise=MotionNoise(0.0, 0.0, 0.0, 0.0)),
        SimConfig(physics_dt=0.1, limits=Limits(5.0, 10.0, 20.0, 50.0), seed=3),
    ],
    ids=['training', 'defaults', 'noisy', 'noise-free', 'coarse-fast'],
)
def test_fast_moves_equal_the_reference_exactly(config):
    fast, reference = walk(config, False), walk(config, True)
    outcomes = [entry[0].outcome for entry in reference]
    assert Outcome.BUMPED in outcomes and Outcome.REJECTED in outcomes
    assert fast == reference


def test_fast_moves_time_out_as_the_reference_does():
    hurried = ControllerConfig(time_limit_factor=0.0, time_limit_margin=0.5)
    moves = [Move(MoveKind.UP, 2.0), Move(MoveKind.RIGHT, 0.5)]
    fast = walk(TRAINING, False, moves, controller=hurried)
    reference = walk(TRAINING, True, moves, controller=hurried)
    assert reference[0][0].outcome == Outcome.TIMED_OUT
    assert fast == reference


def test_the_step_hook_sees_the_same_states_on_both_paths():
    fast_seen, reference_seen = [], []
    moves = MOVES[:3]
    walk(TRAINING, False, moves, fast_seen)
    walk(TRAINING, True, moves, reference_seen)
    assert len(fast_seen) > 100 and fast_seen == reference_seen


def test_a_due_step_hook_is_called_only_when_due_with_the_same_state():
    def run(reference):
        sim = Simulator(maze_map(), TRAINING, START, reference=reference)
        seen = []
        every_half_second = lambda time, updates: round(time / 0.04) % 12 == 0  # noqa: E731
        result = execute_move(
            sim,
            Move(MoveKind.UP, 0.5),
            on_step=lambda s: seen.append((s.time, s.state, s.odometry_pose, s.estimate)),
            on_step_due=every_half_second,
        )
        return result, seen

    (fast_result, fast_seen), (reference_result, reference_seen) = run(False), run(True)
    assert fast_result == reference_result and fast_seen == reference_seen
    assert 0 < len(fast_seen) <= fast_result.steps // 12 + 1
