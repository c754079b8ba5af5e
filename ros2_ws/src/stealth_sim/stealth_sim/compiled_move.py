"""The fast path of a move: the reference closed loop compiled with numba, filter included.

``move_executor._MoveRun`` driving ``Simulator.step`` (controller, velocity limits, exact arc
integration, swept-disc collision, AMCL odometry noise, the filter's update schedule, the
laser cast and the particle filter's predict, likelihood-field correct, estimate and
systematic resampling) is repeated here as ``@njit`` kernels on the simulator's arrays, in the
same operations and the same random draws from the same generators (numba's
``np.random.Generator`` draws are NumPy's, bit for bit). What differs is summation order where
NumPy hands a sum to BLAS (the estimate's weighted means and covariance: last-bit differences)
and where its complex product may fuse a multiply-add (beam endpoints: last-bit differences
that change a likelihood cell only on an exact cell boundary). ``test_fast_paths`` proves whole
seeded walks equal to the reference within 1e-9.

Why compiled rather than numpy batches: a move is cut every ~3 physics steps by
state-dependent events (filter updates, odometry segments, the controller leaving its
acceleration limit, bumps), and each filter update is a 60-beam cast and 200 x 60 lookups
whose numpy calls cost more than their arithmetic.

The kernels (:mod:`stealth_sim.kernels`: one module per concept, on the array layout of
``kernels.layout``) compile on first use (:mod:`stealth_core.jit`: once per machine, into
numba's cache; an unwritable cache only costs the compile in every process). Here the
simulator's objects become those arrays and back. Without numba the reference runs, and
:func:`problem` says why.
"""

import math

import numpy as np
from stealth_core.jit import import_problem

from stealth_sim.kernels import move_loop, particle_filter
from stealth_sim.kernels.layout import (
    ANGULAR,
    BUMPS,
    DISTANCE,
    ESTIMATE_AT_UPDATE,
    HAS_TARGET,
    HEADING,
    LINEAR,
    NORMALS,
    ODOM,
    ODOM_AT_UPDATE,
    OUTCOME,
    PAUSED,
    RUN_STEPS,
    SEGMENT_ODOM,
    SEGMENT_TRUE,
    SIM_STEPS,
    STAGE,
    STATE_SIZE,
    STOP_TIME,
    STOP_UPDATES,
    TARGET_X,
    TARGET_Y,
    TURN,
    UPDATES,
    YAW,
    X,
    Y,
    parameters,
)

# --- the simulator's objects in arrays, and back ---------------------------------------------


def _static_arrays(sim):
    """The map's arrays the kernels read, built once per simulator."""
    cached = getattr(sim, '_compiled_arrays', None)
    if cached is None:
        footprint, caster = sim.footprint, sim.caster
        cached = (
            (
                np.ascontiguousarray(footprint.blocked),
                np.ascontiguousarray(footprint.lower_bound, dtype=np.float64),
            ),
            (
                np.frombuffer(caster._free_samples, dtype=np.uint8),
                caster.blocked.shape[1] * 4,
                np.asarray(caster._steps, dtype=np.float64),
                np.ascontiguousarray(sim.filter_beam_bearings, dtype=np.float64),
                _score_table(sim.localiser.filter.field.score),
            ),
        )
        sim._compiled_arrays = cached
    return cached


