"""One RL move, executed closed-loop on the localisation estimate in simulated time.

A move is "turn to a heading, then drive a distance" (or only the turn). The controller sees only
the estimate, as a robot running on AMCL would: it turns in place until the estimated heading is
within tolerance, then drives towards the target point fixed at the start of the drive
(estimated start + distance along the heading), steering onto it, and finally brakes to rest.
Speeds follow the discrete-time braking curve of the physics step (:mod:`stealth_core.controller`),
so the robot can always stop within the acceleration limit and, near the target, covers the rest
in one step (no slow proportional tail). Simulated time runs as fast as the CPU allows;
``on_step`` lets a caller publish or pace it.

The four grid moves are the original's actions: up (+y), down (-y), left (-x), right (+x) of the
map frame, each a drive of the given step from wherever the robot is. GO_TO drives to a point of
the map instead (turn to face it, then drive): a caller that moves on a lattice of points uses
it to go to the next lattice point, so the small errors of every move (the controller's
tolerance, a bump, localisation noise) do not add up over an episode.
"""

from collections.abc import Callable
import logging
import math
import time
from typing import NamedTuple

import numpy as np
from stealth_core import jit
from stealth_core.controller import approach_speed, signed_approach_speed
from stealth_core.kinematics import Pose, wrap_angle
from stealth_core.moves import (
    GRID_HEADINGS,
    ControllerConfig,
    MoveKind,
    MoveOutcome,
    MoveRequest,
    MoveResult,
    move_problem,
)
from stealth_core.occupancy_map import FREE, OCCUPIED, OccupancyMap

from stealth_sim import compiled_move
from stealth_sim.simulator import SimConfig, Simulator

DEFAULT_CONTROLLER = ControllerConfig()


class StepStops(NamedTuple):
    """After which physics steps a move's step hook is due, as plain numbers.

    Why numbers rather than a predicate: the compiled path then runs its kernel on until the
    step the hook needs (a kernel call costs ~45 us of argument conversion, a step ~10 us), so
    a move with a hook is a handful of kernel calls instead of one per step. The hook is due
    after a step whose simulated time is ``>= time``, or after which the filter's update count
    differs from ``updates`` (-1: never), or after every step with ``every_step``.
    """

    time: float = math.inf
    updates: int = -1
    every_step: bool = False

    def due(self, sim_time: float, updates: int) -> bool:
        return (
            self.every_step
            or sim_time >= self.time
            or (self.updates >= 0 and updates != self.updates)
        )


def execute_move(
    sim: Simulator,
    move: MoveRequest,
    on_step: Callable[[Simulator], None] | None = None,
    controller: ControllerConfig = DEFAULT_CONTROLLER,
    step_stops: Callable[[], StepStops] | None = None,
) -> MoveResult:
    """Run ``move`` to its end; a rejected move leaves the simulator untouched.

    ``on_step`` sees the simulator after every physics step or, with ``step_stops``, only
    after the steps its :class:`StepStops` names; ``step_stops()`` is asked before the first
    step and again after each ``on_step`` (the hook is what changes them). The fast path
    (:mod:`stealth_sim.compiled_move`) runs unless the simulator was made with
    ``reference=True`` or the kernels cannot run it (said once in the log).
    """
    start = sim.estimate
    problem = move_problem(move, sim.max_move_distance, start)
    if problem:
        return MoveResult(MoveOutcome.REJECTED, problem)
    kind = MoveKind(move.kind)
    if kind == MoveKind.HOLD:
        return execute_hold(sim, move.seconds, on_step, step_stops)
    target = None
    if kind == MoveKind.GO_TO:
        distance = math.hypot(move.x - start.x, move.y - start.y)
        heading = math.atan2(move.y - start.y, move.x - start.x) if distance else start.yaw
        if distance <= controller.position_tolerance:
            distance, heading = 0.0, start.yaw  # there already: no turn, no drive
        target = (move.x, move.y)
    elif kind == MoveKind.DRIVE_DISTANCE:
        heading, distance = start.yaw, move.distance
    elif kind == MoveKind.TURN_TO_HEADING:
        heading, distance = wrap_angle(move.heading), 0.0
    else:
        heading, distance = GRID_HEADINGS[kind], move.distance
    nominal = _nominal_duration(sim, heading, distance)
    if sim.reference or not _compiled_path_usable(sim):
        run = _MoveRun(sim, controller, on_step, nominal, step_stops)
    else:
        run = compiled_move.CompiledMoveRun(sim, controller, on_step, nominal, step_stops)
    outcome = MoveOutcome(run.move(heading, distance, target))
    messages = {
        MoveOutcome.DONE: '',
        MoveOutcome.BUMPED: 'the robot touched a wall or unknown space and stopped',
        MoveOutcome.TIMED_OUT: f'the move did not finish within {run.time_limit:.1f} s',
    }
    return MoveResult(outcome, messages[outcome], sim.time - run.start_time, run.steps)


