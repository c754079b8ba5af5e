"""The closed loop of a move as a kernel: ``move_executor._MoveRun.move`` (turn, brake, drive,
brake, localise) on the estimate, with the controller's speed law (:mod:`stealth_core.controller`,
compiled in) and ``Simulator.step`` per physics step, pausing where a step hook is due."""

import math

from stealth_core.controller import approach_speed, signed_approach_speed
from stealth_core.jit import jit

from stealth_sim.kernels.layout import (
    AIM_DISTANCE,
    ANGULAR,
    ANGULAR_ACCEL,
    BRAKING_SHARE,
    BUMPED,
    BUMPS,
    DISTANCE,
    DRIVE,
    DT,
    END_BRAKE,
    ENDED,
    FINISHED,
    HAS_TARGET,
    HEADING,
    HEADING_TOLERANCE,
    LINEAR,
    LINEAR_ACCEL,
    LOCALISE,
    MAX_ANGULAR,
    MAX_LINEAR,
    ODOM,
    ODOM_AT_UPDATE,
    OUTCOME,
    PAUSED,
    POSITION_TOLERANCE,
    RUN_STEPS,
    SIM_STEPS,
    STAGE,
    START_TIME,
    STOP_TIME,
    STOP_UPDATES,
    STOPPED_SPEED,
    TARGET_X,
    TARGET_Y,
    TIME_LIMIT,
    TIMED_OUT,
    TURN,
    TURN_BRAKE,
    UPDATE_MIN_A,
    UPDATE_MIN_D,
    UPDATES,
)
from stealth_sim.kernels.numeric import TWO_PI, remainder
from stealth_sim.kernels.odometry import odometry_update, relative
from stealth_sim.kernels.particle_filter import estimate, update_localisation
from stealth_sim.kernels.physics import physics_step


@jit
def _step(s, p, footprint, arrays, covariance, particles, weights, rngs, linear, angular, timed):
    """``Simulator.step`` and ``_MoveRun._step``: BUMPED, TIMED_OUT or FINISHED (go on)."""
    blocked, lower_bound = footprint
    bumped = physics_step(s, p, blocked, lower_bound, linear, angular)
    s[SIM_STEPS] += 1.0
    s[BUMPS] += bumped
    odometry_update(s, p, rngs[0])
    forward, left, turn = relative(s, ODOM_AT_UPDATE, ODOM)
    if math.hypot(forward, left) >= p[UPDATE_MIN_D] or abs(turn) >= p[UPDATE_MIN_A]:
        update_localisation(s, p, arrays, covariance, particles, weights, rngs)
    s[RUN_STEPS] += 1.0
    if bumped:
        return BUMPED
    if timed and int(s[SIM_STEPS]) * p[DT] - p[START_TIME] > p[TIME_LIMIT]:
        return TIMED_OUT
    return FINISHED


@jit
def run_move(max_steps, s, p, footprint, arrays, covariance, particles, weights, rngs):
    """``_MoveRun.move`` from the stage in ``s[STAGE]`` on: the outcome when the move has
    ended, else PAUSED right after the step a hook needs: the ``max_steps``-th, or one whose
    simulated time is >= ``s[STOP_TIME]``, or after which the filter's update count differs
    from ``s[STOP_UPDATES]`` (unless that is -1)."""
    heading = s[HEADING]
    turn_decel = p[BRAKING_SHARE] * p[ANGULAR_ACCEL]
    drive_decel = p[BRAKING_SHARE] * p[LINEAR_ACCEL]
    while True:
        stage = int(s[STAGE])
        if stage == ENDED:
            return int(s[OUTCOME])
        if stage == LOCALISE:  # Simulator.localise_now
            if (
                s[ODOM] != s[ODOM_AT_UPDATE]
                or s[ODOM + 1] != s[ODOM_AT_UPDATE + 1]
                or s[ODOM + 2] != s[ODOM_AT_UPDATE + 2]
            ):
                update_localisation(s, p, arrays, covariance, particles, weights, rngs)
            s[STAGE] = ENDED
            continue
        linear = angular = 0.0
        if stage == TURN:
            error = remainder(heading - estimate(s)[2], TWO_PI)
            if abs(error) <= p[HEADING_TOLERANCE]:
                s[STAGE] = TURN_BRAKE
                continue
            angular = signed_approach_speed(error, p[MAX_ANGULAR], turn_decel, p[DT])
        elif stage == DRIVE:
            x, y, yaw = estimate(s)
            dx, dy = s[TARGET_X] - x, s[TARGET_Y] - y
            remaining = dx * math.cos(heading) + dy * math.sin(heading)
            if remaining <= p[POSITION_TOLERANCE]:
                s[STAGE] = END_BRAKE
                continue
            aim = math.atan2(dy, dx) if math.hypot(dx, dy) > p[AIM_DISTANCE] else heading
            error = remainder(aim - yaw, TWO_PI)
            linear = approach_speed(remaining, p[MAX_LINEAR], drive_decel, p[DT])
            linear *= max(0.0, math.cos(error))
            angular = signed_approach_speed(error, p[MAX_ANGULAR], turn_decel, p[DT])
        elif abs(s[LINEAR]) <= p[STOPPED_SPEED] and abs(s[ANGULAR]) <= p[STOPPED_SPEED]:
            if stage == END_BRAKE or s[DISTANCE] <= 0.0:
                s[STAGE] = END_BRAKE if stage == TURN_BRAKE else LOCALISE
                continue
            if not s[HAS_TARGET]:
                x, y, _ = estimate(s)
                s[TARGET_X] = x + s[DISTANCE] * math.cos(heading)
                s[TARGET_Y] = y + s[DISTANCE] * math.sin(heading)
            s[STAGE] = DRIVE
            continue
        outcome = _step(
            s,
            p,
            footprint,
            arrays,
            covariance,
            particles,
            weights,
            rngs,
            linear,
            angular,
            stage != END_BRAKE,
        )
        if outcome == BUMPED:
            s[OUTCOME], s[STAGE] = BUMPED, LOCALISE
        elif outcome == TIMED_OUT:
            s[OUTCOME], s[STAGE] = TIMED_OUT, END_BRAKE
        max_steps -= 1
        if (
            max_steps == 0
            or s[SIM_STEPS] * p[DT] >= s[STOP_TIME]
            or (s[STOP_UPDATES] >= 0.0 and s[UPDATES] != s[STOP_UPDATES])
        ):
            return PAUSED
