"""Where everything sits in the two float64 arrays the kernels share: the move's state (updated
in place) and its parameters (read only, filled by :func:`parameters`). One place for the
indices, so that every kernel module reads the same layout."""

import math

import numpy as np

# The move state, one float64 array the kernels update in place (indices).
X, Y, YAW, LINEAR, ANGULAR, SIM_STEPS, BUMPS = range(7)
# Poses, three floats each:
ODOM, SEGMENT_TRUE, SEGMENT_ODOM, NORMALS, ODOM_AT_UPDATE, ESTIMATE_AT_UPDATE = range(7, 25, 3)
UPDATES, RUN_STEPS, STAGE, OUTCOME, HEADING, DISTANCE = range(25, 31)
TARGET_X, TARGET_Y, HAS_TARGET = range(31, 34)
# Where run_move pauses for a step hook (move_executor.StepStops: time, updates).
STOP_TIME, STOP_UPDATES, STATE_SIZE = range(34, 37)

# Parameters, one float64 array (indices).
(
    DT,
    MAX_LINEAR,
    MAX_ANGULAR,
    LINEAR_ACCEL,
    ANGULAR_ACCEL,
    BRAKING_SHARE,
    HEADING_TOLERANCE,
    POSITION_TOLERANCE,
    AIM_DISTANCE,
    STOPPED_SPEED,
    TIME_LIMIT,
    START_TIME,
    ODOM_ALPHAS,  # 4
) = range(13)
SEGMENT_DISTANCE, SEGMENT_ANGLE, UPDATE_MIN_D, UPDATE_MIN_A, RESAMPLE_INTERVAL = range(16, 21)
FILTER_ALPHAS = 21  # 4
FOOTPRINT_RES, FOOTPRINT_X, FOOTPRINT_Y, RADIUS = range(25, 29)
CASTER_RES, CASTER_X, CASTER_Y, RANGE_MAX, RANGE_MIN, NOISE_STD = range(29, 35)
FIELD_INVERSE_RES, FIELD_X, FIELD_Y, PARAMS_SIZE = 35, 36, 37, 38

# The stages of a move (``_MoveRun.move``) and what a kernel call ends with (move_executor's
# MoveOutcome numbers, and PAUSED: the step budget is used up).
TURN, TURN_BRAKE, DRIVE, END_BRAKE, LOCALISE, ENDED = range(6)
FINISHED, BUMPED, TIMED_OUT, PAUSED = 0, 1, 3, -1


class _NoController:
    braking_share = heading_tolerance = position_tolerance = math.nan
    aim_distance = stopped_speed = math.nan


_NO_CONTROLLER = _NoController()


def parameters(sim, controller, start_time: float, time_limit: float) -> np.ndarray:
    """The parameter array of a move of ``sim`` (a ``Simulator``) under ``controller`` (a
    ``move_executor.ControllerConfig``; None for a filter update alone: its fields NaN)."""
    config, limits, localiser = sim.config, sim.config.limits, sim.localiser
    if controller is None:
        controller = _NO_CONTROLLER
    odometry, noise = sim.odometry, sim.odometry.noise
    motion, footprint, caster = localiser.filter.motion_noise, sim.footprint, sim.caster
    field = localiser.filter.field
    p = np.empty(PARAMS_SIZE)
    p[DT : ODOM_ALPHAS + 4] = (
        config.physics_dt,
        limits.max_linear_speed,
        limits.max_angular_speed,
        limits.max_linear_accel,
        limits.max_angular_accel,
        controller.braking_share,
        controller.heading_tolerance,
        controller.position_tolerance,
        controller.aim_distance,
        controller.stopped_speed,
        time_limit,
        start_time,
        noise.alpha1,
        noise.alpha2,
        noise.alpha3,
        noise.alpha4,
    )
    p[SEGMENT_DISTANCE:PARAMS_SIZE] = (
        odometry.segment_distance,
        odometry.segment_angle,
        localiser.config.update_min_d,
        localiser.config.update_min_a,
        localiser.config.resample_interval,
        motion.alpha1,
        motion.alpha2,
        motion.alpha3,
        motion.alpha4,
        footprint.resolution,
        footprint.origin_x,
        footprint.origin_y,
        footprint.radius,
        caster.resolution,
        caster.origin_x,
        caster.origin_y,
        caster.range_max,
        config.laser.range_min,
        config.laser.noise_std,
        field.inverse_resolution,
        field.origin_x,
        field.origin_y,
    )
    return p
