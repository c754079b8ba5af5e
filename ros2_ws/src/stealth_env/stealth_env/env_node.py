"""The environment node (``environment``): rl-texplore-ros-pkg's rl_env protocol over the
simulator, judged by the shared core (``StealthTask`` via ``EpisodeFlow``).

Topics (frame ``map``; RL topics reliable, volatile, KEEP_ALL: the protocol is lockstep and no
step may be dropped silently):

* publishes ``rl_env/rl_env_description`` (RLEnvDescription; reliable + transient local,
  depth 1) once; ``rl_env/rl_state_reward`` (RLStateReward) at every episode start and after
  every action; ``rl_env/step_info`` (StepInfo) after every action; ``rl_env/episode_summary``
  (EpisodeSummary) at every episode end; ``searchlights`` (SearchlightArray, transient local)
  and ``searchlight_markers`` (visualization_msgs/MarkerArray, transient local): the lights
  and the scene for RViz and Foxglove, and ``visibility_grid`` (nav_msgs/OccupancyGrid,
  transient local: the lit area as a costmap, 0-100 = total visibility as a percentage of the
  detection threshold), again every ``marker_period`` while lights move or when a new viewer
  subscribes; with ``publish_plan`` (on under ``stealth train --watch``), ``planned_path``
  (nav_msgs/Path, transient local): value iteration's optimum on the move lattice, once;
* subscribes ``rl_agent/rl_action`` (RLAction) and ``rl_agent/rl_experiment_info``
  (RLExperimentInfo);
* StepInfo is built only while someone subscribes (a recorder, a viewer), as the simulator
  does with its periodic topics;
* serves ``rl_env/restart_episode`` (RestartEpisode): a restarted simulator's or agent's episode
  ends ABORTED (stealth train's respawn); ``step_info`` and ``episode_summary`` are transient
  local with the last STEP_HISTORY and REPORT_HISTORY messages, for a reader that (re)joins
  late (a recorder, the orchestrator, an agent: DDS may match a restarted node's endpoints after
  the first ones);
* calls ``sim/execute_move`` and ``sim/reset`` (stealth_interfaces) of the simulator node
  (``robot_interface`` service; ``topics``: see below),
  asynchronously: no callback ever blocks the executor; reads the simulator's latched ``map``
  once to check it is the scenario's (an error line if not).

Episode flow: the description goes out at once; the first episode starts when both simulator
services answer and an agent is connected (its rl_state_reward reader matched, so the volatile
first state is not lost), after ``start_delay``. Each action is a move of the scenario's step
distance (``ExecuteMove.GO_TO`` the lattice node), a wait where lights move (``HOLD``), or a turn
in place where the scenario weighs lights by exposure (``TURN_TO_HEADING``); the new state is the
localisation estimate in the answer, rounded to the state grid (cells centred on the move lattice's
nodes); reward and terminal come from the core, judged on the true pose at the move's end time
(``judge_on: estimate`` for the original's estimate-only way). Goal, detection or the step limit
end an episode; the agent's RLExperimentInfo starts the next one. Actions that arrive out of turn
or out of range are dropped with a warning. A move the simulator rejects, fails or does not answer
within ``move_timeout`` ends the episode as ABORTED (a terminal state with reward 0 keeps the agent
in step), and so does a first state with no answer within ``first_action_timeout``. An agent that
goes away ends its episode as ABORTED, and the next agent to come gets a fresh one. Totals of
actions and states are logged at shutdown. The decisions are ``stealth_env.episode_flow``'s; the
marker geometry ``stealth_env.markers``'.

Robot interface (``robot_interface``, ``reset_mode``): ``service`` (the default) is the above.
``topics`` plugs into any ROS robot (Stage, Gazebo, a TurtleBot with nav2's AMCL; or
``stealth_sim`` over the same topics): a move is the same turn-then-drive with the same
tolerances and outcomes, executed closed-loop by ``stealth_env.topic_moves`` on every ``odom``
message: ``geometry_msgs/Twist`` on ``cmd_vel``, the pose from ``amcl_pose``
(PoseWithCovarianceStamped, frame ``map``) carried forward by ``odom``, BUMPED from ``scan``
(a wall within ``bump_distance`` ahead) or no progress for ``stall_time``, TIMED_OUT at the
service path's time limit, in the robot's clock (message stamps). Judging uses
``ground_truth`` (nav_msgs/Odometry, frame ``map``) when it is published, otherwise the
estimate (a warning once; StepInfo.true_pose is then NaN). ``reset_mode`` ``teleport`` calls
``reset_service`` (stealth_interfaces/ResetRobot, ``sim/reset``); ``drive`` drives back to the
start along a collision-free path on the move lattice (lights ignored), then publishes
``initialpose``. All topic names are relative and remappable. A robot that does not move on
``cmd_vel`` makes moves TIME OUT; after ``unresponsive_moves`` of them in a row the episode is
ABORTED and the node exits with code 3 and a line saying the robot is not responding. A robot
that stops publishing ``odom`` for ``move_timeout`` aborts the episode, as a simulator that does
not answer. An ``amcl_pose`` in another frame or any non-finite pose is dropped with a one-line
error naming the topic (throttled), and the move goes on with the next good message. The ROS
shell of this mode is ``stealth_env.topic_robot``.

Bad startup input (no or an unusable scenario, an unknown goal, a bad parameter value) stops
the node with one line saying which and why, and exit code 2.
"""

from __future__ import annotations

