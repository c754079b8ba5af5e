"""The fast path of a move: the closed loop of ``move_executor`` in plain local floats.

Same controller, physics, odometry and filter schedule as the reference (``_MoveRun`` driving
``Simulator.step``), the same floating-point operations in the same order, so the same
trajectory bit for bit (test_fast_move proves it). What it saves is per-step Python: the
reference builds ~10 tuples and makes ~30 calls a step (velocity limits, integration, two cell
lookups into a numpy array, odometry decomposition and noise, two relative poses for the update
check and the estimate); here a step is inline arithmetic on locals, the estimate's and the
update check's trigonometry is computed once per filter update, and the simulator's objects
(state, odometry, counters) are written back only when someone looks: at a filter update, a
step hook that is due, and the end of each phase.

Why not numpy batches of steps: a move is cut into pieces by events that depend on the state
(a filter update every 0.25 m or 0.2 rad, an odometry noise segment as often, the controller
leaving its acceleration limit, a bump), about one every three physics steps at the training
settings; a batch of three steps costs more numpy calls than the scalar steps it replaces.
"""

from array import array
import math

from stealth_sim.kinematics import TWO_PI, Pose, RobotState
from stealth_sim.odometry_noise import MIN_BEARING_TRANSLATION

_SINC_SERIES = 1e-4  # kinematics.integrate's switch to the series form of sinc


