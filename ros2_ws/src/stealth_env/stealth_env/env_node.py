"""The environment node (``environment``): rl-texplore-ros-pkg's rl_env protocol over the
simulator, judged by the shared core (``StealthTask`` via ``EpisodeFlow``). A thin shell: the
decisions are ``stealth_env.episode_flow``'s, the messages ``env_messages``', the RL topics
``agent_link``'s, the scene ``scene_publisher``'s (its geometry ``markers``'), and the robot one
``stealth_env.robot.Robot``: ``service_robot`` or ``topic_robot``.

## Topics

Frame ``map``; the RL loop's names and QoS from ``stealth_node_kit.rl_contract`` (reliable,
volatile, a lockstep history that never fills: no step is lost).

* publishes ``rl_env/rl_env_description`` (RLEnvDescription; reliable + transient local,
  depth 1) once; ``rl_env/rl_state_reward`` (RLStateReward) at every episode start and after
  every action; ``rl_env/step_info`` (StepInfo) after every action, built only while someone
  subscribes (episodes wait for ``step_readers`` of it: stealth train's monitor and recorder);
  ``rl_env/episode_summary`` (EpisodeSummary) at every episode end. ``step_info`` and
  ``episode_summary`` are transient local with the last STEP_HISTORY and SUMMARY_HISTORY
  messages, for a reader that (re)joins late (a recorder, the orchestrator, an agent: DDS may
  match a restarted node's endpoints after the first ones);
* the scene for RViz and Foxglove, transient local: ``searchlights`` (SearchlightArray) and
  ``searchlight_markers`` (visualization_msgs/MarkerArray): the lights and the scene, and
  ``visibility_grid`` (nav_msgs/OccupancyGrid: the lit area as a costmap, 0-100 = total
  visibility as a percentage of the detection threshold), again every ``marker_period`` while
  lights move or when a new viewer subscribes; with ``publish_plan`` (on under ``stealth train
  --watch``), ``planned_path`` (nav_msgs/Path): value iteration's optimum on the move lattice,
  once; with ``track: sensed`` (the robot that does not know the lights: the states carry what
  it sensed, ``stealth_env.sensed_track``), ``sensed_light`` (nav_msgs/OccupancyGrid); with
  ``observation_layout: grid``, ``rl_env/observation`` (GridObservation, ``agent_link``).
* subscribes ``rl_agent/rl_action`` (RLAction) and ``rl_agent/rl_experiment_info``
  (RLExperimentInfo); reads the simulator's latched ``map`` once to check it is the scenario's
  (an error line if not).

## Services

Serves ``rl_env/restart_episode`` (RestartEpisode): a restarted simulator's or agent's episode
ends ABORTED (stealth train's respawn). Calls ``sim/execute_move`` and ``sim/reset``
(stealth_interfaces) of the simulator node (``robot_interface`` service; ``topics``: see below)
asynchronously: no callback ever blocks the executor (directly when a node of this process
serves them: ``stealth_bringup.sim_env``).

## Episodes

The description goes out at once; the first episode starts ``start_delay`` after both
simulator services answer and an agent is connected (its rl_state_reward reader matched: the
volatile first state is not lost). Each action is a move of the scenario's step distance
(``ExecuteMove.GO_TO`` the lattice node), a wait where lights move (``HOLD``), or a turn in place
where the scenario weighs lights by exposure (``TURN_TO_HEADING``); the new state is the
localisation estimate in the answer, rounded to the state grid (cells centred on the move
lattice's nodes); reward and terminal come from the core, judged on the true pose at the move's
end time (``judge_on: estimate`` for the original's estimate-only way). Goal, detection or the
step limit end an episode; the agent's RLExperimentInfo starts the next one. Actions out of
turn or out of range are dropped with a warning. A move the simulator rejects, fails or does not
answer within ``move_timeout``, a first state with no answer within ``first_action_timeout`` and
an agent that goes away end the episode as ABORTED (a terminal state with reward 0 keeps the
agent in step; the next agent to come gets a fresh one). Totals are logged at shutdown.

## Parameters

``stealth_env.env_parameters.PARAMETERS``. Bad startup input (no or an unusable scenario, an
unknown goal, a bad parameter value) stops the node with one line saying which and why, and exit
code 2. The robot interface (``robot_interface``): ``service`` (the default) is the above;
``topics`` plugs into any ROS robot over ``cmd_vel``/``odom``/``amcl_pose``/``scan`` (Stage,
Gazebo, a TurtleBot with nav2's AMCL, or ``stealth_sim`` over the same topics), the same moves
with the same tolerances and outcomes executed closed-loop (``stealth_env.topic_robot``, which
says how, with its resets, ``reset_mode``, and its watchdogs). There the judge uses
``ground_truth`` (nav_msgs/Odometry, frame ``map``) when it is published, otherwise the estimate
(a warning once; StepInfo.true_pose is then NaN); a robot that is not responding (after
``unresponsive_moves`` timed-out moves in a row) ends the episode ABORTED and the node exits with
code 3 and a line saying so.
"""

