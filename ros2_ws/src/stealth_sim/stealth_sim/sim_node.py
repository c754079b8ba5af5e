"""The simulator node (``simulator``): a thin ROS 2 shell around :class:`Simulator`.

It stands in for Stage and AMCL. Everything it simulates is in the plain-Python core
(simulator, kinematics, odometry_noise, laser, localisation, move_executor, idle_time); its
messages are built in sim_messages; this node decides when to send them.

## Topics

Frames ``map``, ``odom``, ``base_link``.

* ``map`` (nav_msgs/OccupancyGrid, reliable + transient local), from the ``map`` YAML;
* ``odom`` (nav_msgs/Odometry: the noisy odometry pose, odom -> base_link), ``ground_truth``
  (nav_msgs/Odometry: the exact pose, map -> base_link); both carry the true body velocities;
* ``scan`` (sensor_msgs/LaserScan, base_link: the laser sits at the robot's centre), ``clock``;
* ``amcl_pose`` (geometry_msgs/PoseWithCovarianceStamped, map; reliable + transient local, as
  nav2's AMCL) after every filter update, and always at the end of a move or reset;
* ``/tf`` (tf2_msgs/TFMessage, reliable, volatile, depth 100, as tf2_ros's
  TransformBroadcaster): ``map -> odom`` (the localisation's correction, estimate *
  odometry^-1, as AMCL publishes it) and ``odom -> base_link`` (the odometry), stamped with the
  simulated time, with ``odom`` and only when someone subscribes (math in
  :mod:`stealth_core.frames`). No ``/tf_static``: there is no fixed frame, the laser sits at
  base_link's origin and its scans are in base_link;
* subscribes ``cmd_vel`` (geometry_msgs/Twist; a command older than ``cmd_vel_timeout`` of
  simulated time is dropped, so teleop tools that publish on key presses work) and
  ``initialpose`` (re-initialises localisation, as AMCL does; an all-zero covariance means the
  default spread).

## Services

``sim/execute_move`` (stealth_interfaces/ExecuteMove) and ``sim/reset``
(stealth_interfaces/ResetRobot) run the motion interface (names from
``stealth_node_kit.rl_contract``); a node of the same process (``stealth_bringup sim_env``)
calls them directly.

## Parameters

The table in ``stealth_sim.sim_parameters`` (``map`` and ``initial_pose`` at start-up only; the
rest may change while running, checked by the same ``sim_config`` that builds the simulator).

## Time

Time is simulated, published on ``clock`` with the periodic topics (to nodes under
``use_sim_time``; a new subscriber gets the current time at once, even while it stands still).
Under ``use_sim_time`` the node's own ROS clock takes its ``/clock`` at the idle tick
(``stealth_node_kit.on_demand``): nothing here reads it, and a wake-up (or a take) for it each
control period was a cost of its own; so were the QoS warnings' event handlers, also polled then.
A move over the service runs as fast as the CPU allows when ``real_time_factor`` is 0, or held
to that multiple of wall time. Between moves, with a factor > 0, simulated time flows at that
multiple of wall time. With the factor 0 it stands still until a ``cmd_vel`` comes, so training
over the service wastes no CPU and a seeded run of moves is the same whatever the load: no
physics step, random draw or clock tick ever happens because wall time passed
(:mod:`stealth_sim.idle_time`). Under ``cmd_vel`` it then runs as fast as its subscribers keep
up, in lockstep with the controller (:mod:`stealth_sim.lockstep`): the simulator steps one
control period (``1 / publish_rate`` of simulated time), publishes odometry, scan and clock, and
steps the next period as soon as the command answering that odometry arrives, or after one
period of wall time without an answer (a teleop tool or a silent subscriber: real time, never
stalled; a controller that answered the last period is given a second, ``lockstep.PATIENCE``);
once the command is older than ``cmd_vel_timeout`` and the robot is
at rest, time stands still again. The periodic topics go out at ``publish_rate`` Hz of simulated
time, and only when someone subscribes: publishing every physics step would slow training down;
they draw their scan noise from a stream of their own.
"""

import ctypes
import ctypes.util
import math
import time

