"""The fast paths against the references they replace: same seed, same results.

A move's fast path (``fast_move``) repeats the reference's floating-point operations in the same
order and draws the same random numbers in the same order, so whole walks must agree exactly:
every outcome, pose, odometry, estimate, covariance and step count. The filter's fast lookup
computes the endpoints by another route (a matrix product instead of complex products), so its
sums are compared within 1e-9; the walks then agree exactly as long as no endpoint lands within
rounding error of a cell edge, which the walks here show does not happen in practice.
"""

import dataclasses
import math

import numpy as np
import pytest
from sim_test_maps import maze_map
from stealth_sim import localisation
from stealth_sim.kinematics import Limits, Pose
from stealth_sim.laser import LaserConfig
from stealth_sim.localisation import (
    FilterConfig,
    LikelihoodField,
    LikelihoodModel,
    reference_score_sums,
)
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


def likelihood_field(range_max=8.0):
    return LikelihoodField(maze_map(), LikelihoodModel(), range_max)


def scans_and_particles(seed: int, count: int, spread: float):
    rng = np.random.default_rng(seed)
    bearings = LaserConfig().bearings(np.arange(0, 180, 3))
    ranges = rng.uniform(0.05, 7.99, bearings.size)
    poses = np.column_stack(
        [
            rng.normal(5.0, spread, count),
            rng.normal(4.0, spread, count),
            rng.uniform(-math.pi, math.pi, count),
        ]
    )
    return poses, ranges, bearings


@pytest.mark.parametrize('seed', range(5))
def test_fast_likelihood_sums_equal_the_reference(seed):
    field = likelihood_field()
    poses, ranges, bearings = scans_and_particles(seed, 500, 3.0)
    fast = field.score_sums(poses, ranges, bearings)
    assert fast == pytest.approx(reference_score_sums(field, poses, ranges, bearings), abs=1e-9)


def test_particles_far_off_the_map_are_weighed_on_the_reference_path():
    field = likelihood_field()
    poses, ranges, bearings = scans_and_particles(0, 200, 1.0)
    poses[7, 0] = -40.0  # beyond the padding
    fast = field.score_sums(poses, ranges, bearings)
    assert fast == pytest.approx(reference_score_sums(field, poses, ranges, bearings), abs=1e-9)


def test_a_table_too_large_falls_back_to_the_reference_and_says_why(monkeypatch):
    monkeypatch.setattr(localisation, 'MAX_PADDED_CELLS', 1000)
    config = dataclasses.replace(TRAINING, laser=LaserConfig(range_max=30.0))
    sim = Simulator(maze_map(), config, START)
    assert len(sim.fallback_reasons) == 1 and 'laser_range 30 m' in sim.fallback_reasons[0]
    moves = MOVES[:2]
    fast, reference = walk(config, False, moves), walk(config, True, moves)
    assert fast == reference