from __future__ import annotations

import functools
import time

import numpy as np
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from stealth_core.grid_observation import observed_grid
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import ScenarioError, load_scenario
from stealth_core.task import StealthTask
from stealth_interfaces.msg import RLAction, RLExperimentInfo
from stealth_interfaces.srv import ExecuteMove, RestartEpisode
from stealth_node_kit import rl_contract
from stealth_node_kit.conversions import seconds, time_msg
from stealth_node_kit.in_process import InProcessServices
from stealth_node_kit.log_throttle import Throttle
from stealth_node_kit.on_demand import OnDemand, events_on_demand
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.running import StartupNode, StopRequested, run_node

from stealth_env.agent_link import TOPICS, AgentLink
from stealth_env.env_messages import MAP_FRAME
from stealth_env.env_parameters import PARAMETERS, not_a_choice, topic_config
from stealth_env.episode_flow import (
    Aborted,
    EpisodeFlow,
    EpisodePhase,
    PlanarPose,
    is_finite_pose,
    progress_line,
)
from stealth_env.robot import MoveEnd, Robot
from stealth_env.scene_publisher import ScenePublisher
from stealth_env.sensed_track import SensedTrack
from stealth_env.service_robot import ServiceRobot, Teleport
from stealth_env.start_gate import StartGate
from stealth_env.topic_moves import Pose
from stealth_env.topic_robot import TopicRobot

NODE_NAME = 'environment'
TICK_PERIOD = 0.1  # s of wall time between housekeeping ticks (start, timeouts, agent presence)
RESET_RETRY = 1.0  # s of wall time before a failed reset is tried again
MOVE_NOTE_LOG_PERIOD = 5.0  # s of wall time between lines about bumped moves
RESET_FAILED_LOG_PERIOD = 10.0  # s of wall time between lines about failed resets
STOP_DELAY = 1.0  # s of wall time between giving up on the robot and exiting (messages go out)
EXIT_ROBOT_NOT_RESPONDING = 3
# Parameters the node reads where it uses them: a change takes effect at once.
READ_AT_USE = ('move_timeout', 'clock_timeout', 'start_delay', 'first_action_timeout',
               'step_readers', 'log_every')  # fmt: skip
