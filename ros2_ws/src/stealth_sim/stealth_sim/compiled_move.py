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

The kernels compile on first use (``cache=True``: once per machine, into numba's cache; an
unwritable cache only costs the compile in every process). Without numba the reference runs,
and :func:`problem` says why.
"""

import logging
import math
import os

import numpy as np

from stealth_sim.odometry_noise import MIN_BEARING_TRANSLATION

LOG = logging.getLogger('stealth_sim.compiled_move')
TWO_PI = 2.0 * math.pi
_SINC_SERIES = 1e-4  # kinematics.integrate's switch to the series form of sinc
_CONTACT_BISECTIONS = 12  # kinematics' bisection steps for a bump's contact point

try:
    import numba
except ImportError as exc:  # pragma: no cover - numba is pinned in requirements.lock
    numba = None
    _IMPORT_PROBLEM = f'numba is not importable ({exc})'
else:
    _IMPORT_PROBLEM = None


def _njit(function):
    """``numba.njit(cache=True)``, or without the cache when numba has nowhere to write it.

    The cache sits beside the source file the code object names: the real file, so that the
    colcon install (symlinks) and the source tree share one cache.
    """
    code = function.__code__
    function.__code__ = code.replace(co_filename=os.path.realpath(code.co_filename))
    try:
        return numba.njit(cache=True, error_model='numpy')(function)
    except RuntimeError as exc:  # numba: "cannot cache function ...: no locator available"
        LOG.warning('numba cannot cache %s (%s); it compiles in every process', function, exc)
        return numba.njit(error_model='numpy')(function)


def _identity(function):
    return function


jit = _identity if numba is None else _njit

# The move state, one float64 array the kernels update in place (indices).
X, Y, YAW, LINEAR, ANGULAR, SIM_STEPS, BUMPS = range(7)
# Poses, three floats each:
ODOM, SEGMENT_TRUE, SEGMENT_ODOM, NORMALS, ODOM_AT_UPDATE, ESTIMATE_AT_UPDATE = range(7, 25, 3)
UPDATES, RUN_STEPS, PHASE, OUTCOME, HEADING, DISTANCE = range(25, 31)
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

# The phases of a move (``_MoveRun.move``) and what a kernel call ends with (move_executor's
# Outcome numbers, and PAUSED: the step budget is used up).
TURN, TURN_BRAKE, DRIVE, END_BRAKE, LOCALISE, ENDED = range(6)
FINISHED, BUMPED, TIMED_OUT, PAUSED = 0, 1, 3, -1


@jit
def _remainder(x, y):
    """CPython's ``math.remainder`` (exact, for finite x and y > 0): numba has none."""
    absx = abs(x)
    if absx < 0.5 * y:  # already in range (exact: fl(y - absx) >= y / 2 > absx)
        return x
    m = np.fmod(absx, y)
    c = y - m
    if m < c:
        r = m
    elif m > c:
        r = -c
    else:
        r = m - 2.0 * np.fmod(0.5 * (absx - m), y)
    return math.copysign(1.0, x) * r


@jit
def _wrap_array_value(angle):
    """``kinematics.wrap_angle`` of an array element (round half to even, not remainder)."""
    return angle - TWO_PI * np.rint(angle / TWO_PI)


@jit
def _pairwise_block(values, start, count):
    """NumPy's pairwise summation of up to 128 contiguous float64: eight running sums."""
    if count < 8:
        total = 0.0
        for i in range(start, start + count):
            total += values[i]
        return total
    r0, r1, r2, r3 = values[start], values[start + 1], values[start + 2], values[start + 3]
    r4, r5, r6, r7 = values[start + 4], values[start + 5], values[start + 6], values[start + 7]
    whole = count - count % 8
    for i in range(start + 8, start + whole, 8):
        r0 += values[i]
        r1 += values[i + 1]
        r2 += values[i + 2]
        r3 += values[i + 3]
        r4 += values[i + 4]
        r5 += values[i + 5]
        r6 += values[i + 6]
        r7 += values[i + 7]
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for i in range(start + whole, start + count):
        total += values[i]
    return total


