"""A move's compiled fast path against the reference it replaces: same seed, same results.

The compiled path (``compiled_move``) repeats the reference's floating-point operations and
draws the same random numbers from the same generators in the same order (numba's Generator
methods are NumPy's, bit for bit: tested below). The filter's particles and weights come out
the same; the estimate's weighted sums run in another order than NumPy's BLAS, a last-bit
difference that the closed loop carries along. So whole walks must agree in every discrete
result (outcome, steps, bumps, filter updates, rejection messages) exactly and in every pose,
odometry, estimate and covariance within 1e-9, step hooks included.
"""

import copy
import dataclasses
import logging
import math

import numpy as np
import pytest
from sim_test_maps import maze_map
from stealth_core.jit import jit
from stealth_core.kinematics import Limits, Pose
from stealth_core.moves import ControllerConfig, MoveKind, MoveOutcome, MoveRequest
from stealth_sim import compiled_move, move_executor
from stealth_sim.kernels import move_loop, numeric
from stealth_sim.laser import noisy_ranges
from stealth_sim.localisation import FilterConfig
from stealth_sim.move_executor import StepStops, execute_move
from stealth_sim.odometry_noise import MotionNoise
from stealth_sim.simulator import SimConfig, Simulator

TOLERANCE = 1e-9
START = Pose(3.0, 2.0, 0.0)
TRAINING = SimConfig(physics_dt=0.04, filter=FilterConfig(particles=200))
MOVES = [
    MoveRequest(MoveKind.UP, 0.5),
    MoveRequest(MoveKind.HOLD, seconds=3.0),  # from a move's residual speed: brake, then stand
    MoveRequest(MoveKind.LEFT, 0.5),
    MoveRequest(MoveKind.TURN_TO_HEADING, heading=-2.5),
    MoveRequest(MoveKind.DRIVE_DISTANCE, 1.0),
    MoveRequest(MoveKind.RIGHT, 0.5),
    MoveRequest(MoveKind.DOWN, 3.0),  # into the bottom wall: BUMPED
    MoveRequest(MoveKind.DOWN, 0.5),  # pushing against it again
    MoveRequest(MoveKind.UP, 0.7),
    MoveRequest(MoveKind.UP, float('nan')),  # rejected
    MoveRequest(MoveKind.GO_TO, x=3.5, y=1.0),  # turn to face it, drive there
    MoveRequest(MoveKind.GO_TO, x=3.5, y=1.005),  # there already: DONE at once
    MoveRequest(MoveKind.GO_TO, x=3.5, y=-2.0),  # through the bottom wall: BUMPED
    MoveRequest(MoveKind.GO_TO, x=float('inf'), y=1.0),  # rejected
    MoveRequest(MoveKind.GO_TO, x=2.0, y=1.5),
    MoveRequest(MoveKind.HOLD, seconds=0.01),  # less than a physics step: one step
    MoveRequest(MoveKind.HOLD, seconds=float('nan')),  # rejected
    MoveRequest(MoveKind.HOLD, seconds=1.7),
]


KERNEL_MOVES = [move for move in MOVES if move.kind != MoveKind.HOLD]


def walk(config, reference, moves=MOVES, seen=None, controller=None):
    """Everything observable after each move of a seeded walk."""
    sim = Simulator(maze_map(), config, START, reference=reference)
    on_step = None if seen is None else (lambda s: seen.append(observed(s)))
    record = []
    for move in moves:
        result = execute_move(sim, move, on_step, controller or ControllerConfig())
        record.append((dataclasses.astuple(result), *observed(sim)))
    return record


def observed(sim):
    return (
        sim.state,
        sim.odometry_pose,
        sim.estimate,
        sim.estimate_covariance.tolist(),
        (sim.time, sim.steps, sim.bumps, sim.localisation_updates),
    )


def assert_equal_within_tolerance(fast, reference, path='walk'):
    """Same structure, same ints and strings, floats within TOLERANCE."""
    if isinstance(reference, float):
        assert math.isclose(fast, reference, rel_tol=0.0, abs_tol=TOLERANCE), path
    elif isinstance(reference, tuple | list):
        assert len(fast) == len(reference), path
        for index, (a, b) in enumerate(zip(fast, reference, strict=True)):
            assert_equal_within_tolerance(a, b, f'{path}[{index}]')
    else:
        assert fast == reference, path


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
def test_fast_moves_equal_the_reference(config):
    fast, reference = walk(config, False), walk(config, True)
    outcomes = [entry[0][0] for entry in reference]
    assert MoveOutcome.BUMPED in outcomes and MoveOutcome.REJECTED in outcomes
    assert_equal_within_tolerance(fast, reference)


def test_fast_moves_are_deterministic():
    assert walk(TRAINING, False) == walk(TRAINING, False)