import array
from collections import Counter
import functools
import math
import time
from typing import Any, NamedTuple

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose2D, PoseStamped
from nav_msgs.msg import OccupancyGrid, Path
import numpy as np
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.qos import DurabilityPolicy
from rclpy.task import Future
from std_msgs.msg import ColorRGBA
from stealth_interfaces.msg import (
    EpisodeSummary,
    RLAction,
    RLEnvDescription,
    RLExperimentInfo,
    RLStateReward,
    Searchlight,
    SearchlightArray,
    StepInfo,
)
from stealth_interfaces.srv import ExecuteMove, ResetRobot, RestartEpisode
from stealth_node_kit import rl_contract
from stealth_node_kit.conversions import quaternion_yaw, seconds, time_msg, yaw_quaternion
from stealth_node_kit.endpoints import (
    QUIET_PUBLISHER,
    QUIET_SUBSCRIPTION,
    warn_publisher,
    warn_subscription,
)
from stealth_node_kit.in_process import InProcessClient, InProcessServices
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.qos import kept_qos
from stealth_node_kit.running import StartupNode, run_node
from visualization_msgs.msg import Marker, MarkerArray

from stealth_env.env_parameters import PARAMETERS
from stealth_env.episode_flow import (
    JUDGE_ON,
    Aborted,
    Endpoint,
    EpisodeFlow,
    Phase,
    PlanarPose,
    agent_connected,
    is_finite_pose,
)
from stealth_env.exposure import heading_angle
from stealth_env.log_throttle import Throttle
from stealth_env.markers import (
    WallMap,
    any_moving,
    scene_markers,
    searchlight_fields,
    visibility_levels,
)
from stealth_env.reward import Outcome
from stealth_env.scenario import ScenarioError, load_scenario
from stealth_env.task import WAIT, StealthTask
from stealth_env.topic_moves import (
    Limits,
    MoveGoal,
    Pose,
    TopicConfig,
    go_to,
    hold_goal,
    route_home,
)
from stealth_env.topic_robot import TOPICS as ROBOT_TOPICS
from stealth_env.topic_robot import MoveEnd, TopicRobot

NODE_NAME = 'environment'
MAP_FRAME = 'map'
TICK_PERIOD = 0.1  # s of wall time between housekeeping ticks (start, timeouts, agent presence)
RESET_RETRY = 1.0  # s of wall time before a failed reset is tried again
# s of wall time a teleport (sim/reset, answered in milliseconds) is waited for before it is sent
# again: just after the simulator restarts the request or its answer can be lost (DDS still
# matches the dead server's endpoints), and the run should not wait a whole move_timeout.
RESET_ANSWER_TIMEOUT = 5.0
SLOT_TOLERANCE = 1e-3  # s: a move ending this close to its step's slot end is not padded
WAITING_LOG_PERIOD = 10.0  # s of wall time between 'still waiting' lines
MOVE_NOTE_LOG_PERIOD = 5.0  # s of wall time between lines about bumped moves
RESET_FAILED_LOG_PERIOD = 10.0  # s of wall time between lines about failed resets
STOP_DELAY = 1.0  # s of wall time between giving up on the robot and exiting (messages go out)
EXIT_ROBOT_NOT_RESPONDING = 3
ROBOT_INTERFACES = ('service', 'topics')
RESET_MODES = ('teleport', 'drive')
CHOICES = {'judge_on': JUDGE_ON, 'robot_interface': ROBOT_INTERFACES, 'reset_mode': RESET_MODES}

LATCHED_QOS = kept_qos(1)
# The RL loop's names come from the contract (stealth_node_kit.rl_contract); the scene's are
# this node's own.
TOPICS = {
    'description': rl_contract.ENV_DESCRIPTION,
    'state': rl_contract.STATE,
    'step_info': rl_contract.STEP_INFO,
    'summary': rl_contract.EPISODE_SUMMARY,
    'action': rl_contract.ACTION,
    'experiment_info': rl_contract.EXPERIMENT_INFO,
    'restart': rl_contract.RESTART_EPISODE,
    'searchlights': 'searchlights',
    'markers': 'searchlight_markers',
    'visibility_grid': 'visibility_grid',
    'planned_path': 'planned_path',
}
MOVE_SERVICE = rl_contract.EXECUTE_MOVE
MARKER_KINDS = {
    'triangle_list': Marker.TRIANGLE_LIST,
    'line_strip': Marker.LINE_STRIP,
    'sphere': Marker.SPHERE,
    'cylinder': Marker.CYLINDER,
    'text': Marker.TEXT_VIEW_FACING,
}


# --- message conversions ------------------------------------------------------------------------


def planar_pose(pose) -> PlanarPose:
    """(x, y, yaw) of a geometry_msgs/Pose."""
    return PlanarPose(pose.position.x, pose.position.y, quaternion_yaw(pose.orientation))


def pose2d_msg(pose: PlanarPose) -> Pose2D:
    return Pose2D(x=float(pose.x), y=float(pose.y), theta=float(pose.yaw))


def description_msg(fields: dict) -> RLEnvDescription:
    return RLEnvDescription(
        num_actions=float(fields['num_actions']),
        num_states=float(fields['num_states']),
        min_state_range=[float(v) for v in fields['min_state_range']],
        max_state_range=[float(v) for v in fields['max_state_range']],
        max_reward=float(fields['max_reward']),
        reward_range=float(fields['reward_range']),
        stochastic=bool(fields['stochastic']),
        episodic=bool(fields['episodic']),
        title=fields['title'],
    )


def step_info_msg(
    report, state: list, reward: float, stamp: Time, truth_known: bool = True
) -> StepInfo:
    """truth_known False: no ground truth is published, the step was judged on the estimate
    and ``true_pose`` is NaN."""
    judgement = report.judgement
    info = StepInfo(
        episode=report.episode,
        step=report.step,
        action=report.action,
        state=state,
        reward=reward,
        visibility=_float32(judgement.visibility),
        distance_to_goal=_float32(judgement.distance_to_goal),
        detected=judgement.detected,
        terminal=report.terminal,
        estimated_pose=pose2d_msg(report.estimate),
        true_pose=pose2d_msg(report.truth if truth_known else PlanarPose(*[math.nan] * 3)),
    )
    info.header.stamp, info.header.frame_id = stamp, MAP_FRAME
    return info