from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
from nav_msgs.msg import OccupancyGrid, Odometry
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import LaserScan
from stealth_core.frames import (
    MAP_FRAME,
    ODOM_FRAME,
    robot_transforms,
)
from stealth_core.kinematics import Pose
from stealth_core.moves import MoveOutcome, MoveRequest
from stealth_core.occupancy_map import MapError, OccupancyMap, load_map
from stealth_interfaces.srv import ExecuteMove, ResetRobot
from stealth_node_kit import rl_contract
from stealth_node_kit.conversions import quaternion_yaw, time_msg
from stealth_node_kit.endpoints import QUIET_PUBLISHER, warn_publisher, warn_subscription
from stealth_node_kit.in_process import InProcessServices
from stealth_node_kit.on_demand import OnDemand, clock_on_demand, events_on_demand
from stealth_node_kit.parameters import StartupError, declare_parameters
from stealth_node_kit.qos import kept_qos
from stealth_node_kit.running import StartupNode, run_node
from tf2_msgs.msg import TFMessage

from stealth_sim.idle_time import RealTimePacer, idle_tick
from stealth_sim.lockstep import Lockstep
from stealth_sim.move_executor import StepStops, execute_move, warm_up
from stealth_sim.sim_messages import (
    StateMessages,
    occupancy_grid,
    planar_covariance,
    pose_msg,
    pose_with_covariance,
)
from stealth_sim.sim_parameters import PARAMETERS, START_UP, sim_config
from stealth_sim.simulator import Simulator, most_open_pose