def test_fast_moves_time_out_as_the_reference_does():
    hurried = ControllerConfig(time_limit_factor=0.0, time_limit_margin=0.5)
    moves = [
        MoveRequest(MoveKind.UP, 2.0),
        MoveRequest(MoveKind.RIGHT, 0.5),
        MoveRequest(MoveKind.GO_TO, x=2, y=3),
    ]
    fast = walk(TRAINING, False, moves, controller=hurried)
    reference = walk(TRAINING, True, moves, controller=hurried)
    assert reference[0][0][0] == MoveOutcome.TIMED_OUT
    assert_equal_within_tolerance(fast, reference)


def test_the_step_hook_sees_the_same_states_on_both_paths():
    fast_seen, reference_seen = [], []
    moves = KERNEL_MOVES[:3] + KERNEL_MOVES[9:12]
    walk(TRAINING, False, moves, fast_seen)
    walk(TRAINING, True, moves, reference_seen)
    assert len(fast_seen) > 100
    assert_equal_within_tolerance(fast_seen, reference_seen)


class Publisher:
    """A step hook as sim_node's: publish every ``period`` s of simulated time and after each
    filter update, recording what it saw; its :class:`StepStops` say when that is due."""

    def __init__(self, sim, period, on_time=True, on_update=True):
        self.sim, self.period, self.on_time, self.on_update = sim, period, on_time, on_update
        self.next_publish, self.published_updates = sim.time + period, sim.localisation_updates
        self.seen = []

    def stops(self):
        return StepStops(
            self.next_publish - 1e-9 if self.on_time else math.inf,
            self.published_updates if self.on_update else -1,
        )

    def on_step(self, sim):
        self.seen.append(observed(sim))
        if sim.time >= self.next_publish - 1e-9:
            self.next_publish = sim.time + self.period
        self.published_updates = sim.localisation_updates


def hooked_walk(reference, per_step=False, moves=MOVES, **publisher):
    """A walk whose step hook is due by StepStops; ``per_step``: the kernel returns after every
    step and Python asks ``StepStops.due``, as the compiled path did before it paused itself."""
    sim = Simulator(maze_map(), TRAINING, START, reference=reference)
    hook = Publisher(sim, **publisher)
    record = []
    for move in moves:
        if per_step:
            current = [hook.stops()]

            def on_step(s, current=current):
                if current[0].due(s.time, s.localisation_updates):
                    hook.on_step(s)
                    current[0] = hook.stops()

            result = execute_move(
                sim, move, on_step, step_stops=lambda: StepStops(every_step=True)
            )
        else:
            result = execute_move(sim, move, hook.on_step, step_stops=hook.stops)
        record.append((dataclasses.astuple(result), *observed(sim)))
    return record, hook.seen


@pytest.mark.parametrize(
    'publisher',
    [
        {'period': 0.1},  # sim_node's default rate: not a multiple of the 0.04 s step
        {'period': 0.5, 'on_update': False},
        {'period': 0.3, 'on_time': False},
        {'period': 0.1, 'on_time': False, 'on_update': False},  # nobody listens: no hook
    ],
    ids=['time-and-updates', 'time', 'updates', 'never'],
)
def test_the_kernel_pauses_exactly_at_the_steps_the_hook_is_due(publisher, monkeypatch):
    """Same hook steps and states as the per-step path (bit for bit) and as the reference (within
    1e-9), and one kernel call per hook call plus one per move."""
    calls = []
    run_move = move_loop.run_move

    def counted(*arguments):
        calls.append(arguments[0])
        return run_move(*arguments)

    monkeypatch.setattr(move_loop, 'run_move', counted)
    fast = hooked_walk(False, moves=KERNEL_MOVES, **publisher)
    fast_calls = len(calls)
    assert fast == hooked_walk(False, per_step=True, moves=KERNEL_MOVES, **publisher)
    assert_equal_within_tolerance(fast, hooked_walk(True, moves=KERNEL_MOVES, **publisher))
    record, seen = fast
    executed = sum(entry[0][0] != MoveOutcome.REJECTED for entry in record)
    assert fast_calls == len(seen) + executed
    if publisher.get('on_time', True):
        assert len(seen) > 50
    if not publisher.get('on_update', True) and not publisher.get('on_time', True):
        assert seen == []
    steps = sum(entry[0][3] for entry in record)
    assert fast_calls < steps / 2


@pytest.mark.parametrize('publisher', [{'period': 0.1}, {'period': 0.3, 'on_time': False}])
def test_holds_pass_their_steps_at_rest_at_once_but_stop_where_the_hook_is_due(publisher):
    """A hold jumps over the steps at rest between the hook's stops: the same hook calls, states
    and clock as stepping every physics step (bit for bit) and as the reference."""
    fast = hooked_walk(False, **publisher)
    assert fast == hooked_walk(False, per_step=True, **publisher)
    assert_equal_within_tolerance(fast, hooked_walk(True, **publisher))
    record, seen = fast
    held = [entry for move, entry in zip(MOVES, record, strict=True) if move.kind == MoveKind.HOLD]
    done, rejected = MoveOutcome.DONE, MoveOutcome.REJECTED
    assert [entry[0][0] for entry in held] == [done, done, rejected, done]
    assert [entry[0][3] for entry in held] == [75, 1, 0, 42]  # 3, 0.01 and 1.7 s in 0.04 s steps