@jit
def _pairwise_sum(values, count):
    """NumPy's pairwise summation (what ``ndarray.sum`` does): halves (multiples of 8) until
    blocks of 128, here without recursion (which numba's cache cannot hold)."""
    if count <= 128:
        return _pairwise_block(values, 0, count)
    starts = np.empty(64, np.int64)
    counts = np.empty(64, np.int64)
    stages = np.empty(64, np.int64)
    lefts = np.empty(64)
    depth, starts[0], counts[0], stages[0] = 0, 0, count, 0
    total = 0.0
    while depth >= 0:
        n = counts[depth]
        if n <= 128:
            total = _pairwise_block(values, starts[depth], n)
            depth -= 1
            continue
        half = n // 2
        half -= half % 8
        if stages[depth] == 2:
            total = lefts[depth] + total
            depth -= 1
            continue
        if stages[depth] == 1:
            lefts[depth] = total
        stages[depth] += 1
        first = stages[depth] == 1
        starts[depth + 1] = starts[depth] if first else starts[depth] + half
        counts[depth + 1] = half if first else n - half
        stages[depth + 1] = 0
        depth += 1
    return total


# --- the robot -------------------------------------------------------------------------------


@jit
def _sweep_touches_blocked(p, blocked, x0, y0, x1, y1):
    """``DiscFootprint._sweep_touches_blocked``: segment-to-square distances, exactly."""
    res, radius = p[FOOTPRINT_RES], p[RADIUS]
    origin_x, origin_y = p[FOOTPRINT_X], p[FOOTPRINT_Y]
    rows, cols = blocked.shape
    col_lo = max(math.floor((min(x0, x1) - radius - origin_x) / res), 0)
    col_hi = min(math.floor((max(x0, x1) + radius - origin_x) / res), cols - 1)
    row_lo = max(math.floor((min(y0, y1) - radius - origin_y) / res), 0)
    row_hi = min(math.floor((max(y0, y1) + radius - origin_y) / res), rows - 1)
    dx, dy = x1 - x0, y1 - y0
    length_sq = dx * dx + dy * dy
    radius_sq = radius * radius
    for row in range(row_lo, row_hi + 1):
        for col in range(col_lo, col_hi + 1):
            if not blocked[row, col]:
                continue
            left = origin_x + col * res
            bottom = origin_y + row * res
            right, top = left + res, bottom + res
            ex = max(max(left - x0, x0 - right), 0.0)
            ey = max(max(bottom - y0, y0 - top), 0.0)
            nearest = ex * ex + ey * ey
            ex = max(max(left - x1, x1 - right), 0.0)
            ey = max(max(bottom - y1, y1 - top), 0.0)
            nearest = min(nearest, ex * ex + ey * ey)
            if length_sq != 0.0:
                for corner in range(4):
                    corner_x = right if corner & 1 else left
                    corner_y = top if corner & 2 else bottom
                    t = ((corner_x - x0) * dx + (corner_y - y0) * dy) / length_sq
                    t = min(max(t, 0.0), 1.0)
                    ex, ey = x0 + t * dx - corner_x, y0 + t * dy - corner_y
                    nearest = min(nearest, ex * ex + ey * ey)
            if nearest < radius_sq:
                return True
            # segment_crosses_squares: the slab test, boundaries included.
            t_enter, t_exit = 0.0, 1.0
            for axis in range(2):
                start, delta, low = (x0, dx, left) if axis == 0 else (y0, dy, bottom)
                if delta == 0.0:
                    if not (low <= start and start <= low + res):
                        t_exit = -1.0
                    continue
                t_a, t_b = (low - start) / delta, (low + res - start) / delta
                t_enter = max(t_enter, min(t_a, t_b))
                t_exit = min(t_exit, max(t_a, t_b))
            if t_enter <= t_exit:
                return True
    return False