def execute_hold(
    sim: Simulator,
    seconds: float,
    on_step: Callable[[Simulator], None] | None = None,
    step_stops: Callable[[], StepStops] | None = None,
) -> MoveResult:
    """Stand still for ``seconds`` of simulated time (at least one physics step): brake a robot
    that still moves (a move's end may leave < 1 mm/s) with no command, then let the time pass.

    The reference (``sim.reference``) steps every physics step; otherwise the steps at rest
    between the hook's stops are passed at once (``Simulator.stand_still``), which changes
    nothing but their cost: the state, the random streams and the clock end up the same.
    """
    dt = sim.config.physics_dt
    count = max(1, round(seconds / dt))
    start_time, start_step, end = sim.time, sim.steps, sim.steps + count
    stops = step_stops() if on_step is not None and step_stops is not None else None
    while sim.steps < end:
        at_rest = sim.state.linear == 0.0 and sim.state.angular == 0.0
        every_step = sim.reference or (on_step is not None and (stops is None or stops.every_step))
        if at_rest and not every_step:
            sim.stand_still(_steps_to_stop(sim, end, stops) - sim.steps)
        elif sim.step(0.0, 0.0):
            message = 'the robot touched a wall or unknown space while braking to stand still'
            return MoveResult(
                MoveOutcome.BUMPED, message, sim.time - start_time, sim.steps - start_step
            )
        if on_step is not None and (
            stops is None or stops.due(sim.time, sim.localisation_updates)
        ):
            on_step(sim)
            if step_stops is not None:
                stops = step_stops()
    return MoveResult(MoveOutcome.DONE, '', sim.time - start_time, count)


def _steps_to_stop(sim: Simulator, end: int, stops: StepStops | None) -> int:
    """The physics step count at which a hold's hook is next due (or its end)."""
    if stops is None:
        return end
    if stops.updates >= 0 and stops.updates != sim.localisation_updates:
        return sim.steps + 1  # a filter update the hook has not seen yet (the move's last)
    if not math.isfinite(stops.time):
        return end
    dt = sim.config.physics_dt
    until = min(end, max(sim.steps + 1, math.ceil(stops.time / dt - 1e-6)))
    while until < end and until * dt < stops.time:
        until += 1
    return until


_fallback_logged = set()


def _compiled_path_usable(sim: Simulator) -> bool:
    """Whether the compiled path can run ``sim``; the log says why not, once per reason."""
    reason = compiled_move.problem(sim)
    if reason is not None and reason not in _fallback_logged:
        _fallback_logged.add(reason)
        logging.getLogger(__name__).warning('moves run on the slow reference path: %s', reason)
    return reason is None


def _nominal_duration(sim: Simulator, heading: float, distance: float) -> float:
    """Time for the turn and the drive at full speed, ignoring acceleration (s)."""
    limits = sim.config.limits
    turn = abs(wrap_angle(heading - sim.estimate.yaw))
    return turn / limits.max_angular_speed + distance / limits.max_linear_speed


