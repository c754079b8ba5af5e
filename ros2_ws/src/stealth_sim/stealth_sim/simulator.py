"""The simulated robot: kinematics, noisy odometry, a laser and a localisation estimate, composed.

:class:`Simulator` is what the node and any in-process user drive: ``step`` advances simulated
time by one physics step under a velocity command; ``reset`` teleports the robot; the properties
give the ground truth, the odometry and the estimate. The localisation sees only what AMCL would:
the odometry and laser scans taken at the true pose.

Randomness comes from independent streams spawned from one seed (odometry error, the filter, the
filter's scans, the published scans), so publishing scans or idling never changes what a seeded
run of moves does.
"""

import dataclasses
import math

import cv2
import numpy as np
from stealth_core import jit
from stealth_core.kinematics import (
    DiscFootprint,
    Limits,
    Pose,
    RobotState,
    require_finite,
    step_robot,
    wrap_angle,
)
from stealth_core.occupancy_map import OccupancyMap

from stealth_sim import compiled_move
from stealth_sim.kernels import laser as laser_kernel
from stealth_sim.laser import LaserConfig, RayCaster, noisy_ranges
from stealth_sim.localisation import (
    FilterConfig,
    LikelihoodField,
    Localiser,
    ParticleFilter,
    validate_covariance,
)
from stealth_sim.odometry_noise import MotionNoise, NoisyOdometry


@dataclasses.dataclass(frozen=True)
class SimConfig:
    """Everything that shapes a simulation. Units: s, m, rad."""

    physics_dt: float = 0.02
    limits: Limits = Limits()
    robot_radius: float = 0.2
    odometry_noise: MotionNoise = MotionNoise()
    laser: LaserConfig = LaserConfig()
    filter: FilterConfig = FilterConfig()
    # Spread of the localisation around a reset pose when the caller gives none (m, m, rad).
    initial_std: tuple[float, float, float] = (0.1, 0.1, 0.05)
    seed: int = 0

    def __post_init__(self):
        require_finite(physics_dt=self.physics_dt)
        if not 0 < self.physics_dt <= 1.0:
            raise ValueError(f'physics_dt: expected a number in (0, 1] (s), got {self.physics_dt}')

    @property
    def default_covariance(self) -> np.ndarray:
        return np.diag(np.square(self.initial_std))


def most_open_pose(occupancy_map: OccupancyMap) -> Pose:
    """The centre of the free cell farthest from any blocked cell, heading 0: a start that
    always fits."""
    free = np.pad(~occupancy_map.blocked, 1, constant_values=False).astype(np.uint8)
    distance = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
    row, col = np.unravel_index(np.argmax(distance), distance.shape)
    x, y = occupancy_map.cell_to_world(col, row)
    return Pose(x, y, 0.0)


