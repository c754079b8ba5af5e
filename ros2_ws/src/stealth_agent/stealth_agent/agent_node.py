"""The agent node (``agent``): rl-texplore-ros-pkg's rl_agent protocol over the tabular learners.

Everything it decides is in the plain-Python core: what it does with each message in
agent_loop.py, over protocol.py, learners.py, prioritized_sweeping.py, schedules.py,
state_index.py, policy_store.py, agent_parameters.py, agent_setup.py, agent_messages.py,
grid_agent.py, policy_plugins.py and progress.py; this node translates messages and parameters.

## Topics

Names and QoS from ``stealth_node_kit.rl_contract``; every type is stealth_interfaces'.

* subscribes ``rl_env/rl_env_description`` (RLEnvDescription; reliable, transient local) and
  ``rl_env/rl_state_reward`` (RLStateReward; reliable, volatile);
* subscribes ``rl_env/observation`` (GridObservation; reliable, transient local) when
  ``agent`` is a policy plugin (``agent: generalist``: ``policy_plugins``, ``grid_agent``); it
  then subscribes ``rl_env/rl_state_reward`` only once it has planned on the first grid (the
  environment waits for that reader before it starts an episode);
* subscribes ``episode_summary_topic`` (EpisodeSummary, ``rl_env/episode_summary``; reliable,
  transient local), when the environment publishes it (stealth_env does): see Episode endings;
* publishes ``rl_agent/rl_action`` (RLAction) after every non-terminal state, and
  ``rl_agent/rl_experiment_info`` (RLExperimentInfo) and ``rl_agent/episode_info``
  (AgentEpisodeInfo: greedy or not, epsilon, alpha; transient local) at every terminal state;
* publishes, with ``agent: light-model``, its belief of the lights as two
  nav_msgs/OccupancyGrid in the ``map`` frame (reliable, transient local, depth 1):
  ``~/light_belief`` (the most likely light field, 100 = the detection threshold) and
  ``~/light_belief_uncertain`` (how evenly the hypotheses split on a cell being lit, 0 = all
  agree, 100 = an even split), -1 on walls (``stealth_core.light_belief_map``); built once
  the model is attached and after every learning episode, only while someone subscribes.

## Services

None: the agent only answers states.

## Parameters

The table in ``stealth_agent.agent_parameters``. The learner settings may change while running;
a value that would not make a usable agent is refused, at startup and at runtime. With
eval_every M > 0, every M-th episode of a learning run is a greedy evaluation (epsilon 0, no
updates, the schedules stand still), so an experiment can watch the learned policy itself.

## Episode endings

An environment that also publishes EpisodeSummary tells the agent how each episode ended: a
TIMEOUT is then a truncation, not a terminal state (the last update bootstraps from the final
state, so the agent does not learn that running out of time is cheap), and an ABORTED episode
teaches nothing. A terminal state waits for its summary as long as the environment (a summary
publisher) is there, with a warning every summary_wait seconds: a summary that is only late, on
a loaded machine, never turns into a guess, so the same seed learns the same episodes whatever
the load. Only when no publisher is left is the state learned as terminal. A plain rl_msgs
environment, with no summary publisher, gets rl_agent's behaviour. A restarted environment is
told by its states' DDS sequence numbers starting again (the old episode is dropped there,
whenever its latched description arrives).

## Time

The node's ROS clock stamps AgentEpisodeInfo: simulated time under ``use_sim_time`` (every node
of a ``stealth train`` topics run). The clock is read only there, so its ``/clock`` messages
wait in their queue until then (``stealth_node_kit.on_demand``) instead of waking the node at
every control period of the simulator (~5 ms of CPU per RL step in a topics run). The summary
wait stays on wall time: it waits for a message from the environment, not for the robot, and
must not stand still with a stopped clock.

## Decision time

Each answered state's time from the node's callback to its action published is kept; the
totals line at exit gives its mean, median, p95 and max over the last DECISIONS_KEPT, and the
thread's CPU time of the same (wall minus CPU: waiting for a core on a loaded machine)
(``bench/bench_generalist_ros.py``).

## Bad input

An unusable description, a state before any description, a state whose length changes, a
non-finite reward, an unusable policy file: each is logged with what is wrong and the message
skipped; the node stays up and the table is never touched by a rejected message.
"""

from collections import deque
import time

from nav_msgs.msg import OccupancyGrid
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from stealth_core.light_belief_map import BeliefMapper
from stealth_interfaces.msg import (
    AgentEpisodeInfo,
    EpisodeSummary,
    GridObservation,
    RLAction,
    RLEnvDescription,
    RLExperimentInfo,
    RLStateReward,
)
from stealth_node_kit import rl_contract
from stealth_node_kit.endpoints import (
    QUIET_PUBLISHER,
    QUIET_SUBSCRIPTION,
    warn_publisher,
    warn_subscription,
)
from stealth_node_kit.on_demand import OnDemand, clock_on_demand
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.running import StartupNode, run_node