def test_runs_of_steps_under_a_command_equal_the_reference_step_by_step():
    """``Simulator.step_run`` (a control period under cmd_vel, its filter updates on the
    kernel) against the reference's ``step``: the same state after every run, and a run ends
    right after the step that updated the filter."""
    commands = [(0.3, 0.0)] * 40 + [(0.0, 1.0)] * 10 + [(0.5, -0.3)] * 30 + [(0.0, 0.0)] * 5
    fast = Simulator(maze_map(), TRAINING, START)
    reference = Simulator(maze_map(), TRAINING, START, reference=True)
    runs = 0
    for linear, angular in commands + [(-0.4, 0.2)] * 20:
        left = 5
        while left:
            updates = fast.localisation_updates
            taken = fast.step_run(linear, angular, left)
            for _ in range(taken):
                reference.step(linear, angular)
            assert taken == left or fast.localisation_updates == updates + 1
            assert_equal_within_tolerance(observed(fast), observed(reference))
            left, runs = left - taken, runs + 1
    assert fast.bumps > 0 and fast.localisation_updates > 20 and runs > len(commands) + 20


def test_a_hook_with_stops_due_every_step_sees_every_step():
    def run(reference):
        sim = Simulator(maze_map(), TRAINING, START, reference=reference)
        seen = []
        result = execute_move(
            sim,
            MoveRequest(MoveKind.UP, 0.5),
            on_step=lambda s: seen.append(observed(s)),
            step_stops=lambda: StepStops(math.inf, -1, every_step=True),
        )
        return dataclasses.astuple(result), seen

    (fast_result, fast_seen), reference = run(False), run(True)
    assert_equal_within_tolerance((fast_result, fast_seen), reference)
    assert len(fast_seen) == fast_result[3]


def test_without_the_kernels_moves_take_the_reference_path_and_say_so_once(monkeypatch, caplog):
    """As without numba, or for a map the kernels do not support."""
    monkeypatch.setattr(compiled_move, 'problem', lambda sim: 'numba is not importable')
    monkeypatch.setattr(move_executor, '_fallback_logged', set())
    with caplog.at_level(logging.WARNING):
        fallback = walk(TRAINING, False, MOVES[:2])
    assert fallback == walk(TRAINING, True, MOVES[:2])  # the reference, exactly
    assert [r.getMessage() for r in caplog.records] == [
        'moves run on the slow reference path: numba is not importable'
    ]


@jit
def _numba_draws(rng, count):
    return (rng.standard_normal(3), rng.standard_normal((count, 3)), rng.random())


def test_numba_draws_are_numpys_bit_for_bit():
    """The premise of the equality: numba's Generator methods are NumPy's, in the same order."""
    compiled, plain = np.random.default_rng(5), np.random.default_rng(5)
    for _ in range(3):
        normals, particles, uniform = _numba_draws(compiled, 200)
        assert (normals == plain.standard_normal(3)).all()
        assert (particles == plain.standard_normal((200, 3))).all()
        assert uniform == plain.random()
    assert (plain.normal(0.0, 0.01, 60) == compiled.normal(0.0, 0.01, 60)).all()


def test_the_kernels_sums_and_remainders_are_numpys_and_pythons():
    rng = np.random.default_rng(0)
    for count in (1, 7, 8, 60, 128, 129, 200, 1000, 100_000):
        values = rng.random(count) ** 3
        assert numeric.pairwise_sum(values, count) == values.sum()
    angles = np.concatenate([rng.uniform(-20, 20, 2000), np.arange(-6, 7) * math.pi])
    for angle in angles.tolist():
        for modulus in (math.pi, 2.0 * math.pi):
            assert numeric.remainder(angle, modulus) == math.remainder(angle, modulus)


def test_whoever_listens_the_walk_is_the_same_bit_for_bit():
    """A viewer or recorder subscribing (sim_node's hook, due at other steps) changes where the
    kernel pauses, never what a seeded walk does: a run is repeatable whoever listens."""
    alone = walk(TRAINING, False)
    for publisher in ({'period': 0.1}, {'period': 0.5, 'on_update': False}):
        assert hooked_walk(False, **publisher)[0] == alone


def test_the_published_scan_is_the_references_bit_for_bit():
    """The scan a simulator publishes is cast by the kernel; the caster's numpy march gives the
    same ranges, so the same noisy readings from the same random stream, pose after pose."""
    config = dataclasses.replace(TRAINING, laser=dataclasses.replace(TRAINING.laser, beams=180))
    sim = Simulator(maze_map(), config, START)
    for move in KERNEL_MOVES[:8]:
        execute_move(sim, move, None, ControllerConfig())
        stream = copy.deepcopy(sim._published_scan_rng)
        reference = noisy_ranges(
            sim.caster.cast(*sim.state.pose, config.laser.bearings()), config.laser, stream
        )
        published = sim.scan()
        assert np.isfinite(published).any()
        assert np.array_equal(published, reference)