class Simulator:
    """One robot on one map, advanced in fixed physics steps of simulated time."""

    def __init__(
        self, occupancy_map: OccupancyMap, config: SimConfig, pose: Pose, reference: bool = False
    ):
        # reference: moves step by step through step(), as before the fast path (the baseline
        # it is proven and measured against).
        self.reference = reference
        self.map = occupancy_map
        self.config = config
        self.footprint = DiscFootprint(occupancy_map, config.robot_radius)
        self.caster = RayCaster(occupancy_map, config.laser.range_max)
        streams = [np.random.default_rng(s) for s in np.random.SeedSequence(config.seed).spawn(4)]
        odometry_rng, filter_rng, self._filter_scan_rng, self._published_scan_rng = streams
        self.odometry = NoisyOdometry(
            config.odometry_noise,
            odometry_rng,
            config.filter.update_min_d,
            config.filter.update_min_a,
        )
        field = LikelihoodField(occupancy_map, config.filter.likelihood, config.laser.range_max)
        self.localiser = Localiser(
            ParticleFilter(field, config.filter, config.odometry_noise, filter_rng)
        )
        # AMCL's beam subsampling: max_beams evenly spread over the scan, ends included.
        beams, max_beams = config.laser.beams, config.filter.likelihood.max_beams
        step = max(1, (beams - 1) // max(1, max_beams - 1))
        self.filter_beam_bearings = config.laser.bearings(np.arange(0, beams, step))
        self._scan_bearings = (None, None)  # the laser config and its bearings, for scan()
        self.time = 0.0
        self.steps = 0
        self.bumps = 0
        self.state = RobotState(Pose(0.0, 0.0, 0.0))
        self.reset(pose)

    # --- validation --------------------------------------------------------------------------

    def pose_problem(self, pose: Pose) -> str | None:
        """Why the robot cannot be put at ``pose``, or None when it can."""
        try:
            require_finite(x=pose.x, y=pose.y, yaw=pose.yaw)
        except ValueError as exc:
            return str(exc)
        if not self.map.contains_point(pose.x, pose.y):
            x0, y0, x1, y1 = self.map.bounds
            return (
                f'pose ({pose.x:.3f}, {pose.y:.3f}) is outside the map '
                f'[{x0:.2f}, {x1:.2f}] x [{y0:.2f}, {y1:.2f}] m'
            )
        if not self.footprint.fits(pose.x, pose.y):
            return (
                f'pose ({pose.x:.3f}, {pose.y:.3f}) is inside a wall or unknown space: the '
                f'robot (radius {self.config.robot_radius:g} m) does not fit there'
            )
        return None

    # --- control -----------------------------------------------------------------------------

    def reset(self, pose: Pose, covariance=None) -> None:
        """Teleport the robot to ``pose`` at rest, restart odometry there, re-localise around it.

        Raises ValueError (and changes nothing) for a pose outside the map or in a wall, or an
        invalid covariance.
        """
        problem = self.pose_problem(pose)
        if problem:
            raise ValueError(problem)
        pose = Pose(float(pose.x), float(pose.y), float(wrap_angle(pose.yaw)))
        covariance = self._covariance_or_default(covariance)
        self.state = RobotState(pose)
        self.odometry.reset(pose)
        self.localiser.initialise(pose, covariance, pose)

    def set_initial_estimate(self, pose: Pose, covariance) -> None:
        """Re-initialise localisation only (an /initialpose): the robot stays where it is."""
        require_finite(x=pose.x, y=pose.y, yaw=pose.yaw)
        covariance = self._covariance_or_default(covariance)
        self.localiser.initialise(pose, covariance, self.odometry.pose)

    def _covariance_or_default(self, covariance) -> np.ndarray:
        if covariance is None or not np.any(np.asarray(covariance, dtype=float)):
            return self.config.default_covariance
        return validate_covariance(covariance)

    def step(self, linear: float, angular: float) -> bool:
        """Advance one physics step under the command (m/s, rad/s); True when the robot bumped.

        Raises ValueError (and changes nothing) for a non-finite command.
        """
        return self._step(linear, angular, self._update_localisation)

    def step_run(self, linear: float, angular: float, count: int) -> int:
        """Up to ``count`` steps under one command (m/s, rad/s), ending after a step that
        updated the filter (a caller that publishes the estimate sees every update): the steps
        taken (``bumps`` counts the bumps). ``step`` that many times, with the filter updated
        on the compiled kernel unless the simulator is the reference or the kernel cannot run
        it (the same update within 1e-9, ``test_fast_paths``): a robot driven over cmd_vel
        steps every physics step from Python, where each update cost ~1 ms in numpy.
        """
        if count < 1:
            raise ValueError(f'count: expected >= 1, got {count}')
        localise = self._update_localisation
        if not self.reference and compiled_move.problem(self) is None:
            localise = self._update_localisation_compiled
        for taken in range(1, count + 1):
            updates = self.localisation_updates
            self._step(linear, angular, localise)
            if self.localisation_updates != updates:
                return taken
        return count

    def _step(self, linear: float, angular: float, localise) -> bool:
        require_finite(linear_velocity=linear, angular_velocity=angular)
        config = self.config
        self.state, bumped = step_robot(
            self.state, linear, angular, config.limits, config.physics_dt, self.footprint
        )
        self.steps += 1
        self.time = self.steps * config.physics_dt
        self.bumps += bumped
        odom_pose = self.odometry.update(self.state.pose)
        if self.localiser.moved_enough(odom_pose):
            localise(odom_pose)
        return bumped

    def stand_still(self, steps: int) -> None:
        """Let ``steps`` physics steps pass on a robot at rest with no command: only the clock
        moves. Exactly what as many ``step(0, 0)`` would do, without their cost: at rest the
        pose stays, odometry draws no noise for no motion and the filter sees no movement.

        Raises ValueError for a robot that is moving (brake it with ``step`` first).
        """
        if self.state.linear != 0.0 or self.state.angular != 0.0:
            raise ValueError('the robot is moving: step it to rest before standing still')
        if steps < 0:
            raise ValueError(f'steps: expected >= 0, got {steps}')
        self.steps += steps
        self.time = self.steps * self.config.physics_dt

    def localise_now(self) -> bool:
        """A filter update now, if the odometry moved since the last (AMCL's forced update)."""
        odom_pose = self.odometry.pose
        if not self.localiser.has_moved(odom_pose):
            return False
        self._update_localisation(odom_pose)
        return True

    def _update_localisation(self, odom_pose: Pose) -> None:
        ranges = noisy_ranges(
            self.caster.cast(*self.state.pose, self.filter_beam_bearings),
            self.config.laser,
            self._filter_scan_rng,
        )
        self.localiser.update(odom_pose, ranges, self.filter_beam_bearings)

    def _update_localisation_compiled(self, odom_pose: Pose) -> None:
        """``_update_localisation`` on the kernel (it reads the odometry from ``self``)."""
        compiled_move.update_localisation(self)

    def reconfigure(self, config: SimConfig) -> None:
        """Take the limits, odometry noise and laser noise of ``config``; the rest is fixed."""
        fixed = ('physics_dt', 'robot_radius', 'filter', 'initial_std', 'seed')
        changed = [name for name in fixed if getattr(config, name) != getattr(self.config, name)]
        laser_layout = dataclasses.replace(config.laser, noise_std=self.config.laser.noise_std)
        if laser_layout != self.config.laser:
            changed.append('laser')
        if changed:
            raise ValueError(f'cannot change {", ".join(changed)} of a running simulator')
        self.config = config
        self.odometry.noise = config.odometry_noise
        self.localiser.filter.motion_noise = config.odometry_noise

    # --- observation -------------------------------------------------------------------------

    @property
    def ground_truth(self) -> Pose:
        return self.state.pose

    @property
    def odometry_pose(self) -> Pose:
        return self.odometry.pose

    @property
    def estimate(self) -> Pose:
        """The localisation estimate now (the last filter update carried by the odometry)."""
        return self.localiser.estimate(self.odometry.pose)

    @property
    def estimate_covariance(self) -> np.ndarray:
        """3x3 covariance of (x, y, yaw) of the last filter update (m^2, m rad, rad^2)."""
        return self.localiser.covariance

    @property
    def localisation_updates(self) -> int:
        return self.localiser.updates

    def scan(self) -> np.ndarray:
        """A full noisy laser scan at the true pose (m; +inf = no return), for publishing.

        Cast by the compiled kernel unless the simulator is the reference or numba is
        missing: the same ranges (``test_fast_paths``), and 180 beams cost ~1.5 ms in numpy,
        a third of a training move's simulator time when the scan is recorded.
        """
        laser = self.config.laser
        if self._scan_bearings[0] is not laser:  # reconfigure() replaces it
            self._scan_bearings = (laser, laser.bearings())
        bearings = self._scan_bearings[1]
        x, y, yaw = self.state.pose
        if not self.reference and jit.import_problem() is None:
            ranges = laser_kernel.cast(self.caster, x, y, yaw, bearings)
        else:
            ranges = self.caster.cast(x, y, yaw, bearings)
        return noisy_ranges(ranges, self.config.laser, self._published_scan_rng)

    @property
    def max_move_distance(self) -> float:
        """No single move may be longer than the map's diagonal."""
        x0, y0, x1, y1 = self.map.bounds
        return math.hypot(x1 - x0, y1 - y0)