class FastMoveRun:
    """One move in progress; the interface of ``move_executor._MoveRun``."""

    def __init__(self, sim, controller, on_step, nominal_duration, on_step_due=None):
        from stealth_sim.move_executor import Outcome  # it imports this module

        self.bumped, self.timed_out = Outcome.BUMPED, Outcome.TIMED_OUT
        self.sim = sim
        self.controller = controller
        self.on_step = on_step
        self.on_step_due = on_step_due
        self.start_time = sim.time
        self.steps = 0
        self.time_limit = (
            controller.time_limit_factor * nominal_duration + controller.time_limit_margin
        )
        config = sim.config
        limits = config.limits
        self.dt = config.physics_dt
        self.max_linear, self.max_angular = limits.max_linear_speed, limits.max_angular_speed
        self.linear_step = limits.max_linear_accel * self.dt
        self.angular_step = limits.max_angular_accel * self.dt
        self.linear_decel = controller.braking_share * limits.max_linear_accel
        self.angular_decel = controller.braking_share * limits.max_angular_accel
        footprint = sim.footprint
        self.footprint = footprint
        self.lower_bound = _flat_lower_bound(footprint)
        self.rows, self.cols = footprint.blocked.shape
        noise = sim.odometry.noise
        self.alphas = (noise.alpha1, noise.alpha2, noise.alpha3, noise.alpha4)
        self._load()

    # --- the simulator's state in locals, and back ----------------------------------------------

    def _load(self) -> None:
        sim = self.sim
        pose, self.linear, self.angular = sim.state
        self.x, self.y, self.yaw = pose
        self.sim_steps, self.bumps = sim.steps, sim.bumps
        odometry = sim.odometry
        self.segment_true = tuple(odometry._segment_true_start)
        self.segment_odom = tuple(odometry._segment_odom_start)
        self.normals = odometry._normals
        self.odom = tuple(odometry.pose)
        self._load_filter_anchor()

    def _load_filter_anchor(self) -> None:
        """The last filter update's odometry and estimate, with the sines both transforms use."""
        localiser = self.sim.localiser
        self.anchor_odom = tuple(localiser._odom_at_update)
        self.anchor_estimate = tuple(localiser._estimate_at_update)
        self.anchor_cos, self.anchor_sin = (
            math.cos(self.anchor_odom[2]),
            math.sin(self.anchor_odom[2]),
        )
        self.estimate_cos, self.estimate_sin = (
            math.cos(self.anchor_estimate[2]),
            math.sin(self.anchor_estimate[2]),
        )

    def _store(self) -> None:
        sim = self.sim
        sim.state = RobotState(Pose(self.x, self.y, self.yaw), self.linear, self.angular)
        sim.steps, sim.bumps = self.sim_steps, self.bumps
        sim.time = self.sim_steps * self.dt
        odometry = sim.odometry
        odometry.pose = Pose(*self.odom)
        odometry._segment_true_start = Pose(*self.segment_true)
        odometry._segment_odom_start = Pose(*self.segment_odom)
        odometry._normals = self.normals

    # --- one physics step -------------------------------------------------------------------

    def _step(self, linear_command: float, angular_command: float, timed: bool = True):
        """``Simulator.step`` and ``_MoveRun._step`` in one: BUMPED, TIMED_OUT or None."""
        dt = self.dt
        target = min(max(linear_command, -self.max_linear), self.max_linear)
        change = min(max(target - self.linear, -self.linear_step), self.linear_step)
        linear = self.linear + change
        target = min(max(angular_command, -self.max_angular), self.max_angular)
        change = min(max(target - self.angular, -self.angular_step), self.angular_step)
        angular = self.angular + change
        # kinematics.integrate
        x0, y0, yaw0 = self.x, self.y, self.yaw
        half_turn = 0.5 * angular * dt
        if abs(half_turn) < _SINC_SERIES:
            sinc = 1.0 - half_turn * half_turn / 6.0
        else:
            sinc = math.sin(half_turn) / half_turn
        chord = linear * dt * sinc
        heading = yaw0 + half_turn
        x = x0 + chord * math.cos(heading)
        y = y0 + chord * math.sin(heading)
        yaw = math.remainder(yaw0 + angular * dt, TWO_PI)
        bumped = not self._sweep_is_free(x0, y0, x, y)
        if bumped:
            fraction = self.footprint.free_fraction(x0, y0, x, y)
            x, y = x0 + fraction * (x - x0), y0 + fraction * (y - y0)
            linear = angular = 0.0
            self.bumps += 1
        self.x, self.y, self.yaw, self.linear, self.angular = x, y, yaw, linear, angular
        self.sim_steps += 1
        time = self.sim_steps * dt
        self._odometry_update(x, y, yaw)
        forward, left, turn = self._since_anchor()
        config = self.sim.localiser.config
        updated = math.hypot(forward, left) >= config.update_min_d or (
            abs(turn) >= config.update_min_a
        )
        if updated:
            self._store()
            self.sim._update_localisation(Pose(*self.odom))
            self._load_filter_anchor()
        self.steps += 1
        if self.on_step is not None and (
            self.on_step_due is None or self.on_step_due(time, self.sim.localiser.updates)
        ):
            if not updated:
                self._store()
            self.on_step(self.sim)
        if bumped:
            return self.bumped
        if timed and time - self.start_time > self.time_limit:
            return self.timed_out
        return None

    def _sweep_is_free(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """``DiscFootprint.sweep_is_free``: the clearance bound inline, the exact test rare."""
        footprint = self.footprint
        resolution = footprint.resolution
        col = math.floor((x0 - footprint.origin_x) / resolution)
        row = math.floor((y0 - footprint.origin_y) / resolution)
        if 0 <= row < self.rows and 0 <= col < self.cols:
            end_col = math.floor((x1 - footprint.origin_x) / resolution)
            end_row = math.floor((y1 - footprint.origin_y) / resolution)
            if 0 <= end_row < self.rows and 0 <= end_col < self.cols:
                length = math.hypot(x1 - x0, y1 - y0)
                if self.lower_bound[row * self.cols + col] - length >= footprint.radius:
                    return True
        return footprint.sweep_is_free(x0, y0, x1, y1)

    def _odometry_update(self, x: float, y: float, yaw: float) -> None:
        """``NoisyOdometry.update`` with ``decompose``, ``noise_stddevs`` and the scalar
        ``apply_noisy_motion`` inline."""
        start_x, start_y, start_yaw = self.segment_true
        if x == start_x and y == start_y and yaw == start_yaw:
            self.odom = self.segment_odom
            return
        dx, dy = x - start_x, y - start_y
        trans = math.hypot(dx, dy)
        rot1 = math.remainder(math.atan2(dy, dx) - start_yaw, TWO_PI) if trans > 0.0 else 0.0
        rot2 = math.remainder(yaw - start_yaw - rot1, TWO_PI)
        if trans < MIN_BEARING_TRANSLATION:
            noise_rot1, noise_rot2 = 0.0, abs(math.remainder(rot1 + rot2, math.pi))
        else:
            noise_rot1 = abs(math.remainder(rot1, math.pi))
            noise_rot2 = abs(math.remainder(rot2, math.pi))
        alpha1, alpha2, alpha3, alpha4 = self.alphas
        trans_sq = trans * trans
        normals = self.normals
        odom_x, odom_y, odom_yaw = self.segment_odom
        noisy_rot1 = (
            rot1 - math.sqrt(alpha1 * noise_rot1 * noise_rot1 + alpha2 * trans_sq) * (normals[0])
        )
        noisy_trans = (
            trans
            - math.sqrt(
                alpha3 * trans_sq + alpha4 * (noise_rot1 * noise_rot1 + noise_rot2 * noise_rot2)
            )
            * (normals[1])
        )
        heading = odom_yaw + noisy_rot1
        noisy_rot2 = (
            rot2 - math.sqrt(alpha1 * noise_rot2 * noise_rot2 + alpha2 * trans_sq) * (normals[2])
        )
        self.odom = (
            odom_x + noisy_trans * math.cos(heading),
            odom_y + noisy_trans * math.sin(heading),
            math.remainder(heading + noisy_rot2, TWO_PI),
        )
        odometry = self.sim.odometry
        turned = abs(math.remainder(yaw - start_yaw, TWO_PI))
        if trans >= odometry.segment_distance or turned >= odometry.segment_angle:
            self.segment_true = (x, y, yaw)
            self.segment_odom = self.odom
            self.normals = odometry.rng.standard_normal(3).tolist()

    def _since_anchor(self) -> tuple[float, float, float]:
        """``relative(odometry at the last update, odometry now)``."""
        odom_x, odom_y, odom_yaw = self.odom
        anchor_x, anchor_y, anchor_yaw = self.anchor_odom
        dx, dy = odom_x - anchor_x, odom_y - anchor_y
        cos_yaw, sin_yaw = self.anchor_cos, self.anchor_sin
        return (
            dx * cos_yaw + dy * sin_yaw,
            -dx * sin_yaw + dy * cos_yaw,
            math.remainder(odom_yaw - anchor_yaw, TWO_PI),
        )

    def _estimate(self) -> tuple[float, float, float]:
        """``Localiser.estimate``: the last update's estimate carried by the odometry since."""
        forward, left, turn = self._since_anchor()
        x, y, yaw = self.anchor_estimate
        cos_yaw, sin_yaw = self.estimate_cos, self.estimate_sin
        return (
            x + forward * cos_yaw - left * sin_yaw,
            y + forward * sin_yaw + left * cos_yaw,
            math.remainder(yaw + turn, TWO_PI),
        )

    # --- the controller (move_executor._MoveRun's, on the locals) -----------------------------

    def _approach_speed(self, distance: float, max_speed: float, decel: float) -> float:
        dt = self.dt
        speed = decel * (math.sqrt(dt * dt + 2.0 * distance / decel) - dt)
        return min(speed, max_speed)

    def _turn_rate(self, error: float) -> float:
        rate = self._approach_speed(abs(error), self.max_angular, self.angular_decel)
        return math.copysign(rate, error)

    def _finish(self, outcome):
        self._store()
        return outcome

    def turn_to(self, heading: float):
        tolerance = self.controller.heading_tolerance
        while True:
            error = math.remainder(heading - self._estimate()[2], TWO_PI)
            if abs(error) <= tolerance:
                return self.brake()
            outcome = self._step(0.0, self._turn_rate(error))
            if outcome is not None:
                return self._finish(outcome)

    def drive_to(self, target: tuple[float, float], heading: float):
        controller = self.controller
        direction = (math.cos(heading), math.sin(heading))
        while True:
            x, y, yaw = self._estimate()
            dx, dy = target[0] - x, target[1] - y
            remaining = dx * direction[0] + dy * direction[1]
            if remaining <= controller.position_tolerance:
                return self._finish(None)
            aim = math.atan2(dy, dx) if math.hypot(dx, dy) > controller.aim_distance else heading
            error = math.remainder(aim - yaw, TWO_PI)
            speed = self._approach_speed(remaining, self.max_linear, self.linear_decel)
            speed *= max(0.0, math.cos(error))
            outcome = self._step(speed, self._turn_rate(error))
            if outcome is not None:
                return self._finish(outcome)

    def brake(self, timed: bool = True):
        stopped = self.controller.stopped_speed
        while abs(self.linear) > stopped or abs(self.angular) > stopped:
            outcome = self._step(0.0, 0.0, timed)
            if outcome is not None:
                return self._finish(outcome)
        return self._finish(None)


def _flat_lower_bound(footprint) -> array:
    """The footprint's clearance bound as a flat array of Python floats (a fast scalar read),
    built once per footprint."""
    cached = getattr(footprint, '_flat_lower_bound', None)
    if cached is None:
        cached = array('d', footprint.lower_bound.ravel().tobytes())
        footprint._flat_lower_bound = cached
    return cached