class _MoveRun:
    """The reference: one move in progress, a ``Simulator.step`` per physics step."""

    def __init__(self, sim, controller, on_step, nominal_duration, step_stops=None):
        self.sim = sim
        self.controller = controller
        self.on_step = on_step
        self.step_stops = step_stops
        self.stops = step_stops() if on_step is not None and step_stops is not None else None
        self.start_time = sim.time
        self.steps = 0
        self.time_limit = (
            controller.time_limit_factor * nominal_duration + controller.time_limit_margin
        )

    def _step(self, linear: float, angular: float, timed: bool = True) -> MoveOutcome | None:
        bumped = self.sim.step(linear, angular)
        self.steps += 1
        if self.on_step is not None and (
            self.stops is None or self.stops.due(self.sim.time, self.sim.localisation_updates)
        ):
            self.on_step(self.sim)
            if self.stops is not None:
                self.stops = self.step_stops()
        if bumped:
            return MoveOutcome.BUMPED
        if timed and self.sim.time - self.start_time > self.time_limit:
            return MoveOutcome.TIMED_OUT
        return None

    def move(self, heading: float, distance: float, target) -> MoveOutcome:
        """Turn to ``heading``, drive ``distance`` to ``target`` (None: that far along the
        heading from the estimate after the turn), end at rest, update the filter."""
        outcome = self.turn_to(heading)
        if outcome is None and distance > 0:
            if target is None:
                start = self.sim.estimate
                target = (
                    start.x + distance * math.cos(heading),
                    start.y + distance * math.sin(heading),
                )
            outcome = self.drive_to(target, heading)
        if outcome in (None, MoveOutcome.TIMED_OUT):
            # Always end at rest; only a bump can interrupt the braking.
            outcome = self.brake(timed=False) or outcome or MoveOutcome.DONE
        self.sim.localise_now()
        return outcome

    def _turn_rate(self, error: float) -> float:
        """Turn rate towards a heading error, on the braking curve."""
        limits = self.sim.config.limits
        return signed_approach_speed(
            error,
            limits.max_angular_speed,
            self.controller.braking_share * limits.max_angular_accel,
            self.sim.config.physics_dt,
        )

    def turn_to(self, heading: float) -> MoveOutcome | None:
        """Turn in place until the estimated heading is within tolerance, then stop (None)."""
        tolerance = self.controller.heading_tolerance
        while True:
            error = wrap_angle(heading - self.sim.estimate.yaw)
            if abs(error) <= tolerance:
                return self.brake()
            outcome = self._step(0.0, self._turn_rate(error))
            if outcome is not None:
                return outcome

    def drive_to(self, target: tuple[float, float], heading: float) -> MoveOutcome | None:
        """Drive until the target is within tolerance along the drive's line (None)."""
        limits, controller = self.sim.config.limits, self.controller
        direction = (math.cos(heading), math.sin(heading))
        while True:
            pose: Pose = self.sim.estimate
            dx, dy = target[0] - pose.x, target[1] - pose.y
            remaining = dx * direction[0] + dy * direction[1]  # along the drive's line
            if remaining <= controller.position_tolerance:
                return None
            aim = math.atan2(dy, dx) if math.hypot(dx, dy) > controller.aim_distance else heading
            error = wrap_angle(aim - pose.yaw)
            speed = approach_speed(
                remaining,
                limits.max_linear_speed,
                controller.braking_share * limits.max_linear_accel,
                self.sim.config.physics_dt,
            )
            # Slow down while badly misaligned rather than drive sideways off the line.
            speed *= max(0.0, math.cos(error))
            outcome = self._step(speed, self._turn_rate(error))
            if outcome is not None:
                return outcome

    def brake(self, timed: bool = True) -> MoveOutcome | None:
        """Command zero until the robot is at rest (None), unless it bumps or runs out of time."""
        stopped = self.controller.stopped_speed
        while abs(self.sim.state.linear) > stopped or abs(self.sim.state.angular) > stopped:
            outcome = self._step(0.0, 0.0, timed)
            if outcome is not None:
                return outcome
        return None


def warm_up() -> float | None:
    """Compile the kernels (or load them from the cache) with one move and one filter update
    (``Simulator.step_run``'s) of a throwaway simulator, so that no real move or control
    period pays for it: the seconds it took, None without numba."""
    if jit.import_problem() is not None:
        return None
    cells = np.full((40, 40), OCCUPIED, np.int8)
    cells[1:-1, 1:-1] = FREE
    sim = Simulator(OccupancyMap(cells, 0.05, (0.0, 0.0, 0.0)), SimConfig(), Pose(1.0, 1.0, 0.0))
    started = time.perf_counter()
    execute_move(sim, MoveRequest(MoveKind.UP, 0.3))
    compiled_move.update_localisation(sim)
    return time.perf_counter() - started
