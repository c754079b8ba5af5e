"""The particle filter's update as kernels: ``Simulator._update_localisation`` and
``Localiser.update`` (the noisy scan, ``ParticleFilter.predict``, the likelihood-field
``correct``, the estimate and its spread, systematic ``resample``), and ``Localiser.estimate``
between updates."""

import math

import numpy as np
from stealth_core.jit import jit

from stealth_sim.kernels.laser import cast_from_free
from stealth_sim.kernels.layout import (
    ESTIMATE_AT_UPDATE,
    FIELD_INVERSE_RES,
    FIELD_X,
    FIELD_Y,
    FILTER_ALPHAS,
    NOISE_STD,
    ODOM,
    ODOM_AT_UPDATE,
    RANGE_MAX,
    RANGE_MIN,
    RESAMPLE_INTERVAL,
    UPDATES,
    YAW,
    X,
    Y,
)
from stealth_sim.kernels.numeric import TWO_PI, pairwise_sum, remainder, wrap_array_value
from stealth_sim.kernels.odometry import decompose, relative, stddevs


@jit
def estimate(s):
    """``Localiser.estimate``: the last update's estimate carried by the odometry since."""
    forward, left, turn = relative(s, ODOM_AT_UPDATE, ODOM)
    x, y, yaw = s[ESTIMATE_AT_UPDATE], s[ESTIMATE_AT_UPDATE + 1], s[ESTIMATE_AT_UPDATE + 2]
    cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
    return (
        x + forward * cos_yaw - left * sin_yaw,
        y + forward * sin_yaw + left * cos_yaw,
        remainder(yaw + turn, TWO_PI),
    )


@jit
def _predict(s, p, particles, filter_rng):
    """``ParticleFilter.predict`` with the odometry's motion since the last update."""
    at = ODOM_AT_UPDATE
    rot1, trans, rot2 = decompose(s[at], s[at + 1], s[at + 2], s[ODOM], s[ODOM + 1], s[ODOM + 2])
    std1, std_trans, std2 = stddevs(rot1, trans, rot2, p, FILTER_ALPHAS)
    normals = filter_rng.standard_normal(particles.shape)
    for i in range(particles.shape[0]):
        heading = particles[i, 2] + (rot1 - normals[i, 0] * std1)
        moved = trans - normals[i, 1] * std_trans
        particles[i, 0] = particles[i, 0] + moved * np.cos(heading)
        particles[i, 1] = particles[i, 1] + moved * np.sin(heading)
        particles[i, 2] = wrap_array_value(heading + (rot2 - normals[i, 2] * std2))


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
        weights[i] = weights[i] * (1.0 + pairwise_sum(beam_scores, beams))
    total = pairwise_sum(weights, weights.size)
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
        deviation[2] = wrap_array_value(particles[i, 2] - yaw_mean)
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
def update_localisation(s, p, arrays, covariance, particles, weights, rngs):
    """``Simulator._update_localisation`` and ``Localiser.update``."""
    free_samples, row_stride, steps, bearings, score = arrays
    _, filter_rng, scan_rng = rngs
    ranges = cast_from_free(p, free_samples, row_stride, steps, s[X], s[Y], s[YAW], bearings)
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
