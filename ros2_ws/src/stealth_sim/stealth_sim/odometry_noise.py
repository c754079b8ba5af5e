"""Odometry error as AMCL's diff-drive motion model describes it.

nav2_amcl's ``DifferentialMotionModel`` (sample_motion_model_odometry, Probabilistic Robotics
p. 136) splits a motion into a first rotation ``rot1``, a translation ``trans`` and a second
rotation ``rot2`` and perturbs each with zero-mean Gaussian noise whose variance grows with the
motion:

* ``var(rot1) = alpha1 rot1^2 + alpha2 trans^2``
* ``var(trans) = alpha3 trans^2 + alpha4 rot1^2 + alpha4 rot2^2``
* ``var(rot2) = alpha1 rot2^2 + alpha2 trans^2``

where the rotations in the variances are taken modulo pi (backward motion is as noisy as forward
motion). A motion shorter than 1 cm has no meaningful bearing, so AMCL counts all of its turn as
``rot2``; here that rule shapes the variances only, while the motion itself keeps its exact
geometry (AMCL moves such a motion along the heading instead, which would make even noise-free
odometry wrong by up to a centimetre per update). The same functions perturb the simulated
odometry and, vectorised, the particles of the filter.
"""

import dataclasses
import math
from typing import NamedTuple

import numpy as np
from stealth_core.kinematics import TWO_PI, Pose, is_finite_number, wrap_angle

# AMCL's threshold below which a motion has no meaningful bearing (m).
MIN_BEARING_TRANSLATION = 0.01


@dataclasses.dataclass(frozen=True)
class MotionNoise:
    """The four alphas of AMCL's diff-drive model.

    alpha1: rotation noise from rotation (rad^2/rad^2); alpha2: rotation noise from translation
    (rad^2/m^2); alpha3: translation noise from translation (m^2/m^2); alpha4: translation noise
    from rotation (m^2/rad^2). All >= 0.
    """

    # Defaults: turns in place slip (10 % standard deviation of the rotation), straight driving
    # much less (4.5 % of the distance), crosstalk small.
    alpha1: float = 0.01
    alpha2: float = 0.001
    alpha3: float = 0.002
    alpha4: float = 0.001

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if not (is_finite_number(value) and value >= 0):
                raise ValueError(f'{field.name}: expected a finite number >= 0, got {value!r}')


class MotionDelta(NamedTuple):
    """A motion as AMCL decomposes it: turn ``rot1`` (rad), drive ``trans`` (m), turn ``rot2``."""

    rot1: float
    trans: float
    rot2: float


def decompose(start: Pose, end: Pose) -> MotionDelta:
    """The exact (rot1, trans, rot2) of the motion from ``start`` to ``end``."""
    dx, dy = end.x - start.x, end.y - start.y
    trans = math.hypot(dx, dy)
    rot1 = math.remainder(math.atan2(dy, dx) - start.yaw, TWO_PI) if trans > 0.0 else 0.0
    rot2 = math.remainder(end.yaw - start.yaw - rot1, TWO_PI)
    return MotionDelta(rot1, trans, rot2)


def _rotation_for_noise(rotation: float) -> float:
    """A rotation's size modulo pi: driving backwards is as noisy as driving forwards."""
    return abs(math.remainder(rotation, math.pi))


def noise_stddevs(delta: MotionDelta, noise: MotionNoise) -> tuple[float, float, float]:
    """Standard deviations of the rot1, trans and rot2 errors for one motion (AMCL's rule)."""
    if delta.trans < MIN_BEARING_TRANSLATION:
        rot1, rot2 = 0.0, _rotation_for_noise(delta.rot1 + delta.rot2)
    else:
        rot1, rot2 = _rotation_for_noise(delta.rot1), _rotation_for_noise(delta.rot2)
    trans_sq = delta.trans * delta.trans
    return (
        math.sqrt(noise.alpha1 * rot1 * rot1 + noise.alpha2 * trans_sq),
        math.sqrt(noise.alpha3 * trans_sq + noise.alpha4 * (rot1 * rot1 + rot2 * rot2)),
        math.sqrt(noise.alpha1 * rot2 * rot2 + noise.alpha2 * trans_sq),
    )


def apply_noisy_motion(x, y, yaw, delta: MotionDelta, stddevs, normals):
    """Poses after ``delta`` perturbed by ``stddevs`` times standard ``normals``.

    ``x``, ``y``, ``yaw`` are floats or arrays of N poses; ``normals`` has shape (3,) or (N, 3).
    One pose takes plain ``math`` (numpy's per-call overhead would dominate).
    """
    if not isinstance(x, np.ndarray):
        rot1 = delta.rot1 - stddevs[0] * normals[0]
        trans = delta.trans - stddevs[1] * normals[1]
        heading = yaw + rot1
        rot2 = delta.rot2 - stddevs[2] * normals[2]
        return (
            x + trans * math.cos(heading),
            y + trans * math.sin(heading),
            math.remainder(heading + rot2, TWO_PI),
        )
    noisy = np.subtract(delta, normals * np.asarray(stddevs))  # rot1, trans, rot2 per pose
    heading = yaw + noisy[..., 0]
    trans = noisy[..., 1]
    return (
        x + trans * np.cos(heading),
        y + trans * np.sin(heading),
        wrap_angle(heading + noisy[..., 2]),
    )


class NoisyOdometry:
    """Wheel odometry whose error follows AMCL's model, segment by segment.

    The model defines noise per motion update, with a variance growing as the square of the
    motion, so its size depends on how motion is cut into updates. The odometry cuts it where
    AMCL's filter does, whenever the true motion since the last cut exceeds
    ``segment_distance`` or ``segment_angle`` (nav2's update_min_d and update_min_a): one segment
    then carries exactly the error the model assumes, whatever the physics step. The segment's
    three standard normals are drawn when it begins and applied to the motion so far, so the
    odometry moves continuously instead of jumping at the cuts.
    """

    def __init__(
        self,
        noise: MotionNoise,
        rng: np.random.Generator,
        segment_distance: float = 0.25,
        segment_angle: float = 0.2,
    ):
        self.noise = noise
        self.rng = rng
        self.segment_distance = segment_distance
        self.segment_angle = segment_angle
        self.reset(Pose(0.0, 0.0, 0.0))

    def reset(self, pose: Pose) -> None:
        """Restart at ``pose`` (the true pose and the odometry coincide)."""
        self.pose = pose
        self._segment_true_start = pose
        self._segment_odom_start = pose
        self._normals = self.rng.standard_normal(3).tolist()

    def update(self, true_pose: Pose) -> Pose:
        """The odometry after the robot has moved to ``true_pose``."""
        start = self._segment_true_start
        if true_pose == start:  # standing still: no motion, no error
            self.pose = self._segment_odom_start
            return self.pose
        delta = decompose(start, true_pose)
        odom_start = self._segment_odom_start
        x, y, yaw = apply_noisy_motion(
            odom_start.x,
            odom_start.y,
            odom_start.yaw,
            delta,
            noise_stddevs(delta, self.noise),
            self._normals,
        )
        self.pose = Pose(x, y, yaw)
        turned = abs(math.remainder(true_pose.yaw - start.yaw, TWO_PI))
        if delta.trans >= self.segment_distance or turned >= self.segment_angle:
            self._segment_true_start = true_pose
            self._segment_odom_start = self.pose
            self._normals = self.rng.standard_normal(3).tolist()
        return self.pose