def summary_msg(summary, stamp: Time) -> EpisodeSummary:
    message = EpisodeSummary(
        episode=summary.episode,
        outcome=summary.outcome,
        steps=summary.steps,
        total_reward=_float32(summary.total_reward),
        peak_visibility=_float32(summary.peak_visibility),
        accumulated_visibility=_float32(summary.accumulated_visibility),
        path_length=_float32(summary.path_length),
        final_distance_to_goal=_float32(summary.final_distance_to_goal),
        goal=summary.goal,
    )
    message.header.stamp, message.header.frame_id = stamp, MAP_FRAME
    return message


_FLOAT32_MAX = float(np.finfo(np.float32).max)


def _float32(value: float) -> float:
    """A value a float32 field accepts (rclpy refuses values beyond float32's range)."""
    return float(min(max(value, -_FLOAT32_MAX), _FLOAT32_MAX))


def searchlight_array_msg(lights, t: float) -> SearchlightArray:
    stamp = time_msg(t)
    array = SearchlightArray()
    array.header.stamp, array.header.frame_id = stamp, MAP_FRAME
    for light in lights:
        fields = searchlight_fields(light, t)
        x, y = fields.pop('position')
        waypoints = [Point(x=float(px), y=float(py)) for px, py in fields.pop('waypoints')]
        message = Searchlight(
            position=Point(x=float(x), y=float(y)), waypoints=waypoints, **fields
        )
        message.header.stamp, message.header.frame_id = stamp, MAP_FRAME
        array.lights.append(message)
    return array


def marker_array_msg(specs, t: float) -> MarkerArray:
    """The scene: a DELETEALL (stale markers of an earlier scene go), then every marker."""
    stamp = time_msg(t)
    clear = Marker(action=Marker.DELETEALL)
    clear.header.stamp, clear.header.frame_id = stamp, MAP_FRAME
    markers = [clear]
    for spec in specs:
        marker = Marker(ns=spec.namespace, id=spec.id, type=MARKER_KINDS[spec.kind])
        marker.action = Marker.ADD
        marker.header.stamp, marker.header.frame_id = stamp, MAP_FRAME
        marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = spec.position
        marker.pose.orientation.w = 1.0
        marker.scale.x, marker.scale.y, marker.scale.z = (float(v) for v in spec.scale)
        marker.color = _colour(spec.color)
        marker.points = [Point(x=p[0], y=p[1], z=p[2]) for p in spec.points]
        marker.colors = [_colour(c) for c in spec.colors]
        marker.text = spec.text
        markers.append(marker)
    return MarkerArray(markers=markers)


def _colour(rgba) -> ColorRGBA:
    return ColorRGBA(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))


def map_mismatch(occupancy, grid: OccupancyGrid) -> str:
    """How a nav_msgs/OccupancyGrid differs from a map ('' when it does not)."""
    info = grid.info
    x, y, _ = occupancy.origin
    origin = info.origin.position
    theirs = (info.width, info.height, info.resolution, origin.x, origin.y)
    ours = (occupancy.width, occupancy.height, occupancy.resolution, x, y)
    if theirs[:2] != ours[:2] or not np.allclose(theirs[2:], ours[2:], rtol=0, atol=1e-6):
        return f'{_grid_text(*theirs)}, expected {_grid_text(*ours)}'
    different = int(np.count_nonzero(np.asarray(grid.data) != occupancy.data.ravel()))
    return f'{different} cells differ' if different else ''


def _grid_text(width, height, resolution, x, y) -> str:
    return f'{width} x {height} cells of {resolution:g} m from ({x:g}, {y:g})'


class Pending(NamedTuple):
    """A request to the simulator on its way."""

    token: int
    future: Future
    client: Any
    deadline: float  # time.monotonic()
    what: str
    timeout: str  # what the deadline is, for the message when it passes


# --- the node -----------------------------------------------------------------------------------