@jit
def _sweep_is_free(p, blocked, lower_bound, x0, y0, x1, y1):
    """``DiscFootprint.sweep_is_free``."""
    res, origin_x, origin_y = p[FOOTPRINT_RES], p[FOOTPRINT_X], p[FOOTPRINT_Y]
    rows, cols = blocked.shape
    col = math.floor((x0 - origin_x) / res)
    row = math.floor((y0 - origin_y) / res)
    end_col = math.floor((x1 - origin_x) / res)
    end_row = math.floor((y1 - origin_y) / res)
    if not (0 <= row < rows and 0 <= col < cols and 0 <= end_row < rows and 0 <= end_col < cols):
        return False
    if lower_bound[row, col] - math.hypot(x1 - x0, y1 - y0) >= p[RADIUS]:
        return True
    return not _sweep_touches_blocked(p, blocked, x0, y0, x1, y1)


@jit
def _limited(current, command, max_speed, max_accel, dt):
    """``kinematics.limited_velocity``."""
    target = min(max(command, -max_speed), max_speed)
    change = min(max(target - current, -max_accel * dt), max_accel * dt)
    return current + change


@jit
def _physics_step(s, p, blocked, lower_bound, linear_command, angular_command):
    """``kinematics.step_robot`` on the state; True when the robot bumped."""
    dt = p[DT]
    linear = _limited(s[LINEAR], linear_command, p[MAX_LINEAR], p[LINEAR_ACCEL], dt)
    angular = _limited(s[ANGULAR], angular_command, p[MAX_ANGULAR], p[ANGULAR_ACCEL], dt)
    x0, y0, yaw0 = s[X], s[Y], s[YAW]
    half_turn = 0.5 * angular * dt
    if abs(half_turn) < _SINC_SERIES:
        sinc = 1.0 - half_turn * half_turn / 6.0
    else:
        sinc = math.sin(half_turn) / half_turn
    chord = linear * dt * sinc
    heading = yaw0 + half_turn
    x = x0 + chord * math.cos(heading)
    y = y0 + chord * math.sin(heading)
    yaw = _remainder(yaw0 + angular * dt, TWO_PI)
    bumped = not _sweep_is_free(p, blocked, lower_bound, x0, y0, x, y)
    if bumped:
        low, high = 0.0, 1.0
        for _ in range(_CONTACT_BISECTIONS):
            middle = 0.5 * (low + high)
            free = _sweep_is_free(
                p, blocked, lower_bound, x0, y0, x0 + middle * (x - x0), y0 + middle * (y - y0)
            )
            if free:
                low = middle
            else:
                high = middle
        x, y = x0 + low * (x - x0), y0 + low * (y - y0)
        linear = angular = 0.0
    s[X], s[Y], s[YAW], s[LINEAR], s[ANGULAR] = x, y, yaw, linear, angular
    return bumped


@jit
def _decompose(x0, y0, yaw0, x1, y1, yaw1):
    """``odometry_noise.decompose``: (rot1, trans, rot2)."""
    dx, dy = x1 - x0, y1 - y0
    trans = math.hypot(dx, dy)
    rot1 = _remainder(math.atan2(dy, dx) - yaw0, TWO_PI) if trans > 0.0 else 0.0
    rot2 = _remainder(yaw1 - yaw0 - rot1, TWO_PI)
    return rot1, trans, rot2