DONE = ExecuteMove.Response.DONE


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
        self.clock_timeout = values['clock_timeout']
        self.start_delay = values['start_delay']
        self.first_action_timeout = values['first_action_timeout']
        self.step_readers = values['step_readers']
        self.log_every = values['log_every']
        self.reset_by_teleport = values['reset_mode'] == 'teleport'
        if not self.reset_by_teleport and values['robot_interface'] != 'topics':
            raise StartupError('parameter reset_mode: drive needs robot_interface topics')
        self.reset_service = values['reset_service']
        self.exit_code = 0
        self._first_state_at = 0.0  # time.monotonic() of the latest first state
        self._sim_time = 0.0  # the latest simulated time the simulator reported (s)
        self._gate = StartGate(time.monotonic())
        self._window: list = []  # EpisodeSummaryFields since the last progress line
        self._move_note_log = Throttle(MOVE_NOTE_LOG_PERIOD)
        self._reset_failed_log = Throttle(RESET_FAILED_LOG_PERIOD)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        sensed = SensedTrack(self.task) if values['track'] == 'sensed' else None
        try:
            grid = observed_grid(
                self.task,
                values['track'],
                values['observation_layout'],
                None if sensed is None else sensed.model,
            )
        except ValueError as error:
            raise StartupError(f'parameter observation_layout: {error}') from None
        self.agent = AgentLink(self, self._on_action, self._on_experiment_info, sensed, grid)
        self.scene = ScenePublisher(
            self, self.scenario, self.task.goal.name, self._scene_time, self._steady, sensed
        )
        self.robot = self._make_robot(values)
        self.create_service(RestartEpisode, rl_contract.RESTART_EPISODE, self._on_restart_episode)
        self.create_timer(TICK_PERIOD, self._on_tick, clock=self._steady)
        self._qos_events = events_on_demand(self, OnDemand())  # polled each tick, not waited on
        self.scene.schedule(values['marker_period'])

        description = self.task.description(stochastic=True)
        self.agent.publish_description(description)
        self.scene.publish(force=True)
        if values['publish_plan']:
            self.scene.publish_plan()
        self._configured = True
        goal = self.task.goal
        self.get_logger().info(
            f"environment '{self.task.title}' from {self.scenario.path}: "
            f'{int(description["num_states"])} states, goal {goal.name} at '
            f'({goal.x:g}, {goal.y:g}), step {self.scenario.step_distance:g} m, step limit '
            f'{self.task.step_limit}, {len(self.scenario.lights)} lights, judged on the '
            f'{"true pose" if self.flow.judge_on == "true" else "estimate"}; robot over '
            f'{self.robot.describe()}; waiting for it and an agent'
        )

    def _make_robot(self, values: dict) -> Robot:
        teleport, self._move_timeout = None, lambda: self.move_timeout  # read at each move
        if self.reset_by_teleport:
            teleport = Teleport(self, self._in_process, self.reset_service, self._move_timeout)
        if values['robot_interface'] == 'service':
            return ServiceRobot(self, self._in_process, teleport, self._move_timeout)
        config = topic_config(values, self.scenario.robot_radius)
        return TopicRobot(
            self,
            config,
            MAP_FRAME,
            self.task.lattice,
            teleport,
            values['unresponsive_moves'],
            self._move_timeout,
            lambda: self.clock_timeout,
        )

    # --- parameters -----------------------------------------------------------------------------

    def _load_scenario(self, name: str):
        if not name:
            raise StartupError(
                'parameter scenario: required, a scenario name (e.g. lgfloor) '
                'or the path of a scenario YAML'
            )
        try:
            return load_scenario(name)
        except (ScenarioError, OSError, ValueError) as error:
            raise StartupError(f'parameter scenario: {error}') from None

    def _validate_parameters(self, changes) -> SetParametersResult:
        """rclpy checks types, ranges and read-only; this checks what it cannot."""
        reason = not_a_choice(changes) or non_finite(changes)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply_parameters(self, changes) -> None:
        if not self._configured:
            return
        for change in changes:
            if change.name == 'judge_on':
                self.flow.judge_on = change.value
            elif change.name == 'marker_period':
                self.scene.schedule(change.value)
            elif change.name in READ_AT_USE:
                setattr(self, change.name, change.value)
        names = ', '.join(f'{c.name}={c.value}' for c in changes)
        self.get_logger().info(f'parameters changed: {names}')

    # --- startup, timeouts, agent presence ------------------------------------------------------

    def _on_tick(self) -> None:
        now = time.monotonic()
        self._qos_events.poll_events()
        self.robot.tick()  # deadlines and watchdogs: a failure ends a move or a reset
        phase = self.flow.phase
        if phase is EpisodePhase.WAITING:
            self._maybe_start(now)
        elif self.agent.action_writers() == 0:
            self._agent_gone()
        elif (
            self.first_action_timeout
            and phase is EpisodePhase.RUNNING
            and self.flow.steps == 0
            and now - self._first_state_at > self.first_action_timeout
        ):
            aborted = self.flow.unanswered(
                f'no action for the first state within first_action_timeout '
                f'{self.first_action_timeout:g} s (the state or the action was lost: an agent '
                'that restarted may not have been matched yet)'
            )
            if aborted is not None:
                self._publish_aborted(aborted)

    def _on_restart_episode(self, request, response):
        """rl_env/restart_episode: a node of the loop was restarted under the episode."""
        restarted = 'agent' if request.restarted == RestartEpisode.Request.AGENT else 'simulator'
        why = f'the {restarted} was restarted' + (f' ({request.reason})' if request.reason else '')
        if restarted == 'agent':
            summary = self._agent_gone(why)
        else:
            self.robot.cancel()  # whatever the robot was asked to do is void
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
        self.robot.cancel()  # its answer would be stale
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
        an_agent = f'publishing {TOPICS["action"]}, subscribed to {TOPICS["state"]}'
        readers = self.agent.step_readers() >= self.step_readers
        needs = {
            f'the robot: {self.robot.describe()}': self.robot.ready(),
            f'an agent ({an_agent})': self.agent.agent_connected(),
            f'{self.step_readers} readers of {TOPICS["step_info"]}': readers,
        }
        start, waiting = self._gate.check(now, needs, self.start_delay)
        if waiting is not None:
            self.get_logger().info(waiting)
        if start:
            self._start_episode()

    # --- episodes -------------------------------------------------------------------------------

    def _start_episode(self) -> None:
        """Reset the robot to the start; the episode's first state follows."""
        token, start = self.flow.begin_reset()
        self.robot.reset(Pose(*start), functools.partial(self._reset_done, token))

    def _reset_done(self, token: int, problem: str, t: float) -> None:
        """The robot is at the start (at its clock's t, when it says): the first state goes
        out."""
        if problem:
            if self.flow.reset_failed(token):
                self._gate.retry_at(time.monotonic() + RESET_RETRY)
                if self._reset_failed_log():
                    what = 'the drive to the start'
                    what = self.reset_service if self.reset_by_teleport else what
                    self.get_logger().error(
                        f'{what} failed: {problem}; trying again in {RESET_RETRY:g} s'
                    )
            return
        self._sim_time = max(self._sim_time, t)  # the robot's clock ran on while it was placed
        state = self.flow.reset_done(token, self._sim_time)
        if state is None:
            return  # stale: the agent went away meanwhile
        self.agent.publish_state(state, start=self.scenario.start, episode=self.flow.episode)
        self.scene.publish_sensed(self._sim_time)
        self._first_state_at = time.monotonic()
        self.get_logger().debug(f'episode {self.flow.episode} started at state {list(state)}')

    def _on_action(self, message: RLAction) -> None:
        problem = self.flow.accept_action(message.action)
        if problem is not None:
            counts = self.flow.counts
            self.get_logger().warning(
                f'{problem} ({counts.actions_dropped} of {counts.actions_received} actions '
                'dropped so far)'
            )
            return
        self._run(self.flow.token, self.flow.move_for_action(self._sim_time))

    def _run(self, token: int, move) -> None:
        self.robot.run(move, functools.partial(self._on_move_end, token))

    def _on_move_end(self, token: int, end: MoveEnd) -> None:
        """A move ended (DONE, BUMPED or TIMED_OUT) with these poses at this time: judge it, or
        first back a bumped drive off and retry it, or pad it. A move that cannot run aborts."""
        if end.outcome is None:
            self._abort(token, end.message)
            return
        reason = self.robot.not_responding()
        if reason:
            self._give_up(token, reason)
            return
        truth_known = end.truth is not None
        estimate = PlanarPose(*end.estimate)
        truth = PlanarPose(*end.truth) if truth_known else estimate
        if not is_finite_pose(*estimate, *truth):
            self._abort(token, f'the robot reported a non-finite pose ({estimate}, {truth})')
            return
        stamp = time_msg(end.t)
        t = seconds(stamp)
        self._sim_time = max(self._sim_time, t)
        then, note = self.flow.move_ended(token, t, end.outcome, (end.outcome, end.message))
        if then is not None:  # a bumped drive's back-off or retry, or a hold to the slot's end
            self._run(token, then)
            return
        outcome, message = note
        try:
            report = self.flow.finish_move(token, estimate, truth, t)
        except ValueError as error:
            self._abort(token, f"{error}: does the robot run on the scenario's map?")
            return
        if report is None:
            return  # stale: already aborted (timeout) or the agent went away
        if outcome != DONE and self._move_note_log():
            self.get_logger().info(
                f'move {report.action} of episode {report.episode}, step {report.step}: {message}'
            )
        self.agent.publish_step(report, stamp, truth_known, self.flow.episode_time(t))
        self.scene.publish_sensed(t)
        if report.summary is not None:
            self._publish_summary(report.summary, stamp)

    def _give_up(self, token: int, reason: str) -> None:
        """The robot cannot be used: end the episode (the agent gets its terminal state), then
        exit with EXIT_ROBOT_NOT_RESPONDING once the messages are out."""
        self._abort(token, reason)
        self.get_logger().fatal(f'stopping: {reason}')
        self.exit_code = EXIT_ROBOT_NOT_RESPONDING
        self.robot.cancel()
        self.create_timer(STOP_DELAY, self._stop, clock=self._steady)

    def _stop(self) -> None:
        raise StopRequested(f'{NODE_NAME} gave up on its robot')

    def _abort(self, token: int, reason: str) -> None:
        aborted = self.flow.abort(token, reason)
        if aborted is not None:
            self._publish_aborted(aborted)

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

    def _publish_aborted(self, aborted: Aborted) -> None:
        """The terminal state (reward 0) that keeps the agent in step, and the summary."""
        self.agent.publish_state(aborted.state, 0.0, terminal=True)
        self._publish_summary(aborted.summary)
        self.get_logger().error(
            f'episode {aborted.summary.episode} ABORTED after {aborted.summary.steps} steps: '
            f'{aborted.reason}'
        )

    def _publish_summary(self, summary, stamp=None) -> None:
        self.agent.publish_summary(summary, stamp or time_msg(self._sim_time))
        self.get_logger().debug(
            f'episode {summary.episode}: {EpisodeOutcome(summary.outcome).name} after '
            f'{summary.steps} steps, return {summary.total_reward:.2f}'
        )
        self._window.append(summary)
        if self.log_every and len(self._window) >= self.log_every:
            self.get_logger().info(progress_line(self._window))
            self._window = []

    def _scene_time(self) -> float:
        """The lights' time to draw them at: the episode's clock (EpisodeFlow) at the latest
        simulated time the simulator reported, or at the ROS clock under use_sim_time."""
        t = self._sim_time
        if self.get_parameter('use_sim_time').value:
            t = max(t, self.get_clock().now().nanoseconds * 1e-9)
        return self.flow.episode_time(t)

    def log_totals(self) -> None:
        """The counts that show nothing was lost (a plain logger once the context is down)."""
        ok = self.context.ok()
        logger = self.get_logger() if ok else rclpy.logging.get_logger(f'{NODE_NAME}.exit')
        note = ''
        if self.flow.in_episode:
            note = f'; episode {self.flow.episode} was running ({self.flow.steps} steps)'
        logger.info(f'totals: {self.flow.counts.describe()}{note}')


def main(args=None) -> int:
    nodes = []

    def make_node() -> EnvironmentNode:
        nodes.append(EnvironmentNode())
        return nodes[-1]

    code = run_node(make_node, NODE_NAME, args=args, on_exit=EnvironmentNode.log_totals)
    return code or (nodes[0].exit_code if nodes else 0)


if __name__ == '__main__':
    raise SystemExit(main())