class EnvironmentNode(StartupNode):
    """stealth-nav's rl_env: scenario, judging and episodes over the simulator's moves.

    `services`: the service servers of this process (`stealth_bringup.sim_env` passes the
    simulator's); a service it calls that one of them serves is called directly.
    """

    def __init__(self, services: InProcessServices | None = None, **kwargs):
        self._in_process = services if services is not None else InProcessServices()
        super().__init__(NODE_NAME, **kwargs)

    def set_up(self) -> None:
        self._configured = False
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        values = declare_parameters(self, PARAMETERS)
        self.scenario = self._load_scenario(values['scenario'])
        try:
            self.task = StealthTask(
                self.scenario, values['goal'] or None, rng=np.random.default_rng(values['seed'])
            )
        except ValueError as error:
            raise StartupError(f'parameter goal: {error}') from None
        self.flow = EpisodeFlow(self.task, values['judge_on'], values['first_episode'])
        self.move_timeout = values['move_timeout']
        self.start_delay = values['start_delay']
        self.first_action_timeout = values['first_action_timeout']
        self.step_readers = values['step_readers']
        self._first_state_at = 0.0  # time.monotonic() of the latest first state
        self.log_every = values['log_every']
        self.robot_interface, self.reset_mode = values['robot_interface'], values['reset_mode']
        if self.reset_mode == 'drive' and self.robot_interface != 'topics':
            raise StartupError('parameter reset_mode: drive needs robot_interface topics')
        self.reset_service = values['reset_service']
        self.unresponsive_moves = values['unresponsive_moves']
        self._unresponsive = 0  # moves in a row that timed out without the robot moving
        self.exit_code = 0
        self._judged_on_estimate = False  # said once: no ground truth, judged on the estimate
        self._walls = WallMap.of(self.scenario.map)
        self._moving_lights = any_moving(self.scenario)
        self._sim_time = 0.0  # the latest simulated time the simulator reported (s)
        # A move that ended before its step's time slot: (token, outcome, message) while the
        # hold that pads it runs (EpisodeFlow's "episode's clock").
        self._padding: tuple[int, int, str] | None = None
        self._pending: Pending | None = None
        self._ready_since: float | None = None
        self._retry_at = 0.0
        self._waiting_logged = time.monotonic()
        self._window: list = []  # EpisodeSummaryFields since the last progress line
        scene = ('searchlights', 'markers', 'visibility_grid')
        self._scene_published = dict.fromkeys(scene, (-1.0, 0))
        self._markers_cache: tuple[float, MarkerArray] | None = None
        self._move_note_log = Throttle(MOVE_NOTE_LOG_PERIOD)
        self._reset_failed_log = Throttle(RESET_FAILED_LOG_PERIOD)

        self._description_pub = self.create_publisher(
            RLEnvDescription, TOPICS['description'], rl_contract.DESCRIPTION_QOS
        )
        self._state_pub = self.create_publisher(
            RLStateReward,
            TOPICS['state'],
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=warn_publisher(
                self.get_logger,
                f'a subscription to {TOPICS["state"]} requests QoS this environment cannot '
                'offer ({policy}): it gets no states; the RL topics are reliable and volatile',
            ),
        )
        self._step_pub = self._quiet_publisher(
            StepInfo, TOPICS['step_info'], rl_contract.STEP_INFO_QOS
        )
        self._summary_pub = self._quiet_publisher(
            EpisodeSummary, TOPICS['summary'], rl_contract.SUMMARY_QOS
        )
        self._lights_pub = self._quiet_publisher(
            SearchlightArray, TOPICS['searchlights'], LATCHED_QOS
        )
        self._markers_pub = self._quiet_publisher(MarkerArray, TOPICS['markers'], LATCHED_QOS)
        self._grid_pub = self._quiet_publisher(
            OccupancyGrid, TOPICS['visibility_grid'], LATCHED_QOS
        )
        self._action_sub = self.create_subscription(
            RLAction,
            TOPICS['action'],
            self._on_action,
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=warn_subscription(
                self.get_logger,
                f'a publisher of {TOPICS["action"]} offers QoS this environment cannot accept '
                '({policy}): its actions never arrive; the RL topics are reliable and volatile',
            ),
        )
        self.create_subscription(
            RLExperimentInfo,
            TOPICS['experiment_info'],
            self._on_experiment_info,
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=QUIET_SUBSCRIPTION,
        )
        self.create_subscription(
            OccupancyGrid, 'map', self._check_map, LATCHED_QOS, event_callbacks=QUIET_SUBSCRIPTION
        )
        self._move_client = self._reset_client = self._robot = None
        if self.robot_interface == 'service':
            self._move_client = self._in_process.client(self, ExecuteMove, MOVE_SERVICE)
        else:
            self._robot = TopicRobot(self, self._topic_config(values), MAP_FRAME)
        if self.reset_mode == 'teleport':
            self._reset_client = self._in_process.client(self, ResetRobot, self.reset_service)
        self.create_service(RestartEpisode, TOPICS['restart'], self._on_restart_episode)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(TICK_PERIOD, self._on_tick, clock=self._steady)
        self._scene_timer = None
        self._schedule_scene(values['marker_period'])

        description = self.task.description(stochastic=True)
        self._description_pub.publish(description_msg(description))
        self._publish_scene(force=True)
        if values['publish_plan']:
            self._publish_plan()
        self._configured = True
        goal = self.task.goal
        self.get_logger().info(
            f"environment '{self.task.title}' from {self.scenario.path}: "
            f'{int(description["num_states"])} states, goal {goal.name} at '
            f'({goal.x:g}, {goal.y:g}), step {self.scenario.step_distance:g} m, step limit '
            f'{self.task.step_limit}, {len(self.scenario.lights)} lights, judged on the '
            f'{"true pose" if self.flow.judge_on == "true" else "estimate"}; robot over '
            f'{self._robot_description()}; waiting for it and an agent'
        )

    def _topic_config(self, values: dict) -> TopicConfig:
        limits = Limits(
            *(values[name] for name in ('max_linear_speed', 'max_angular_speed',
                                        'max_linear_accel', 'max_angular_accel'))
        )  # fmt: skip
        return TopicConfig(
            limits=limits,
            robot_radius=self.scenario.robot_radius,
            bump_distance=values['bump_distance'],
            stall_time=values['stall_time'],
        )

    def _robot_description(self) -> str:
        """What the robot is reached over: services, or topics (and the reset's way)."""
        if isinstance(self._move_client, InProcessClient):
            moves = f'the simulator in this process (called directly: {MOVE_SERVICE}'
        elif self._robot is None:
            moves = f'the simulator ({MOVE_SERVICE}'
        else:
            names = ', '.join(self.resolve_topic_name(t) for t in ROBOT_TOPICS.values())
            moves = f'topics ({names}'
        if self.reset_mode == 'teleport':
            return f'{moves}, {self.resolve_service_name(self.reset_service)})'
        return f'{moves}; reset by driving to the start)'

    def _quiet_publisher(self, message_type, topic: str, qos):
        return self.create_publisher(message_type, topic, qos, event_callbacks=QUIET_PUBLISHER)

    # --- parameters -----------------------------------------------------------------------------

    def _load_scenario(self, name: str):
        if not name:
            raise StartupError(
                'parameter scenario: required, a scenario name (e.g. lgfloor) or the path of a '
                'scenario YAML'
            )
        try:
            return load_scenario(name)
        except (ScenarioError, OSError, ValueError) as error:
            raise StartupError(f'parameter scenario: {error}') from None

    def _validate_parameters(self, changes) -> SetParametersResult:
        """rclpy checks types, ranges and read-only; this checks what it cannot."""
        for change in changes:
            choices = CHOICES.get(change.name)
            if choices is not None and change.value not in choices:
                return SetParametersResult(
                    successful=False,
                    reason=f'{change.name} must be one of {", ".join(choices)}, got '
                    f'{change.value!r}',
                )
        reason = non_finite(changes)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply_parameters(self, changes) -> None:
        if not self._configured:
            return
        for change in changes:
            if change.name == 'judge_on':
                self.flow.judge_on = change.value
            elif change.name == 'move_timeout':
                self.move_timeout = change.value
            elif change.name == 'start_delay':
                self.start_delay = change.value
            elif change.name == 'first_action_timeout':
                self.first_action_timeout = change.value
            elif change.name == 'step_readers':
                self.step_readers = change.value
            elif change.name == 'log_every':
                self.log_every = change.value
            elif change.name == 'marker_period':
                self._schedule_scene(change.value)
        names = ', '.join(f'{c.name}={c.value}' for c in changes)
        self.get_logger().info(f'parameters changed: {names}')

    # --- startup, timeouts, agent presence ------------------------------------------------------

    def _robot_ready(self) -> bool:
        if self._reset_client is not None and not self._reset_client.service_is_ready():
            return False
        if self._robot is None:
            return self._move_client.service_is_ready()
        return self._robot.ready

    def _agent_connected(self) -> bool:
        if self._action_sub.get_publisher_count() == 0:
            return False
        writers = [
            Endpoint(_node_of(info))
            for info in self.get_publishers_info_by_topic(self._action_sub.topic_name)
        ]
        readers = [
            Endpoint(
                _node_of(info),
                info.qos_profile.durability != DurabilityPolicy.TRANSIENT_LOCAL,
            )
            for info in self.get_subscriptions_info_by_topic(self._state_pub.topic_name)
        ]
        return agent_connected(writers, readers, self._state_pub.get_subscription_count())

    def _on_tick(self) -> None:
        now = time.monotonic()
        pending = self._pending
        if pending is not None and now > pending.deadline:
            self._pending = None
            pending.client.remove_pending_request(pending.future)
            self._request_failed(
                pending, f'no answer from {pending.what} within {pending.timeout} '
                '(is the simulator running?)'
            )  # fmt: skip
        if self._robot is not None:
            self._robot_watchdog()
        phase = self.flow.phase
        if phase is Phase.WAITING:
            self._maybe_start(now)
        elif self._action_sub.get_publisher_count() == 0:
            self._agent_gone()
        elif (
            self.first_action_timeout
            and phase is Phase.RUNNING
            and self.flow.steps == 0
            and now - self._first_state_at > self.first_action_timeout
        ):
            self._first_action_overdue()

    def _first_action_overdue(self) -> None:
        aborted = self.flow.unanswered(
            f'no action for the first state within first_action_timeout '
            f'{self.first_action_timeout:g} s (the state or the action was lost: an agent that '
            'restarted may not have been matched yet)'
        )
        if aborted is not None:
            self._publish_aborted(aborted)

    def _robot_watchdog(self) -> None:
        """A robot that stops publishing odometry mid-move fails the move, as a simulator that
        does not answer does."""
        robot = self._robot
        robot.tick()
        if not robot.busy or robot.silent_for() <= self.move_timeout:
            return
        robot.cancel()
        reason = (
            f'no {self.resolve_topic_name(ROBOT_TOPICS["odom"])} for move_timeout '
            f'{self.move_timeout:g} s (is the robot running?)'
        )
        if self.flow.phase is Phase.RESETTING:
            self._reset_failed(self.flow.token, reason)
        else:
            self._abort(self.flow.token, reason)

    def _drop_requests(self) -> None:
        """Whatever the robot was asked to do is void (its answer would be stale)."""
        if self._robot is not None:
            self._robot.cancel()
        if self._pending is not None:
            self._pending.client.remove_pending_request(self._pending.future)
            self._pending = None

    def _on_restart_episode(self, request, response):
        """rl_env/restart_episode: a node of the loop was restarted under the episode."""
        restarted = 'agent' if request.restarted == RestartEpisode.Request.AGENT else 'simulator'
        why = f'the {restarted} was restarted' + (f' ({request.reason})' if request.reason else '')
        if restarted == 'agent':
            summary = self._agent_gone(why)
        else:
            self._drop_requests()
            aborted = self.flow.interrupt(why)
            if aborted is not None:
                self._publish_aborted(aborted)
            summary = None if aborted is None else aborted.summary
        response.aborted = summary is not None
        response.episode = -1 if summary is None else summary.episode
        response.message = (
            f'episode {summary.episode} ended ABORTED: {why}'
            if summary is not None
            else f'{why}; no episode was running'
        )
        return response

    def _agent_gone(self, why: str = ''):
        """No agent any more (or a new one replaced it): back to waiting for one; the summary of
        the episode this ended ABORTED, if any."""
        withdrawn = self.flow.counts.episodes_withdrawn
        self._drop_requests()
        summary = self.flow.agent_lost()
        gone = why or f'the agent went away (no {TOPICS["action"]} publisher)'
        if summary is not None:
            self._publish_summary(summary)
            self.get_logger().warning(
                f'{gone}; episode {summary.episode} ended as ABORTED after {summary.steps} steps'
            )
        elif self.flow.counts.episodes_withdrawn > withdrawn:
            self.get_logger().info(
                f'{gone} before its first action in episode {self.flow.episode + 1}: withdrawn, '
                'the next agent starts it again'
            )
        else:
            self.get_logger().info(gone)
        return summary

    def _maybe_start(self, now: float) -> None:
        robot, agent = self._robot_ready(), self._agent_connected()
        readers = self._step_pub.get_subscription_count() >= self.step_readers
        if not (robot and agent and readers):
            self._ready_since = None
            if now - self._waiting_logged >= WAITING_LOG_PERIOD:
                self._waiting_logged = now
                missing = [
                    what
                    for what, there in (
                        (f'the robot: {self._robot_description()}', robot),
                        (
                            f'an agent (publishing {TOPICS["action"]}, subscribed to '
                            f'{TOPICS["state"]})',
                            agent,
                        ),
                        (f'{self.step_readers} readers of {TOPICS["step_info"]}', readers),
                    )
                    if not there
                ]
                self.get_logger().info(f'still waiting for {" and ".join(missing)}')
            return
        if self._ready_since is None:
            self._ready_since = now
        if now - self._ready_since >= self.start_delay and now >= self._retry_at:
            self._start_episode()

    def _start_episode(self) -> None:
        """Reset the robot to the start; the episode's first state follows the answer."""
        token, (x, y, yaw) = self.flow.begin_reset()
        if self.reset_mode == 'drive':
            self._drive_home(token, Pose(x, y, yaw))
            return
        request = ResetRobot.Request(x=x, y=y, yaw=yaw)  # zero covariance: the node's default
        self._send(self._reset_client, request, token, self.reset_service, self._on_reset_answer,
                   min(self.move_timeout, RESET_ANSWER_TIMEOUT))  # fmt: skip

    def _drive_home(self, token: int, start: Pose) -> None:
        """reset_mode drive: back to the start over the lattice, then tell the localisation."""
        here = self._robot.tracker.estimate
        moves = route_home(self.task.lattice, here, start) if here is not None else None
        if moves is None:
            self._reset_failed(token, f'no collision-free path from {here} to the start')
            return

        def arrived(end: MoveEnd) -> None:
            if end.outcome != ExecuteMove.Response.DONE:
                outcome = 'no move' if end.outcome is None else end.outcome.name
                self._reset_failed(token, f'driving to the start: {outcome} {end.message}')
                return
            self._robot.set_initial_pose(start)
            self._episode_ready(token)

        self._robot.run(moves, arrived)

    def _send(self, client, request, token: int, what: str, on_answer, timeout=None) -> None:
        future = client.call_async(request)
        if timeout is None or timeout >= self.move_timeout:
            timeout, name = self.move_timeout, f'move_timeout {self.move_timeout:g} s'
        else:
            name = f'{timeout:g} s'
        deadline = time.monotonic() + timeout
        self._pending = Pending(token, future, client, deadline, what, name)
        future.add_done_callback(functools.partial(on_answer, token))

    def _request_failed(self, pending: Pending, reason: str) -> None:
        if pending.what == self.reset_service:
            self._reset_failed(pending.token, reason)
        else:
            self._abort(pending.token, reason)

    # --- the simulator's answers ----------------------------------------------------------------

    def _take_answer(self, token: int, future: Future):
        """The response of a request that is still current, or None (stale or failed)."""
        if self._pending is not None and self._pending.token == token:
            self._pending = None
        if future.cancelled():
            return None, 'the request was cancelled'
        error = future.exception()
        if error is not None:
            return None, f'the call failed: {error!r}'
        return future.result(), ''

    def _on_reset_answer(self, token: int, future: Future) -> None:
        response, problem = self._take_answer(token, future)
        if response is None or not response.success:
            self._reset_failed(token, problem or response.message)
            return
        if self._robot is None:
            self._episode_ready(token)
        else:  # the first state once odometry from after the teleport has come
            start = Pose(*self.task.scenario.start)
            self._robot.restart(start, functools.partial(self._episode_ready, token))

    def _episode_ready(self, token: int) -> None:
        """The robot is at the start: the first state goes out."""
        if self._robot is not None and self._robot.tracker.latest is not None:
            # The robot's clock ran on while it was placed (odometry from after the teleport).
            self._sim_time = max(self._sim_time, self._robot.tracker.latest.t)
        state = self.flow.reset_done(token, self._sim_time)
        if state is None:
            return  # stale: the agent went away meanwhile
        self._state_pub.publish(RLStateReward(state=list(state), reward=0.0, terminal=False))
        self._first_state_at = time.monotonic()
        self.get_logger().debug(f'episode {self.flow.episode} started at state {list(state)}')

    def _reset_failed(self, token: int, reason: str) -> None:
        if self.flow.reset_failed(token):
            self._retry_at = time.monotonic() + RESET_RETRY
            if self._reset_failed_log():
                self.get_logger().error(
                    f'{self._reset_what} failed: {reason}; trying again in {RESET_RETRY:g} s'
                )

    @property
    def _reset_what(self) -> str:
        return self.reset_service if self.reset_mode == 'teleport' else 'the drive to the start'

    def _on_move_answer(self, token: int, future: Future) -> None:
        response, problem = self._take_answer(token, future)
        if response is None:
            self._abort(token, f'{MOVE_SERVICE}: {problem}')
            return
        if response.outcome == ExecuteMove.Response.REJECTED:
            self._abort(token, f'the simulator rejected the move: {response.message}')
            return
        estimate = planar_pose(response.estimate.pose)
        truth = planar_pose(response.true_pose)
        self._finish_move(token, response.outcome, response.message, estimate, truth,
                          response.stamp)  # fmt: skip

    def _on_move_end(self, token: int, end: MoveEnd) -> None:
        """topics: a move's end (or why there was none)."""
        if end.outcome is None:
            self._abort(token, end.message)
            return
        timed_out = end.outcome == ExecuteMove.Response.TIMED_OUT
        self._unresponsive = self._unresponsive + 1 if timed_out and not end.moved else 0
        if self._unresponsive >= self.unresponsive_moves:
            cmd_vel = self.resolve_topic_name(ROBOT_TOPICS['cmd_vel'])
            self._give_up(
                token, f'the robot is not responding to {cmd_vel}: {self._unresponsive} moves '
                'in a row timed out without it moving (is it running, and is cmd_vel remapped '
                'to its topic?)'
            )  # fmt: skip
            return
        estimate = PlanarPose(*end.estimate)
        truth = PlanarPose(*end.truth) if end.truth is not None else estimate
        if end.truth is None and not self._judged_on_estimate:
            self._judged_on_estimate = True
            self.get_logger().warning(
                f'no {self.resolve_topic_name(ROBOT_TOPICS["truth"])} is published: steps are '
                'judged on the localisation estimate (StepInfo.true_pose is NaN)'
            )
        self._finish_move(token, end.outcome, end.message, estimate, truth, time_msg(end.t),
                          truth_known=end.truth is not None)  # fmt: skip

    def _finish_move(self, token, outcome, message, estimate, truth, stamp, truth_known=True):
        """A move ended (DONE, BUMPED or TIMED_OUT) with these poses at this time: judge it."""
        if not is_finite_pose(*estimate, *truth):
            self._abort(token, f'the robot reported a non-finite pose ({estimate}, {truth})')
            return
        t = seconds(stamp)
        self._sim_time = max(self._sim_time, t)
        padded, self._padding = self._padding, None
        left = self.flow.step_time_left(t) if token == self.flow.token else 0.0
        if padded is not None and padded[0] == token:  # the hold after the move: judge it now
            if outcome == ExecuteMove.Response.DONE:
                outcome, message = padded[1:]
        elif left >= SLOT_TOLERANCE:
            self._padding = (token, outcome, message)  # early: stand still to the slot's end
            self._hold(token, left)
            return
        try:
            report = self.flow.finish_move(token, estimate, truth, t)
        except ValueError as error:
            self._abort(token, f"{error}: does the robot run on the scenario's map?")
            return
        if report is None:
            return  # stale: already aborted (timeout) or the agent went away
        if outcome != ExecuteMove.Response.DONE and self._move_note_log():
            self.get_logger().info(
                f'move {report.action} of episode {report.episode}, step {report.step}: {message}'
            )
        self._publish_step(report, stamp, truth_known)

    def _give_up(self, token: int, reason: str) -> None:
        """The robot cannot be used: end the episode (the agent gets its terminal state), then
        exit with EXIT_ROBOT_NOT_RESPONDING once the messages are out."""
        self._abort(token, reason)
        self.get_logger().fatal(f'stopping: {reason}')
        self.exit_code = EXIT_ROBOT_NOT_RESPONDING
        self._robot.cancel()
        self.create_timer(STOP_DELAY, self.context.try_shutdown, clock=self._steady)

    def _abort(self, token: int, reason: str) -> None:
        aborted = self.flow.abort(token, reason)
        if aborted is not None:
            self._publish_aborted(aborted)

    def _publish_aborted(self, aborted: Aborted) -> None:
        """The terminal state (reward 0) that keeps the agent in step, and the summary."""
        self._state_pub.publish(
            RLStateReward(state=list(aborted.state), reward=0.0, terminal=True)
        )
        self._publish_summary(aborted.summary)
        self.get_logger().error(
            f'episode {aborted.summary.episode} ABORTED after {aborted.summary.steps} steps: '
            f'{aborted.reason}'
        )

    def _check_map(self, grid: OccupancyGrid) -> None:
        """The simulator's map must be the scenario's, or the judge sees other walls."""
        problem = map_mismatch(self.scenario.map, grid)
        if problem:
            self.get_logger().error(
                f"the simulator's map is not the map of scenario {self.scenario.name!r} "
                f'({self.scenario.map_path}): {problem}; start the simulator with that map'
            )
        else:
            self.get_logger().debug("the simulator's map is the scenario's")

    # --- the agent's messages -------------------------------------------------------------------

    def _on_action(self, message: RLAction) -> None:
        problem = self.flow.accept_action(message.action)
        if problem is not None:
            counts = self.flow.counts
            self.get_logger().warning(
                f'{problem} ({counts.actions_dropped} of {counts.actions_received} actions '
                'dropped so far)'
            )
            return
        # Every action is a drive to a lattice node (StealthTask.move_target), over either
        # interface: the robot stays on the lattice the agent's states and the planners assume.
        # A wait (where lights move) stands still for the rest of the step's time slot. Where
        # lights are weighed by exposure, a turn (and a move the map blocks, which turns
        # nothing on the lattice) turns in place to its lattice heading.
        task, state, action = self.task, self.flow.state, self.flow.action
        if action == WAIT and task.action_names[action] == 'wait':
            self._hold(self.flow.token, self.flow.step_time_left(self._sim_time))
            return
        x, y = task.move_target(*state[:2], action) if action < WAIT else state[:2]
        blocked = task.lattice.point_to_node(x, y) == task.lattice.point_to_node(*state[:2])
        if task.footprint is not None and blocked:
            heading = heading_angle(task.heading_after(task.heading_in(state), action, False))
            request = ExecuteMove.Request(
                kind=ExecuteMove.Request.TURN_TO_HEADING, heading=heading
            )
            self._run(self.flow.token, MoveGoal(heading), request)
            return
        request = ExecuteMove.Request(kind=ExecuteMove.Request.GO_TO, x=x, y=y)
        self._run(self.flow.token, go_to(x, y), request)

    def _hold(self, token: int, seconds: float) -> None:
        """Stand still for `seconds` (a whole step's slot when nothing is left of it: a wait
        that comes after a late step still takes time)."""
        if seconds < SLOT_TOLERANCE:
            seconds = self.task.step_seconds
        request = ExecuteMove.Request(kind=ExecuteMove.Request.HOLD, seconds=seconds)
        self._run(token, hold_goal(seconds), request)

    def _run(self, token: int, move, request: ExecuteMove.Request) -> None:
        """A move over the robot's topics or the simulator's service."""
        if self._robot is not None:
            self._robot.run([move], functools.partial(self._on_move_end, token))
            return
        if not self._move_client.service_is_ready():
            self._abort(token, f'{MOVE_SERVICE} is not available')
            return
        self._send(self._move_client, request, token, MOVE_SERVICE, self._on_move_answer)

    def _on_experiment_info(self, message: RLExperimentInfo) -> None:
        problem = self.flow.experiment_info()
        if problem is not None:
            self.get_logger().warning(
                f'{problem} (episode_number {message.episode_number}, '
                f'{message.number_actions} actions)'
            )
            return
        self._start_episode()

    # --- publishing -----------------------------------------------------------------------------

    def _publish_step(self, report, stamp: Time, truth_known: bool = True) -> None:
        state = list(report.state)
        reward = _float32(report.reward)
        self._state_pub.publish(
            RLStateReward(state=state, reward=reward, terminal=report.terminal)
        )
        if self._step_pub.get_subscription_count():  # as the simulator: built when wanted
            self._step_pub.publish(step_info_msg(report, state, reward, stamp, truth_known))
        if report.summary is not None:
            self._publish_summary(report.summary, stamp)

    def _publish_summary(self, summary, stamp: Time | None = None) -> None:
        self._summary_pub.publish(summary_msg(summary, stamp or time_msg(self._sim_time)))
        self.get_logger().debug(
            f'episode {summary.episode}: {Outcome(summary.outcome).name} after {summary.steps} '
            f'steps, return {summary.total_reward:.2f}'
        )
        self._window.append(summary)
        if self.log_every and len(self._window) >= self.log_every:
            self.get_logger().info(_progress(self._window))
            self._window = []

    def _schedule_scene(self, period: float) -> None:
        if self._scene_timer is not None:
            self.destroy_timer(self._scene_timer)
            self._scene_timer = None
        if period > 0:
            self._scene_timer = self.create_timer(period, self._publish_scene, clock=self._steady)

    def _scene_time(self) -> float:
        """The lights' time to draw them at: the episode's clock (EpisodeFlow) at the latest
        simulated time the simulator reported, or at the ROS clock under use_sim_time."""
        t = self._sim_time
        if self.get_parameter('use_sim_time').value:
            t = max(t, self.get_clock().now().nanoseconds * 1e-9)
        return self.flow.episode_time(t)

    def _publish_scene(self, force: bool = False) -> None:
        """SearchlightArray, markers and the visibility grid: when lights moved since they were
        last sent, or when a new subscriber came (a volatile viewer gets nothing from transient
        local). Moving lights republish all three here, every marker_period: this is the hook."""
        t = self._scene_time() if self._moving_lights else 0.0
        for key, publisher, build in (
            ('searchlights', self._lights_pub, self._searchlights_msg),
            ('markers', self._markers_pub, self._markers_msg),
            ('visibility_grid', self._grid_pub, self._visibility_grid_msg),
        ):
            subscribers = publisher.get_subscription_count()
            last_t, last_subscribers = self._scene_published[key]
            if force or (subscribers and (t != last_t or subscribers > last_subscribers)):
                publisher.publish(build(t))
                last_t = t
            self._scene_published[key] = (last_t, subscribers)

    def _searchlights_msg(self, t: float) -> SearchlightArray:
        return searchlight_array_msg(self.scenario.lights, t)

    def _markers_msg(self, t: float) -> MarkerArray:
        if self._markers_cache is None or self._markers_cache[0] != t:
            specs = scene_markers(self.scenario, self.task.goal.name, t, self._walls)
            self._markers_cache = (t, marker_array_msg(specs, t))
        return self._markers_cache[1]

    def _publish_plan(self) -> None:
        """planned_path: value iteration's optimum from the start to the goal (frame map)."""
        from stealth_env.planners import optimal_path

        publisher = self._quiet_publisher(Path, TOPICS['planned_path'], LATCHED_QOS)
        points, _ = optimal_path(self.scenario, self.task.goal.name)
        plan = Path()
        plan.header.frame_id = MAP_FRAME
        for x, y in points:
            pose = PoseStamped()
            pose.header.frame_id = MAP_FRAME
            pose.pose.position.x, pose.pose.position.y = float(x), float(y)
            pose.pose.orientation.w = 1.0
            plan.poses.append(pose)
        publisher.publish(plan)

    def _visibility_grid_msg(self, t: float) -> OccupancyGrid:
        """The lit area at time t on the scenario's map grid: static lights' field from the disk
        cache, moving lights' computed afresh (a cache file per time would only pile up)."""
        from stealth_env.visibility import scenario_visibility, visibility_field

        occupancy = self.scenario.map
        if self._moving_lights:
            total, _ = visibility_field(
                occupancy.blocked, occupancy.resolution, occupancy.origin, self.scenario.lights, t
            )
        else:
            total, _ = scenario_visibility(self.scenario)
        grid = OccupancyGrid()
        grid.header.stamp, grid.header.frame_id = time_msg(t), MAP_FRAME
        grid.info.map_load_time = grid.header.stamp
        grid.info.resolution = float(occupancy.resolution)
        grid.info.width, grid.info.height = occupancy.width, occupancy.height
        x, y, yaw = occupancy.origin
        grid.info.origin.position.x, grid.info.origin.position.y = float(x), float(y)
        grid.info.origin.orientation = yaw_quaternion(yaw)
        levels = visibility_levels(total, self.scenario.detection_threshold)
        grid.data = array.array('b', levels.tobytes())  # rows from the bottom, as /map
        return grid

    # --- shutdown -------------------------------------------------------------------------------

    def log_totals(self) -> None:
        """The counts that show nothing was lost (after Ctrl-C /rosout is gone: plain logger)."""
        logger = (
            self.get_logger()
            if self.context.ok()
            else rclpy.logging.get_logger(f'{NODE_NAME}.exit')
        )
        note = ''
        if self.flow.in_episode:
            note = f'; episode {self.flow.episode} was running ({self.flow.steps} steps)'
        logger.info(f'totals: {self.flow.counts.describe()}{note}')


def _node_of(info) -> str:
    namespace = info.node_namespace.rstrip('/')
    return f'{namespace}/{info.node_name}'


def _progress(window) -> str:
    outcomes = Counter(Outcome(s.outcome).name.lower() for s in window)
    names = ', '.join(f'{name} {outcomes[name]}' for name in sorted(outcomes))
    mean_return = sum(s.total_reward for s in window) / len(window)
    mean_steps = sum(s.steps for s in window) / len(window)
    return (
        f'episodes {window[0].episode}-{window[-1].episode}: {names}; mean return '
        f'{mean_return:.2f}, mean steps {mean_steps:.1f}'
    )


def main(args=None) -> int:
    nodes = []

    def make_node() -> EnvironmentNode:
        nodes.append(EnvironmentNode())
        return nodes[-1]

    code = run_node(make_node, NODE_NAME, args=args, on_exit=EnvironmentNode.log_totals)
    return code or (nodes[0].exit_code if nodes else 0)


if __name__ == '__main__':
    raise SystemExit(main())