@jit
def _stddevs(rot1, trans, rot2, p, alphas):
    """``odometry_noise.noise_stddevs`` with the alphas at ``p[alphas:alphas + 4]``."""
    if trans < MIN_BEARING_TRANSLATION:
        noise_rot1, noise_rot2 = 0.0, abs(_remainder(rot1 + rot2, math.pi))
    else:
        noise_rot1, noise_rot2 = abs(_remainder(rot1, math.pi)), abs(_remainder(rot2, math.pi))
    alpha1, alpha2, alpha3, alpha4 = p[alphas], p[alphas + 1], p[alphas + 2], p[alphas + 3]
    trans_sq = trans * trans
    return (
        math.sqrt(alpha1 * noise_rot1 * noise_rot1 + alpha2 * trans_sq),
        math.sqrt(
            alpha3 * trans_sq + alpha4 * (noise_rot1 * noise_rot1 + noise_rot2 * noise_rot2)
        ),
        math.sqrt(alpha1 * noise_rot2 * noise_rot2 + alpha2 * trans_sq),
    )


@jit
def _odometry_update(s, p, odometry_rng):
    """``NoisyOdometry.update`` at the true pose."""
    x, y, yaw = s[X], s[Y], s[YAW]
    start_x, start_y, start_yaw = s[SEGMENT_TRUE], s[SEGMENT_TRUE + 1], s[SEGMENT_TRUE + 2]
    if x == start_x and y == start_y and yaw == start_yaw:
        s[ODOM : ODOM + 3] = s[SEGMENT_ODOM : SEGMENT_ODOM + 3]
        return
    rot1, trans, rot2 = _decompose(start_x, start_y, start_yaw, x, y, yaw)
    std1, std_trans, std2 = _stddevs(rot1, trans, rot2, p, ODOM_ALPHAS)
    noisy_rot1 = rot1 - std1 * s[NORMALS]
    noisy_trans = trans - std_trans * s[NORMALS + 1]
    heading = s[SEGMENT_ODOM + 2] + noisy_rot1
    noisy_rot2 = rot2 - std2 * s[NORMALS + 2]
    s[ODOM] = s[SEGMENT_ODOM] + noisy_trans * math.cos(heading)
    s[ODOM + 1] = s[SEGMENT_ODOM + 1] + noisy_trans * math.sin(heading)
    s[ODOM + 2] = _remainder(heading + noisy_rot2, TWO_PI)
    turned = abs(_remainder(yaw - start_yaw, TWO_PI))
    if trans >= p[SEGMENT_DISTANCE] or turned >= p[SEGMENT_ANGLE]:
        s[SEGMENT_TRUE : SEGMENT_TRUE + 3] = s[X : YAW + 1]
        s[SEGMENT_ODOM : SEGMENT_ODOM + 3] = s[ODOM : ODOM + 3]
        s[NORMALS : NORMALS + 3] = odometry_rng.standard_normal(3)


@jit
def _relative(s, origin, at):
    """``kinematics.relative(s[origin:origin + 3], s[at:at + 3])``."""
    dx, dy = s[at] - s[origin], s[at + 1] - s[origin + 1]
    cos_yaw, sin_yaw = math.cos(s[origin + 2]), math.sin(s[origin + 2])
    return (
        dx * cos_yaw + dy * sin_yaw,
        -dx * sin_yaw + dy * cos_yaw,
        _remainder(s[at + 2] - s[origin + 2], TWO_PI),
    )


@jit
def _estimate(s):
    """``Localiser.estimate``: the last update's estimate carried by the odometry since."""
    forward, left, turn = _relative(s, ODOM_AT_UPDATE, ODOM)
    x, y, yaw = s[ESTIMATE_AT_UPDATE], s[ESTIMATE_AT_UPDATE + 1], s[ESTIMATE_AT_UPDATE + 2]
    cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
    return (
        x + forward * cos_yaw - left * sin_yaw,
        y + forward * sin_yaw + left * cos_yaw,
        _remainder(yaw + turn, TWO_PI),
    )


# --- the laser and the filter ------------------------------------------------------------------


