"""AMCL's odometry noise as kernels: ``NoisyOdometry.update`` on the move's state, and the
rot1-trans-rot2 motion model (``odometry_noise.decompose``, ``noise_stddevs``) that the
particle filter's predict shares."""

import math

from stealth_core.jit import jit

from stealth_sim.kernels.layout import (
    NORMALS,
    ODOM,
    ODOM_ALPHAS,
    SEGMENT_ANGLE,
    SEGMENT_DISTANCE,
    SEGMENT_ODOM,
    SEGMENT_TRUE,
    YAW,
    X,
    Y,
)
from stealth_sim.kernels.numeric import TWO_PI, remainder
from stealth_sim.odometry_noise import MIN_BEARING_TRANSLATION


@jit
def decompose(x0, y0, yaw0, x1, y1, yaw1):
    """``odometry_noise.decompose``: (rot1, trans, rot2)."""
    dx, dy = x1 - x0, y1 - y0
    trans = math.hypot(dx, dy)
    rot1 = remainder(math.atan2(dy, dx) - yaw0, TWO_PI) if trans > 0.0 else 0.0
    rot2 = remainder(yaw1 - yaw0 - rot1, TWO_PI)
    return rot1, trans, rot2


@jit
def stddevs(rot1, trans, rot2, p, alphas):
    """``odometry_noise.noise_stddevs`` with the alphas at ``p[alphas:alphas + 4]``."""
    if trans < MIN_BEARING_TRANSLATION:
        noise_rot1, noise_rot2 = 0.0, abs(remainder(rot1 + rot2, math.pi))
    else:
        noise_rot1, noise_rot2 = abs(remainder(rot1, math.pi)), abs(remainder(rot2, math.pi))
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
def odometry_update(s, p, odometry_rng):
    """``NoisyOdometry.update`` at the true pose."""
    x, y, yaw = s[X], s[Y], s[YAW]
    start_x, start_y, start_yaw = s[SEGMENT_TRUE], s[SEGMENT_TRUE + 1], s[SEGMENT_TRUE + 2]
    if x == start_x and y == start_y and yaw == start_yaw:
        s[ODOM : ODOM + 3] = s[SEGMENT_ODOM : SEGMENT_ODOM + 3]
        return
    rot1, trans, rot2 = decompose(start_x, start_y, start_yaw, x, y, yaw)
    std1, std_trans, std2 = stddevs(rot1, trans, rot2, p, ODOM_ALPHAS)
    noisy_rot1 = rot1 - std1 * s[NORMALS]
    noisy_trans = trans - std_trans * s[NORMALS + 1]
    heading = s[SEGMENT_ODOM + 2] + noisy_rot1
    noisy_rot2 = rot2 - std2 * s[NORMALS + 2]
    s[ODOM] = s[SEGMENT_ODOM] + noisy_trans * math.cos(heading)
    s[ODOM + 1] = s[SEGMENT_ODOM + 1] + noisy_trans * math.sin(heading)
    s[ODOM + 2] = remainder(heading + noisy_rot2, TWO_PI)
    turned = abs(remainder(yaw - start_yaw, TWO_PI))
    if trans >= p[SEGMENT_DISTANCE] or turned >= p[SEGMENT_ANGLE]:
        s[SEGMENT_TRUE : SEGMENT_TRUE + 3] = s[X : YAW + 1]
        s[SEGMENT_ODOM : SEGMENT_ODOM + 3] = s[ODOM : ODOM + 3]
        s[NORMALS : NORMALS + 3] = odometry_rng.standard_normal(3)


@jit
def relative(s, origin, at):
    """``kinematics.relative(s[origin:origin + 3], s[at:at + 3])``."""
    dx, dy = s[at] - s[origin], s[at + 1] - s[origin + 1]
    cos_yaw, sin_yaw = math.cos(s[origin + 2]), math.sin(s[origin + 2])
    return (
        dx * cos_yaw + dy * sin_yaw,
        -dx * sin_yaw + dy * cos_yaw,
        remainder(s[at + 2] - s[origin + 2], TWO_PI),
    )