def _score_table(score: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The likelihood field as a uint16 index per cell into its distinct scores (a few
    hundred: one per distance to the nearest obstacle)."""
    scores, index = np.unique(score, return_inverse=True)
    return index.reshape(score.shape).astype(np.uint16), scores


def problem(sim) -> str | None:
    """Why the kernels cannot run this simulator, or None when they can (found once)."""
    if import_problem() is not None:
        return import_problem()
    found = getattr(sim, '_compiled_problem', False)
    if found is False:
        found = None
        if np.unique(sim.localiser.filter.field.score).size > 1 << 16:
            found = 'the likelihood field has more than 65536 distinct scores (a uint16 index)'
        sim._compiled_problem = found
    return found


def _load(sim) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The kernels' state, covariance, particles and weights of ``sim`` (copies)."""
    state = np.empty(STATE_SIZE)
    odometry, localiser = sim.odometry, sim.localiser
    pose, linear, angular = sim.state
    state[X : SIM_STEPS + 2] = (*pose, linear, angular, sim.steps, sim.bumps)
    for at, value in (
        (ODOM, odometry.pose),
        (SEGMENT_TRUE, odometry._segment_true_start),
        (SEGMENT_ODOM, odometry._segment_odom_start),
        (NORMALS, odometry._normals),
        (ODOM_AT_UPDATE, localiser._odom_at_update),
        (ESTIMATE_AT_UPDATE, localiser._estimate_at_update),
    ):
        state[at : at + 3] = value
    state[UPDATES], state[RUN_STEPS] = localiser.updates, 0.0
    state[STOP_TIME], state[STOP_UPDATES] = math.inf, -1.0
    return (
        state,
        np.array(localiser.covariance, dtype=np.float64),
        np.array(localiser.filter.particles, dtype=np.float64, order='C'),
        np.array(localiser.filter.weights, dtype=np.float64),
    )


def _store(sim, state, covariance, particles, weights) -> None:
    """Write the kernels' arrays back into ``sim``'s objects (which keep the arrays given)."""
    from stealth_core.kinematics import Pose, RobotState

    s = state.tolist()
    sim.state = RobotState(Pose(s[X], s[Y], s[YAW]), s[LINEAR], s[ANGULAR])
    sim.steps, sim.bumps = int(s[SIM_STEPS]), int(s[BUMPS])
    sim.time = sim.steps * sim.config.physics_dt
    odometry, localiser = sim.odometry, sim.localiser
    odometry.pose = Pose(*s[ODOM : ODOM + 3])
    odometry._segment_true_start = Pose(*s[SEGMENT_TRUE : SEGMENT_TRUE + 3])
    odometry._segment_odom_start = Pose(*s[SEGMENT_ODOM : SEGMENT_ODOM + 3])
    odometry._normals = s[NORMALS : NORMALS + 3]
    localiser._odom_at_update = Pose(*s[ODOM_AT_UPDATE : ODOM_AT_UPDATE + 3])
    localiser._estimate_at_update = Pose(*s[ESTIMATE_AT_UPDATE : ESTIMATE_AT_UPDATE + 3])
    localiser.updates = int(s[UPDATES])
    localiser.covariance = covariance
    localiser.filter.particles = particles
    localiser.filter.weights = weights


def update_localisation(sim) -> None:
    """``Simulator._update_localisation`` on the kernel (``problem(sim)`` must be None), at
    the odometry the simulator holds: the same update within 1e-9 (``test_fast_paths``), ~1 ms
    less per update than numpy's calls on 60 beams and 200 particles."""
    config = sim.config
    cached = getattr(sim, '_compiled_update_parameters', None)
    if cached is None or cached[0] is not config:  # reconfigure() replaces the config
        cached = (config, parameters(sim, None, 0.0, math.inf))
        sim._compiled_update_parameters = cached
    state, covariance, particles, weights = _load(sim)
    rngs = (sim.odometry.rng, sim.localiser.filter.rng, sim._filter_scan_rng)
    arrays = _static_arrays(sim)[1]
    particle_filter.update_localisation(
        state, cached[1], arrays, covariance, particles, weights, rngs
    )
    _store(sim, state, covariance, particles, weights)


class CompiledMoveRun:
    """One move in progress on the kernels; the interface of ``move_executor._MoveRun``.

    The simulator's objects are written back at the end of the move and before each step
    hook; hooks only look (as sim_node's publish). The kernel runs on until the step the
    hook's ``StepStops`` name, so a move is one kernel call per hook call, plus one.
    """

    def __init__(self, sim, controller, on_step, nominal_duration, step_stops=None):
        self.sim = sim
        self.on_step = on_step
        self.step_stops = step_stops
        self.start_time = sim.time
        self.time_limit = (
            controller.time_limit_factor * nominal_duration + controller.time_limit_margin
        )
        self.params = parameters(sim, controller, self.start_time, self.time_limit)
        self.footprint, self.arrays = _static_arrays(sim)
        self.rngs = (sim.odometry.rng, sim.localiser.filter.rng, sim._filter_scan_rng)
        self._load()

    @property
    def steps(self) -> int:
        return int(self.state[RUN_STEPS])

    def _load(self) -> None:
        self.state, self.covariance, self.particles, self.weights = _load(self.sim)

    def _store(self) -> None:
        _store(self.sim, self.state, self.covariance.copy(), self.particles.copy(),
               self.weights.copy())  # fmt: skip

    def move(self, heading: float, distance: float, target):
        """``_MoveRun.move``: the whole move in one kernel call, plus one per step hook call."""
        state = self.state
        state[STAGE], state[OUTCOME], state[HEADING], state[DISTANCE] = TURN, 0, heading, distance
        state[HAS_TARGET] = target is not None
        if target is not None:
            state[TARGET_X], state[TARGET_Y] = target
        arguments = (
            state,
            self.params,
            self.footprint,
            self.arrays,
            self.covariance,
            self.particles,
            self.weights,
            self.rngs,
        )
        if self.on_step is None:
            outcome = move_loop.run_move(1 << 62, *arguments)
        else:
            while True:
                every_step = True
                if self.step_stops is not None:
                    stops = self.step_stops()
                    state[STOP_TIME], state[STOP_UPDATES] = stops.time, stops.updates
                    every_step = stops.every_step
                outcome = move_loop.run_move(1 if every_step else 1 << 62, *arguments)
                if outcome != PAUSED:
                    break
                self._store()
                self.on_step(self.sim)
        self._store()
        return int(outcome)  # an ExecuteMove outcome number (stealth_core.moves.MoveOutcome)