class SimulatorNode(StartupNode):
    """Parameters, topics, services and simulated time around one :class:`Simulator`.

    `services`: where its two services are also offered to nodes of this process (the
    environment composed with it calls them directly); by default to none.
    """

    def __init__(self, services: InProcessServices | None = None, **kwargs):
        self._in_process = services if services is not None else InProcessServices()
        super().__init__('simulator', **kwargs)

    def set_up(self) -> None:
        values = declare_parameters(self, PARAMETERS)
        self.map = self._load_map(values['map'])
        try:
            config = sim_config(values)
        except ValueError as exc:
            raise StartupError(f'invalid parameter: {exc}') from None
        initial_pose = values['initial_pose']
        if initial_pose is not None and len(initial_pose) != 3:
            raise StartupError(f'parameter initial_pose: expected [x, y, yaw], got {initial_pose}')
        start = Pose(*initial_pose) if initial_pose is not None else most_open_pose(self.map)
        try:
            self.sim = Simulator(self.map, config, start)
        except ValueError as exc:
            raise StartupError(f'parameter initial_pose: {exc}') from None
        self._messages = StateMessages(config.laser)  # the laser's layout cannot change
        self.real_time_factor = values['real_time_factor']
        self.cmd_vel_timeout = values['cmd_vel_timeout']
        self.publish_period = 1.0 / values['publish_rate']
        self.idle_period = values['idle_period']
        self._command: tuple[float, float] | None = None
        self._command_time = 0.0
        self._held = True  # left in place by a move or reset: time stands still (idle_time)
        self._next_publish = 0.0
        self._published_updates = self.sim.localisation_updates
        self._estimate_due = False  # an estimate nobody subscribed to yet (latched: sent later)
        self._pacer = RealTimePacer(self.sim.time)
        self._lockstep = Lockstep(self.publish_period)  # factor 0 under cmd_vel
        self._clock_readers = 0  # /clock subscribers when it was last published
        # Under use_sim_time the node hears its own /clock: taken at the idle tick, not on a
        # wake-up of its own every control period.
        self._on_demand = OnDemand()
        clock_on_demand(self, self._on_demand)

        latched = kept_qos(1)
        # rclpy gives every endpoint default QoS event handlers, each an entity the executor
        # waits on: ~19 here, a third of this node's time per move (measured). The volatile
        # reliable publishers match what readers ask by default, so they go without; the latched
        # ones and the subscriptions keep one warning that explains a topic that stays silent.
        self.map_pub = self.create_publisher(
            OccupancyGrid, 'map', latched, event_callbacks=self._warned_publisher('map')
        )
        self.pose_pub = self.create_publisher(
            PoseWithCovarianceStamped,
            'amcl_pose',
            latched,
            event_callbacks=self._warned_publisher('amcl_pose'),
        )
        quiet = QUIET_PUBLISHER
        self.odom_pub = self.create_publisher(Odometry, 'odom', 10, event_callbacks=quiet)
        self.truth_pub = self.create_publisher(Odometry, 'ground_truth', 10, event_callbacks=quiet)
        self.scan_pub = self.create_publisher(LaserScan, 'scan', 5, event_callbacks=quiet)
        self.clock_pub = self.create_publisher(ClockMsg, 'clock', 10, event_callbacks=quiet)
        # tf2_ros's TransformBroadcaster: absolute /tf, reliable, volatile, depth 100.
        tf_qos = QoSProfile(
            depth=100,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.VOLATILE,
        )
        self.tf_pub = self.create_publisher(TFMessage, '/tf', tf_qos, event_callbacks=quiet)
        self._periodic = (
            self.clock_pub,
            self.odom_pub,
            self.truth_pub,
            self.scan_pub,
            self.tf_pub,
        )
        self.create_subscription(
            Twist,
            'cmd_vel',
            self._on_cmd_vel,
            10,
            event_callbacks=self._warned_subscription('cmd_vel'),
        )
        self.create_subscription(
            PoseWithCovarianceStamped,
            'initialpose',
            self._on_initial_pose,
            10,
            event_callbacks=self._warned_subscription('initialpose'),
        )
        # Before the services: the first move must not wait for numba's compile (or cache load).
        seconds = warm_up()
        if seconds is not None:
            self.get_logger().info(f'compiled move kernels ready in {seconds:.1f} s')
        self._in_process.serve(self, ExecuteMove, rl_contract.EXECUTE_MOVE, self._on_execute_move)
        self._in_process.serve(self, ResetRobot, rl_contract.RESET_ROBOT, self._on_reset)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(self.idle_period, self._on_idle_tick, clock=steady)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        events_on_demand(self, self._on_demand)  # QoS warnings: polled by the idle tick

        grid = occupancy_grid(self.map)
        grid.header.stamp = grid.info.map_load_time = time_msg(self.sim.time)
        self.map_pub.publish(grid)
        self._publish_state(everything=True)
        self.get_logger().info(
            f'{values["map"]}: {self.map.width} x {self.map.height} cells of '
            f'{self.map.resolution:g} m; robot at ({start.x:.2f}, {start.y:.2f}, '
            f'{start.yaw:.2f}); real-time factor {self.real_time_factor:g}'
        )

    # --- parameters --------------------------------------------------------------------------

    def _warned_publisher(self, topic: str):
        text = f'a subscription to {topic} has QoS incompatible with the simulator ({{policy}}): '
        return warn_publisher(self.get_logger, text + 'it gets nothing')

    def _warned_subscription(self, topic: str):
        text = f'a publisher of {topic} has QoS incompatible with the simulator ({{policy}}): '
        return warn_subscription(self.get_logger, text + 'it is not heard')

    def _load_map(self, path: str) -> OccupancyMap:
        if not path:
            raise StartupError('parameter map: required, the path to a nav2 map YAML')
        try:
            return load_map(path)
        except MapError as exc:
            raise StartupError(str(exc)) from None

    def _parameter_values(self, changes: list[Parameter]) -> dict:
        """The tunable parameters' values with ``changes`` applied (the start-up-only ones,
        read-only and possibly unset, are left out)."""
        values = {
            name: self.get_parameter(name).value for name in PARAMETERS if name not in START_UP
        }
        values.update({p.name: p.value for p in changes if p.name not in START_UP})
        return values

    def _validate_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """rclpy checks types, ranges and read-only; this checks what the core refuses."""
        try:
            sim_config(self._parameter_values(changes))
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, changes: list[Parameter]) -> None:
        values = self._parameter_values(changes)
        self.sim.reconfigure(sim_config(values))
        self.real_time_factor = values['real_time_factor']
        self.cmd_vel_timeout = values['cmd_vel_timeout']
        self.publish_period = 1.0 / values['publish_rate']
        self._pacer.anchor(self.sim.time)
        self._lockstep.max_wait = self.publish_period
        self._lockstep.restart()

    # --- time --------------------------------------------------------------------------------

    def _publish_due(self) -> None:
        if self.sim.time >= self._next_publish - 1e-9:
            self._publish_state()
        if self.sim.localisation_updates != self._published_updates:
            self._publish_estimate(only_if_subscribed=True)

    def _move_step(self, sim: Simulator) -> None:
        """After a physics step of a move: publish what is due, keep the real-time factor."""
        self._publish_due()
        self._pacer.wait(sim.time, self.real_time_factor)

    def _move_stops(self) -> StepStops:
        """The steps of a move that need :meth:`_move_step`: a periodic publication or a new
        amcl_pose is due for a subscriber, or the real-time factor paces every step. Training
        (factor 0, nobody listening) so needs none, and a move is one kernel call; a
        subscriber that appears mid-move is served from the move's next hook call or its end."""
        periodic = any(p.get_subscription_count() for p in self._periodic)
        return StepStops(
            self._next_publish - 1e-9 if periodic else math.inf,
            self._published_updates if self.pose_pub.get_subscription_count() else -1,
            self.real_time_factor > 0.0,
        )

    def _fresh_command(self) -> tuple[float, float] | None:
        if self._command is not None and self.sim.time - self._command_time > self.cmd_vel_timeout:
            self._command = None
        return self._command

    def _on_idle_tick(self) -> None:
        """Between moves: simulated time runs at the real-time factor, or in lockstep with
        /cmd_vel at factor 0, and stands still in training (see stealth_sim.idle_time: never on
        wall time alone)."""
        self._on_demand.drain()  # its own /clock, for its ROS clock
        self._on_demand.poll_events()
        if self._estimate_due and self.pose_pub.get_subscription_count():
            self._publish_estimate()
        if self.clock_pub.get_subscription_count() != self._clock_readers:
            self._publish_clock()  # a new node on simulated time learns it, standing still or not
        tick = idle_tick(
            self.sim.time,
            self._pacer.due(self.real_time_factor),
            real_time_factor=self.real_time_factor,
            commanded=self._fresh_command() is not None,
            moving=self.sim.state.linear != 0.0 or self.sim.state.angular != 0.0,
            held=self._held,
            idle_period=self.idle_period,
        )
        if tick.anchor:
            self._pacer.anchor(self.sim.time)
        if tick.lockstep:
            if self._lockstep.waited_out(time.monotonic()):
                self._next_period()
            return
        if self.real_time_factor == 0.0:
            self._lockstep.restart()  # time stands still: the next command goes at once
        self._step_until(tick.until)

    def _step_until(self, until: float) -> None:
        """Physics steps under the latest fresh command up to simulated time ``until``, in
        runs (``Simulator.step_run``) that end where something is due to publish."""
        sim = self.sim
        while sim.time + sim.config.physics_dt <= until + 1e-9:
            command = self._fresh_command()
            bumps = sim.bumps
            sim.step_run(*(command or (0.0, 0.0)), self._steps_alike(command, until))
            if sim.bumps != bumps:
                self.get_logger().info('bumped into a wall', throttle_duration_sec=1.0)
            self._publish_due()

    def _steps_alike(self, command: tuple[float, float] | None, until: float) -> int:
        """How many physics steps from now (at least one) take ``command`` (None: stale) as
        :meth:`_fresh_command` would, end by ``until`` and pass no periodic publication."""
        dt, steps = self.sim.config.physics_dt, self.sim.steps
        count = 1
        while True:
            after = (steps + count) * dt  # as Simulator.time after ``count`` steps
            if after + dt > until + 1e-9 or after >= self._next_publish - 1e-9:
                return count
            if command is not None and after - self._command_time > self.cmd_vel_timeout:
                return count
            count += 1

    def _next_period(self) -> None:
        """Lockstep: one control period, up to and including its publication, whose answer
        is then awaited."""
        self._step_until(max(self._next_publish, self.sim.time + self.sim.config.physics_dt))
        self._lockstep.sent(time.monotonic())

    # --- subscriptions -----------------------------------------------------------------------

    def _on_cmd_vel(self, message: Twist) -> None:
        linear, angular = message.linear.x, message.angular.z
        if not (math.isfinite(linear) and math.isfinite(angular)):
            self.get_logger().warning(
                f'cmd_vel rejected: linear.x {linear} and angular.z {angular} must be finite; '
                'the robot keeps its previous command',
                throttle_duration_sec=1.0,
            )
            return
        self._command = (linear, angular)
        self._command_time = self.sim.time
        self._held = False
        if self.real_time_factor == 0.0 and self._lockstep.command():
            self._next_period()  # the answer to the latest odometry: on to the next period

    def _on_initial_pose(self, message: PoseWithCovarianceStamped) -> None:
        if message.header.frame_id not in ('', MAP_FRAME):
            self.get_logger().warning(
                f"initialpose ignored: frame '{message.header.frame_id}', expected '{MAP_FRAME}'"
            )
            return
        pose = message.pose.pose
        estimate = Pose(pose.position.x, pose.position.y, quaternion_yaw(pose.orientation))
        try:
            self.sim.set_initial_estimate(estimate, planar_covariance(message.pose.covariance))
        except ValueError as exc:
            self.get_logger().warning(f'initialpose ignored: {exc}')
            return
        self.get_logger().info(
            f'initial pose set to ({estimate.x:.2f}, {estimate.y:.2f}, {estimate.yaw:.2f})'
        )
        # The new estimate now, as AMCL publishes it; odometry, scan and /tf keep their period.
        # An odometry more (it once went out too) was a control period more to a controller in
        # lockstep: its second answer was taken as the next period's, and every command after
        # acted a period late (a drive home's first turn swung across its heading).
        self._publish_estimate(only_if_subscribed=True)

    # --- services ----------------------------------------------------------------------------

    def _on_execute_move(self, request, response):
        move = MoveRequest(
            request.kind, request.distance, request.heading, request.x, request.y, request.seconds
        )
        self._command = None  # a move takes over the robot
        self._pacer.anchor(self.sim.time)
        result = execute_move(self.sim, move, on_step=self._move_step, step_stops=self._move_stops)
        self._command = None
        self._held = True
        self._pacer.anchor(self.sim.time)
        self._lockstep.restart()
        if result.outcome == MoveOutcome.REJECTED:
            self.get_logger().warning(f'move rejected: {result.message}')
        else:
            self._publish_state(everything=True)
        response.outcome = int(result.outcome)
        response.message = result.message
        response.estimate = pose_with_covariance(self.sim.estimate, self.sim.estimate_covariance)
        response.true_pose = pose_msg(self.sim.ground_truth)
        response.duration = result.duration
        response.stamp = time_msg(self.sim.time)
        return response

    def _on_reset(self, request, response):
        pose = Pose(request.x, request.y, request.yaw)
        covariance = np.asarray(request.covariance, dtype=float).reshape(3, 3)
        try:
            self.sim.reset(pose, covariance)
        except ValueError as exc:
            self.get_logger().warning(f'reset rejected: {exc}')
            response.success, response.message = False, str(exc)
            return response
        self._command = None
        self._held = True
        self._pacer.anchor(self.sim.time)
        self._lockstep.restart()
        self._publish_state(everything=True)
        response.success, response.message = True, ''
        return response

    # --- publishing --------------------------------------------------------------------------

    def _publish_state(self, everything: bool = False) -> None:
        """Odometry, ground truth, scan, clock and /tf to whoever subscribes; with ``everything``
        also the estimate, which is latched for late subscribers."""
        sim, messages = self.sim, self._messages
        self._next_publish = sim.time + self.publish_period
        if not everything and not any(p.get_subscription_count() for p in self._periodic):
            return  # the usual case in training: nobody listens, so build nothing
        stamp = time_msg(sim.time)
        self._publish_clock()
        for publisher, frame, pose in (
            (self.odom_pub, ODOM_FRAME, sim.odometry_pose),
            (self.truth_pub, MAP_FRAME, sim.ground_truth),
        ):
            if publisher.get_subscription_count():
                publisher.publish(messages.odometry_of(sim, frame, pose, stamp))
        if self.scan_pub.get_subscription_count():
            self.scan_pub.publish(messages.scan_of(sim, stamp, self.publish_period))
        if self.tf_pub.get_subscription_count():
            tree = robot_transforms(sim.estimate, sim.odometry_pose)
            self.tf_pub.publish(messages.transforms_of(tree, stamp))
        if everything:
            self._publish_estimate(only_if_subscribed=True)

    def _publish_clock(self) -> None:
        self._clock_readers = self.clock_pub.get_subscription_count()
        if self._clock_readers:
            self.clock_pub.publish(self._messages.clock_at(self.sim.time))

    def _publish_estimate(self, only_if_subscribed: bool = False) -> None:
        """amcl_pose; `only_if_subscribed`: with no subscriber it stays due, and the idle tick
        sends it to the first one (latched, so a late subscriber still gets the latest estimate,
        while training without one builds no message per move)."""
        if only_if_subscribed and not self.pose_pub.get_subscription_count():
            self._estimate_due = True
            return
        self._estimate_due = False
        self._published_updates = self.sim.localisation_updates
        self.pose_pub.publish(self._messages.estimate_of(self.sim))


def keep_freed_memory_for_reuse() -> None:
    """Stop glibc from returning freed memory to the kernel after every large numpy temporary.

    Measured: in a process with a ROS node the filter's and the laser's arrays (a few hundred
    kB each) are mapped and unmapped on every update, page faults and all, which made a move
    twice as slow as in a plain process. Fixed thresholds (64 MB for mapping, 128 MB for
    trimming) keep them on the heap. No-op off glibc.
    """
    libc_name = ctypes.util.find_library('c')
    mallopt = getattr(ctypes.CDLL(libc_name), 'mallopt', None) if libc_name else None
    if mallopt is not None:
        m_trim_threshold, m_mmap_threshold = -1, -3
        mallopt(m_mmap_threshold, 64 << 20)
        mallopt(m_trim_threshold, 128 << 20)


def main(args=None) -> int:
    keep_freed_memory_for_reuse()
    return run_node(SimulatorNode, 'simulator', args=args)


if __name__ == '__main__':
    raise SystemExit(main())