@jit
def _cast(p, free_samples, row_stride, steps, x, y, yaw, bearings):
    """``RayCaster.cast`` from a free start (the robot's always is): ``RayCaster._trace``."""
    scale, res, range_max = 4, p[CASTER_RES], p[RANGE_MAX]
    origin_x, origin_y = p[CASTER_X], p[CASTER_Y]
    start_col = ((x - origin_x) / res + 1.0) * scale
    start_row = ((y - origin_y) / res + 1.0) * scale
    ranges = np.empty(bearings.size)
    for beam in range(bearings.size):
        angle = yaw + bearings[beam]
        cos_b, sin_b = math.cos(angle), math.sin(angle)
        cos_s, sin_s = cos_b * scale, sin_b * scale
        k, hit, col, row = 0, False, 0, 0
        while k < steps.size:
            col = int(start_col + cos_s * steps[k])
            row = int(start_row + sin_s * steps[k])
            free_after = free_samples[row * row_stride + col]
            if free_after == 0:
                hit = True
                break
            k += free_after
        if not hit:
            ranges[beam] = np.inf
            continue
        left = origin_x + (col // scale - 1) * res
        bottom = origin_y + (row // scale - 1) * res
        t_x = min((left - x) / cos_b, (left + res - x) / cos_b) if cos_b != 0.0 else -np.inf
        t_y = min((bottom - y) / sin_b, (bottom + res - y) / sin_b) if sin_b != 0.0 else -np.inf
        entry = max(t_x, t_y, 0.0)
        ranges[beam] = entry if entry <= range_max else np.inf
    return ranges


@jit
def _predict(s, p, particles, filter_rng):
    """``ParticleFilter.predict`` with the odometry's motion since the last update."""
    at = ODOM_AT_UPDATE
    rot1, trans, rot2 = _decompose(s[at], s[at + 1], s[at + 2], s[ODOM], s[ODOM + 1], s[ODOM + 2])
    std1, std_trans, std2 = _stddevs(rot1, trans, rot2, p, FILTER_ALPHAS)
    normals = filter_rng.standard_normal(particles.shape)
    for i in range(particles.shape[0]):
        heading = particles[i, 2] + (rot1 - normals[i, 0] * std1)
        moved = trans - normals[i, 1] * std_trans
        particles[i, 0] = particles[i, 0] + moved * np.cos(heading)
        particles[i, 1] = particles[i, 1] + moved * np.sin(heading)
        particles[i, 2] = _wrap_array_value(heading + (rot2 - normals[i, 2] * std2))


@jit
def _correct(p, score, particles, weights, ranges, bearings, cos_yaw, sin_yaw):
    """``ParticleFilter.correct``: AMCL's likelihood field for every beam and particle (the
    particles' headings as ``cos_yaw``, ``sin_yaw``). ``score`` is the field as (a uint16
    index per cell, the distinct scores): a quarter of the float64 table, so it stays in
    cache, and exactly the same numbers."""
    cell_score, scores = score
    range_max, inverse = p[RANGE_MAX], p[FIELD_INVERSE_RES]
    beam_x = np.empty(ranges.size)
    beam_y = np.empty(ranges.size)
    beams = 0
    for k in range(ranges.size):
        if np.isfinite(ranges[k]) and ranges[k] < range_max:
            length = ranges[k] * inverse
            beam_x[beams] = length * np.cos(bearings[k])
            beam_y[beams] = length * np.sin(bearings[k])
            beams += 1
    if beams == 0:
        return
    height, width = cell_score.shape
    flat = cell_score.ravel()
    beam_scores = np.empty(beams)
    for i in range(particles.shape[0]):
        col = (particles[i, 0] - p[FIELD_X]) * inverse + 1.0
        row = (particles[i, 1] - p[FIELD_Y]) * inverse + 1.0
        cos_i, sin_i = cos_yaw[i], sin_yaw[i]
        for k in range(beams):
            end_col = (cos_i * beam_x[k] - sin_i * beam_y[k]) + col
            end_row = (cos_i * beam_y[k] + sin_i * beam_x[k]) + row
            cell_col = int(min(max(end_col, 0.0), width - 1))
            cell_row = int(min(max(end_row, 0.0), height - 1))
            beam_scores[k] = scores[flat[cell_row * width + cell_col]]
        weights[i] = weights[i] * (1.0 + _pairwise_sum(beam_scores, beams))
    total = _pairwise_sum(weights, weights.size)
    for i in range(weights.size):
        weights[i] = weights[i] / total


@jit
def _filter_estimate(s, covariance, particles, weights, cos_yaw, sin_yaw):
    """``covariance_from_spread``: the weighted mean (circular for yaw) and spread."""
    x_mean = y_mean = heading_x = heading_y = 0.0
    for i in range(weights.size):
        x_mean += weights[i] * particles[i, 0]
        y_mean += weights[i] * particles[i, 1]
        heading_x += weights[i] * cos_yaw[i]
        heading_y += weights[i] * sin_yaw[i]
    yaw_mean = math.atan2(heading_y, heading_x)
    covariance[:, :] = 0.0
    deviation = np.empty(3)
    for i in range(weights.size):
        deviation[0] = particles[i, 0] - x_mean
        deviation[1] = particles[i, 1] - y_mean
        deviation[2] = _wrap_array_value(particles[i, 2] - yaw_mean)
        for a in range(3):
            for b in range(3):
                covariance[a, b] += deviation[a] * weights[i] * deviation[b]
    s[ESTIMATE_AT_UPDATE], s[ESTIMATE_AT_UPDATE + 1], s[ESTIMATE_AT_UPDATE + 2] = (
        x_mean,
        y_mean,
        yaw_mean,
    )


@jit
def _resample(particles, weights, filter_rng):
    """``ParticleFilter.resample``: systematic, one uniform draw."""
    count = weights.size
    offset = filter_rng.random()
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0
    source = particles.copy()
    j = 0
    for i in range(count):
        pointer = (offset + i) / count
        while cumulative[j] < pointer:  # searchsorted, side 'left'
            j += 1
        particles[i, :] = source[j, :]
    weights[:] = 1.0 / count


@jit
def _update_localisation(s, p, arrays, covariance, particles, weights, rngs):
    """``Simulator._update_localisation`` and ``Localiser.update``."""
    free_samples, row_stride, steps, bearings, score = arrays
    _, filter_rng, scan_rng = rngs
    ranges = _cast(p, free_samples, row_stride, steps, s[X], s[Y], s[YAW], bearings)
    noisy = ranges + scan_rng.normal(0.0, p[NOISE_STD], ranges.size)
    for k in range(ranges.size):
        value = max(noisy[k], p[RANGE_MIN])
        ranges[k] = value if np.isfinite(ranges[k]) and value < p[RANGE_MAX] else np.inf
    _predict(s, p, particles, filter_rng)
    cos_yaw, sin_yaw = np.cos(particles[:, 2]), np.sin(particles[:, 2])
    _correct(p, score, particles, weights, ranges, bearings, cos_yaw, sin_yaw)
    _filter_estimate(s, covariance, particles, weights, cos_yaw, sin_yaw)
    s[UPDATES] += 1.0
    if int(s[UPDATES]) % int(p[RESAMPLE_INTERVAL]) == 0:
        _resample(particles, weights, filter_rng)
    s[ODOM_AT_UPDATE : ODOM_AT_UPDATE + 3] = s[ODOM : ODOM + 3]


# --- the closed loop -------------------------------------------------------------------------


@jit
def _step(s, p, footprint, arrays, covariance, particles, weights, rngs, linear, angular, timed):
    """``Simulator.step`` and ``_MoveRun._step``: BUMPED, TIMED_OUT or FINISHED (go on)."""
    blocked, lower_bound = footprint
    bumped = _physics_step(s, p, blocked, lower_bound, linear, angular)
    s[SIM_STEPS] += 1.0
    s[BUMPS] += bumped
    _odometry_update(s, p, rngs[0])
    forward, left, turn = _relative(s, ODOM_AT_UPDATE, ODOM)
    if math.hypot(forward, left) >= p[UPDATE_MIN_D] or abs(turn) >= p[UPDATE_MIN_A]:
        _update_localisation(s, p, arrays, covariance, particles, weights, rngs)
    s[RUN_STEPS] += 1.0
    if bumped:
        return BUMPED
    if timed and int(s[SIM_STEPS]) * p[DT] - p[START_TIME] > p[TIME_LIMIT]:
        return TIMED_OUT
    return FINISHED


@jit
def _approach_speed(p, distance, max_speed, max_accel):
    decel = p[BRAKING_SHARE] * max_accel
    dt = p[DT]
    return min(decel * (math.sqrt(dt * dt + 2.0 * distance / decel) - dt), max_speed)


@jit
def _turn_rate(p, error):
    rate = _approach_speed(p, abs(error), p[MAX_ANGULAR], p[ANGULAR_ACCEL])
    return math.copysign(rate, error)


@jit
def run_move(max_steps, s, p, footprint, arrays, covariance, particles, weights, rngs):
    """``_MoveRun.move`` from the phase in ``s[PHASE]`` on: the outcome when the move has
    ended, else PAUSED right after the step a hook needs: the ``max_steps``-th, or one whose
    simulated time is >= ``s[STOP_TIME]``, or after which the filter's update count differs
    from ``s[STOP_UPDATES]`` (unless that is -1)."""
    heading = s[HEADING]
    while True:
        phase = int(s[PHASE])
        if phase == ENDED:
            return int(s[OUTCOME])
        if phase == LOCALISE:  # Simulator.localise_now
            if (
                s[ODOM] != s[ODOM_AT_UPDATE]
                or s[ODOM + 1] != s[ODOM_AT_UPDATE + 1]
                or s[ODOM + 2] != s[ODOM_AT_UPDATE + 2]
            ):
                _update_localisation(s, p, arrays, covariance, particles, weights, rngs)
            s[PHASE] = ENDED
            continue
        linear = angular = 0.0
        if phase == TURN:
            error = _remainder(heading - _estimate(s)[2], TWO_PI)
            if abs(error) <= p[HEADING_TOLERANCE]:
                s[PHASE] = TURN_BRAKE
                continue
            angular = _turn_rate(p, error)
        elif phase == DRIVE:
            x, y, yaw = _estimate(s)
            dx, dy = s[TARGET_X] - x, s[TARGET_Y] - y
            remaining = dx * math.cos(heading) + dy * math.sin(heading)
            if remaining <= p[POSITION_TOLERANCE]:
                s[PHASE] = END_BRAKE
                continue
            aim = math.atan2(dy, dx) if math.hypot(dx, dy) > p[AIM_DISTANCE] else heading
            error = _remainder(aim - yaw, TWO_PI)
            linear = _approach_speed(p, remaining, p[MAX_LINEAR], p[LINEAR_ACCEL])
            linear *= max(0.0, math.cos(error))
            angular = _turn_rate(p, error)
        elif abs(s[LINEAR]) <= p[STOPPED_SPEED] and abs(s[ANGULAR]) <= p[STOPPED_SPEED]:
            if phase == END_BRAKE or s[DISTANCE] <= 0.0:
                s[PHASE] = END_BRAKE if phase == TURN_BRAKE else LOCALISE
                continue
            if not s[HAS_TARGET]:
                x, y, _ = _estimate(s)
                s[TARGET_X] = x + s[DISTANCE] * math.cos(heading)
                s[TARGET_Y] = y + s[DISTANCE] * math.sin(heading)
            s[PHASE] = DRIVE
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
            phase != END_BRAKE,
        )
        if outcome == BUMPED:
            s[OUTCOME], s[PHASE] = BUMPED, LOCALISE
        elif outcome == TIMED_OUT:
            s[OUTCOME], s[PHASE] = TIMED_OUT, END_BRAKE
        max_steps -= 1
        if (
            max_steps == 0
            or s[SIM_STEPS] * p[DT] >= s[STOP_TIME]
            or (s[STOP_UPDATES] >= 0.0 and s[UPDATES] != s[STOP_UPDATES])
        ):
            return PAUSED


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


def cast(caster, x: float, y: float, yaw: float, bearings: np.ndarray) -> np.ndarray:
    """``caster.cast`` (a ``RayCaster``) on the kernel: the same ranges (noise-free, m; +inf =
    no return). The kernel traces from a free start, as the robot's always is; from anywhere
    else (only a caller's pose could be) the caster's own march runs."""
    if not caster._starts_free(x, y):
        return caster.cast(x, y, yaw, bearings)
    arrays = getattr(caster, '_compiled_arrays', None)
    if arrays is None:
        params = np.zeros(PARAMS_SIZE)
        params[[CASTER_RES, CASTER_X, CASTER_Y, RANGE_MAX]] = (
            caster.resolution,
            caster.origin_x,
            caster.origin_y,
            caster.range_max,
        )
        arrays = caster._compiled_arrays = (
            params,
            np.frombuffer(caster._free_samples, dtype=np.uint8),
            caster.blocked.shape[1] * 4,
            np.asarray(caster._steps, dtype=np.float64),
        )
    bearings = np.ascontiguousarray(bearings, dtype=np.float64)
    return _cast(*arrays, float(x), float(y), float(yaw), bearings)


def import_problem() -> str | None:
    """Why the kernels cannot run at all (numba missing), or None."""
    return _IMPORT_PROBLEM


def problem(sim) -> str | None:
    """Why the kernels cannot run this simulator, or None when they can (found once)."""
    if _IMPORT_PROBLEM is not None:
        return _IMPORT_PROBLEM
    found = getattr(sim, '_compiled_problem', False)
    if found is False:
        found = None
        if np.unique(sim.localiser.filter.field.score).size > 1 << 16:
            found = 'the likelihood field has more than 65536 distinct scores (a uint16 index)'
        sim._compiled_problem = found
    return found


def _parameters(sim, controller, start_time: float, time_limit: float) -> np.ndarray:
    config, limits, localiser = sim.config, sim.config.limits, sim.localiser
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
        self.params = _parameters(sim, controller, self.start_time, self.time_limit)
        self.footprint, self.arrays = _static_arrays(sim)
        self.rngs = (sim.odometry.rng, sim.localiser.filter.rng, sim._filter_scan_rng)
        self._load()

    @property
    def steps(self) -> int:
        return int(self.state[RUN_STEPS])

    def _load(self) -> None:
        sim, state = self.sim, np.empty(STATE_SIZE)
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
        self.state = state
        self.covariance = np.array(localiser.covariance, dtype=np.float64)
        self.particles = np.array(localiser.filter.particles, dtype=np.float64, order='C')
        self.weights = np.array(localiser.filter.weights, dtype=np.float64)

    def _store(self) -> None:
        from stealth_sim.kinematics import Pose, RobotState

        sim, s = self.sim, self.state.tolist()
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
        localiser.covariance = self.covariance.copy()
        localiser.filter.particles = self.particles.copy()
        localiser.filter.weights = self.weights.copy()

    def move(self, heading: float, distance: float, target):
        """``_MoveRun.move``: the whole move in one kernel call, plus one per step hook call."""
        state = self.state
        state[PHASE], state[OUTCOME], state[HEADING], state[DISTANCE] = TURN, 0, heading, distance
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
            outcome = run_move(1 << 62, *arguments)
        else:
            while True:
                every_step = True
                if self.step_stops is not None:
                    stops = self.step_stops()
                    state[STOP_TIME], state[STOP_UPDATES] = stops.time, stops.updates
                    every_step = stops.every_step
                outcome = run_move(1 if every_step else 1 << 62, *arguments)
                if outcome != PAUSED:
                    break
                self._store()
                self.on_step(self.sim)
        self._store()
        return int(outcome)  # an ExecuteMove outcome number (move_executor.Outcome)