from .agent_loop import AgentLoop
from .agent_messages import belief_msgs
from .agent_parameters import (
    LIVE_LEARNER_PARAMETERS,
    PARAMETERS,
    change_problem,
    is_light_model,
    learner_config,
    learns,
    startup_problem,
)
from .light_model import LightModelLearner
from .policy_plugins import is_plugin
from .progress import totals_line

BELIEF_TOPIC = '~/light_belief'  # the light model's most likely light field
UNCERTAIN_TOPIC = '~/light_belief_uncertain'  # and where its hypotheses disagree
DECISIONS_KEPT = 100_000  # the latest decision times the totals line summarises
# s of wall time between checks, while a terminal state waits for its summary, that the
# environment is still there (only its leaving ends the wait; see SummaryWait).
SUMMARY_CHECK_PERIOD = 0.5
INCOMPATIBLE_QOS = (
    'an environment endpoint of the RL loop has QoS incompatible with the agent ({policy}): '
    'states or actions do not get through; the RL topics are reliable and volatile'
)


class AgentNode(StartupNode):
    """rl_agent for rl_msgs environments, with Q-learning, SARSA, Dyna-Q and prioritized sweeping
    (or a policy plugin's policy): the ROS shell of AgentLoop, which it serves as the loop's
    Ports."""

    def __init__(self):
        super().__init__('agent')

    def set_up(self) -> None:
        self._loop: AgentLoop | None = None
        self._declared = False
        self._summary_sub = None
        self._summary_unmatched_told = False
        self._beliefs_shown = 0
        self._decisions = deque(maxlen=DECISIONS_KEPT)  # s from a state's callback to its action
        self._decisions_cpu = deque(maxlen=DECISIONS_KEPT)  # the thread's CPU s of the same
        self._clock_messages = OnDemand()
        clock_on_demand(self, self._clock_messages)

        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        declare_parameters(self, PARAMETERS)
        self._declared = True
        problem = startup_problem(self.values())
        if problem is not None:
            raise StartupError(problem)
        self._loop = AgentLoop(self)

        # Every QoS event handler is one more entity in each of the executor's waits (rclpy's
        # defaults: several per endpoint, most of the agent's per-step executor work): only the
        # two endpoints of the step keep one, the incompatible-QoS warning of a silent loop.
        self._action_pub = self.create_publisher(
            RLAction,
            rl_contract.ACTION,
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=warn_publisher(self.get_logger, INCOMPATIBLE_QOS),
        )
        self._info_pub = self.create_publisher(
            RLExperimentInfo,
            rl_contract.EXPERIMENT_INFO,
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=QUIET_PUBLISHER,
        )
        self._episode_info_pub = self.create_publisher(
            AgentEpisodeInfo,
            rl_contract.AGENT_EPISODE_INFO,
            rl_contract.AGENT_EPISODE_INFO_QOS,
            event_callbacks=QUIET_PUBLISHER,
        )
        self._belief_pubs = ()
        self._belief_mapper: BeliefMapper | None = None
        if is_light_model(self.param('agent')):
            self._belief_pubs = tuple(
                self.create_publisher(OccupancyGrid, topic, rl_contract.DESCRIPTION_QOS,
                                      event_callbacks=QUIET_PUBLISHER)
                for topic in (BELIEF_TOPIC, UNCERTAIN_TOPIC)
            )  # fmt: skip
        self.create_subscription(
            RLEnvDescription,
            rl_contract.ENV_DESCRIPTION,
            self._loop.on_description,
            rl_contract.DESCRIPTION_QOS,
            event_callbacks=QUIET_SUBSCRIPTION,
        )
        self._state_sub = None
        if is_plugin(self.param('agent')):  # a policy plugin decides on the grid: states
            self.create_subscription(  # only once it planned on one (accept_states)
                GridObservation,
                rl_contract.OBSERVATION,
                self._loop.on_observation,
                rl_contract.DESCRIPTION_QOS,
                event_callbacks=QUIET_SUBSCRIPTION,
            )
        else:
            self.accept_states()
        summary_topic = self.param('episode_summary_topic')
        if summary_topic:
            self._summary_sub = self.create_subscription(
                EpisodeSummary,
                summary_topic,
                self._loop.on_summary,
                rl_contract.REPORT_READER_QOS,
                event_callbacks=QUIET_SUBSCRIPTION,
            )
        self._summary_timer = self.create_timer(
            min(SUMMARY_CHECK_PERIOD, self.param('summary_wait')),
            self._loop.check_summary_wait,
            clock=Clock(clock_type=ClockType.STEADY_TIME),
        )
        self._summary_timer.cancel()
        learning = learns(self.values())
        mode = 'learning' if learning else 'evaluating (greedy, no learning)'
        self.get_logger().info(
            f'agent {self.param("agent")} {mode}; waiting for rl_env/rl_env_description'
        )

    # --- parameters --------------------------------------------------------------------------

    def param(self, name: str):
        return self.get_parameter(name).value

    def values(self) -> dict:
        """Every parameter's value by name."""
        return {name: self.param(name) for name in PARAMETERS}

    def _validate_parameters(self, parameters) -> SetParametersResult:
        """Reject values that would not make a usable agent (at startup and at runtime)."""
        reason = non_finite(parameters)
        if reason is None:
            changes = [(p.name, p.value) for p in parameters]
            reason = change_problem(changes, self.values() if self._declared else None)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters) -> None:
        names = {p.name for p in parameters}
        core = self._loop.core if self._loop is not None else None
        if core is not None and self._loop.learning_run and LIVE_LEARNER_PARAMETERS & names:
            core.learner.set_config(learner_config(self.values()))
            changed = ', '.join(f'{p.name}={p.value}' for p in parameters)
            self.get_logger().info(f'learner settings changed: {changed}')

    # --- the loop's ports --------------------------------------------------------------------

    def _on_state(self, msg: RLStateReward, info: dict) -> None:
        started, cpu, sent = time.perf_counter(), time.thread_time(), self._loop.actions_sent
        self._loop.on_state(msg, info.get('publication_sequence_number'))
        if self._loop.actions_sent > sent:  # the decision time of an answered state
            self._decisions.append(time.perf_counter() - started)
            self._decisions_cpu.append(time.thread_time() - cpu)

    def accept_states(self) -> None:
        """Subscribe to the states (once). The environment starts an episode only when this
        reader is matched, so a policy plugin, which subscribes once its plan is ready (loading
        JAX and compiling take seconds), never has a first state time out unanswered."""
        if self._state_sub is None:
            self._state_sub = self.create_subscription(
                RLStateReward,
                rl_contract.STATE,
                self._on_state,
                rl_contract.LOCKSTEP_QOS,
                event_callbacks=warn_subscription(self.get_logger, INCOMPATIBLE_QOS),
            )

    def show_learner(self, learner) -> None:
        """The light model's belief on its two grids, while someone subscribes to either."""
        if not isinstance(learner, LightModelLearner) or learner.belief is None:
            return
        if not any(pub.get_subscription_count() for pub in self._belief_pubs):
            return
        started = time.perf_counter()
        if self._belief_mapper is None or self._belief_mapper.world is not learner.world:
            self._belief_mapper = BeliefMapper(learner.world)
        arrays = learner.belief_arrays()
        grid = self._belief_mapper.grid(arrays['lights'], arrays['weights'])
        self._clock_messages.drain()  # the latest /clock, under use_sim_time
        now = self.get_clock().now().nanoseconds * 1e-9
        for pub, message in zip(self._belief_pubs, belief_msgs(grid, now), strict=True):
            pub.publish(message)
        seconds = time.perf_counter() - started
        self._beliefs_shown += 1
        (self.get_logger().info if self._beliefs_shown == 1 else self.get_logger().debug)(
            f'light belief published ({grid.width} x {grid.height} cells of '
            f'{grid.resolution:g} m, {len(arrays["weights"])} hypotheses) in '
            f'{seconds * 1e3:.1f} ms'
        )

    def send_action(self, action: int) -> None:
        self._action_pub.publish(RLAction(action=action))

    def send_reports(self, info: RLExperimentInfo, episode: AgentEpisodeInfo) -> None:
        self._info_pub.publish(info)
        self._clock_messages.drain()  # the latest /clock, under use_sim_time
        episode.header.stamp = self.get_clock().now().to_msg()
        self._episode_info_pub.publish(episode)

    def environment_reports_endings(self) -> bool:
        """Whether some environment publishes EpisodeSummary: then a terminal state waits for
        its summary to know whether it ended the task or only the time allowed."""
        if self._summary_sub is None:
            return False
        if self._summary_sub.get_publisher_count() > 0:
            return True
        topic = self._summary_sub.topic_name
        if not self._summary_unmatched_told and self.count_publishers(topic):
            self._summary_unmatched_told = True
            self.get_logger().warning(
                f'{topic} has a publisher that is not matched with the '
                'agent (its QoS must be reliable and transient local, or DDS is still matching '
                'it): terminal states are learned as rl_msgs says, a timeout as terminal'
            )
        return False

    def start_summary_timer(self) -> None:
        self._summary_timer.reset()

    def stop_summary_timer(self) -> None:
        self._summary_timer.cancel()

    def exit_logger(self):
        """A context shut down (not by a signal: the node stops with it up) cannot take /rosout."""
        return self.get_logger() if self.context.ok() else rclpy.logging.get_logger('agent.exit')

    # --- exit --------------------------------------------------------------------------------

    def finish(self) -> None:
        """At exit: the totals (what a lost or doubled message would show in), then save."""
        loop = self._loop
        line = totals_line(
            loop.states_received, loop.actions_sent, self._decisions, self._decisions_cpu,
            loop.plan_seconds,
        )  # fmt: skip
        self.exit_logger().info(line)
        loop.save('shutdown')


def main(args=None) -> int:
    return run_node(AgentNode, 'agent', args=args, on_exit=AgentNode.finish)


if __name__ == '__main__':
    raise SystemExit(main())
