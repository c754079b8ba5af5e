"""The agent node (``agent``): rl-texplore-ros-pkg's rl_agent protocol over the tabular learners.

Everything it decides is in the plain-Python core (protocol.py, learners.py, schedules.py,
state_index.py, policy_store.py, agent_parameters.py, agent_setup.py, agent_messages.py,
progress.py); this node translates messages and parameters.

## Topics

Names and QoS from ``stealth_node_kit.rl_contract``; every type is stealth_interfaces'.

* subscribes ``rl_env/rl_env_description`` (RLEnvDescription; reliable, transient local) and
  ``rl_env/rl_state_reward`` (RLStateReward; reliable, volatile);
* subscribes ``episode_summary_topic`` (EpisodeSummary, ``rl_env/episode_summary``; reliable,
  transient local), when the environment publishes it (stealth_env does): see Episode endings;
* publishes ``rl_agent/rl_action`` (RLAction) after every non-terminal state, and
  ``rl_agent/rl_experiment_info`` (RLExperimentInfo) and ``rl_agent/episode_info``
  (AgentEpisodeInfo: greedy or not, epsilon, alpha; transient local) at every terminal state.

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

## Bad input

An unusable description, a state before any description, a state whose length changes, a
non-finite reward, an unusable policy file: each is logged with what is wrong and the message
skipped; the node stays up and the table is never touched by a rejected message.
"""

import time

from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from stealth_interfaces.msg import (
    AgentEpisodeInfo,
    EpisodeSummary,
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
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.running import StartupNode, run_node

from .agent_messages import (
    StateWriters,
    description_from_msg,
    episode_info,
    experiment_info,
    outcome_ending,
    outcome_name,
    reported_reward,
)
from .agent_parameters import (
    LIVE_LEARNER_PARAMETERS,
    PARAMETERS,
    change_problem,
    learner_config,
    startup_problem,
)
from .agent_setup import set_up_agent
from .policy_store import save_policy
from .progress import ProgressLog, evaluation_line, totals_line
from .protocol import (
    BadInputError,
    Ending,
    EnvDescription,
    EpisodeEndMatcher,
    ProtocolAgent,
    ResolvedEnd,
    SummaryWait,
    is_greedy_episode,
)

# s of wall time between checks, while a terminal state waits for its summary, that the
# environment is still there (only its leaving ends the wait; see SummaryWait).
SUMMARY_CHECK_PERIOD = 0.5
INCOMPATIBLE_QOS = (
    'an environment endpoint of the RL loop has QoS incompatible with the agent ({policy}): '
    'states or actions do not get through; the RL topics are reliable and volatile'
)


class AgentNode(StartupNode):
    """rl_agent for rl_msgs environments, with Q-learning, SARSA and Dyna-Q."""

    def __init__(self):
        super().__init__('agent')

    def set_up(self) -> None:
        self._core: ProtocolAgent | None = None
        self._description: EnvDescription | None = None
        self._setup_error = ''
        self._progress = ProgressLog()
        self._states_received = 0  # for the shutdown totals, as the environment logs its own
        self._early_state: RLStateReward | None = None  # the latest before any description
        self._state_writers = StateWriters()
        self._actions_sent = 0
        self._declared = False
        self._endings = EpisodeEndMatcher()
        self._summary_sub = None
        self._summary_unmatched_told = False

        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        declare_parameters(self, PARAMETERS)
        self._declared = True
        problem = startup_problem(self._values())
        if problem is not None:
            raise StartupError(problem)

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
        self.create_subscription(
            RLEnvDescription,
            rl_contract.ENV_DESCRIPTION,
            self._on_description,
            rl_contract.DESCRIPTION_QOS,
            event_callbacks=QUIET_SUBSCRIPTION,
        )
        self.create_subscription(
            RLStateReward,
            rl_contract.STATE,
            self._on_state,
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=warn_subscription(self.get_logger, INCOMPATIBLE_QOS),
        )
        summary_topic = self._param('episode_summary_topic')
        if summary_topic:
            self._summary_sub = self.create_subscription(
                EpisodeSummary,
                summary_topic,
                self._on_summary,
                rl_contract.REPORT_READER_QOS,
                event_callbacks=QUIET_SUBSCRIPTION,
            )
        self._summary_wait = SummaryWait(self._param('summary_wait'))
        self._summary_timer = self.create_timer(
            min(SUMMARY_CHECK_PERIOD, self._param('summary_wait')),
            self._check_summary_wait,
            clock=Clock(clock_type=ClockType.STEADY_TIME),
        )
        self._summary_timer.cancel()
        mode = 'evaluating (greedy, no learning)' if self._param('evaluate') else 'learning'
        self.get_logger().info(
            f'agent {self._param("agent")} {mode}; waiting for rl_env/rl_env_description'
        )

    # --- parameters --------------------------------------------------------------------------

    def _param(self, name: str):
        return self.get_parameter(name).value

    def _values(self) -> dict:
        """Every parameter's value by name."""
        return {name: self._param(name) for name in PARAMETERS}

    def _validate_parameters(self, parameters) -> SetParametersResult:
        """Reject values that would not make a usable agent (at startup and at runtime)."""
        reason = non_finite(parameters)
        if reason is None:
            changes = [(p.name, p.value) for p in parameters]
            reason = change_problem(changes, self._values() if self._declared else None)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters) -> None:
        names = {p.name for p in parameters}
        if self._core is not None and self._learning_run and LIVE_LEARNER_PARAMETERS & names:
            self._core.learner.set_config(learner_config(self._values()))
            changed = ', '.join(f'{p.name}={p.value}' for p in parameters)
            self.get_logger().info(f'learner settings changed: {changed}')

    @property
    def _learning_run(self) -> bool:
        """Whether this run learns (greedy evaluation episodes in between or not)."""
        return not self._param('evaluate')

    # --- messages ----------------------------------------------------------------------------

    def _on_description(self, msg: RLEnvDescription) -> None:
        log = self.get_logger()
        try:
            description = description_from_msg(msg)
        except BadInputError as error:
            log.error(f'{error}; description ignored, waiting for a usable one')
            return
        if self._core is not None:
            self._description_again(description)
            return
        self._description = description
        self._setup(description)
        early, self._early_state = self._early_state, None
        if early is not None and self._core is not None:
            log.info('answering the state that came before the description')
            self._handle_state(early)

    def _description_again(self, description: EnvDescription) -> None:
        log = self.get_logger()
        other = description.other_environment(self._description)
        if other is not None:
            log.error(
                f'a different environment description arrived ({other}); ignored, restart the '
                'agent to switch environments'
            )
            return
        if self._state_writers.last is not None:
            # The states' sequence numbers tell when a new environment's states begin (see
            # _on_state), and this latched description may come after them, on a writer DDS
            # matched later: an episode in progress now may be the new environment's.
            log.warning(
                'environment description received again (environment restarted?); keeping the '
                "table; the new environment's first state ends the old episode, if one is open"
            )
            return
        note = self._drop_episode()
        log.warning(
            f'environment description received again (environment restarted?); '
            f'keeping the table{note}'
        )

    def _drop_episode(self) -> str:
        """The environment restarted: the episode in progress (if any) is void; a note saying
        what was dropped."""
        aborted = self._core.abort()
        self._endings.new_episode()
        self._stop_waiting()
        return f'; dropped the episode in progress ({aborted.actions} actions)' if aborted else ''

    def _setup(self, description: EnvDescription) -> None:
        """Build (or load) the learner for this environment; on failure stay idle, alive."""
        log = self.get_logger()
        setup = set_up_agent(description, self._values())
        for warning in setup.warnings:
            log.warning(warning)
        if setup.core is None:
            self._setup_error = setup.error
            log.error(
                f'{setup.error}; the agent will not act (and will not overwrite the file): '
                'fix or remove it, then restart the agent'
            )
            return
        self._core = setup.core
        self._setup_error = ''
        log.info(setup.summary)

    def _on_state(self, msg: RLStateReward, info: dict) -> None:
        log = self.get_logger()
        self._states_received += 1
        if self._state_writers.new_writer(info.get('publication_sequence_number')):
            note = self._drop_episode() if self._core is not None else ''
            if note:
                log.warning(f'a new environment is sending states (restarted){note}')
        if self._core is None:
            if self._description is None:
                # Its writer may be matched before the latched description's (a restarted
                # agent): held, not dropped, or the environment would wait for its answer.
                self._early_state = msg
                log.warning(
                    'rl_state_reward received before any environment description '
                    '(rl_env/rl_env_description); held until the description arrives'
                )
            else:
                log.error(
                    f'rl_state_reward skipped: the agent is not usable ({self._setup_error})'
                )
            return
        self._handle_state(msg)

    def _handle_state(self, msg: RLStateReward) -> None:
        if not self._core.in_episode:
            if not msg.terminal:  # (a report may have come before a terminal first state)
                self._endings.new_episode()
            if self._learning_run:
                greedy = is_greedy_episode(self._core.episode, self._param('eval_every'))
                self._core.set_learning(not greedy)
        if msg.terminal and self._environment_reports_endings():
            # Before any action too: an environment ends an episode whose first state got no
            # answer (lost to a restarted agent) ABORTED, and that is what is learned (nothing).
            self._wait_for_summary(msg)
            return
        self._process(msg.state, msg.reward, msg.terminal)

    def _process(self, state, reward, terminal: bool, ending=Ending.TERMINATED) -> None:
        log = self.get_logger()
        try:
            step = self._core.handle(state, reward, terminal, ending)
        except BadInputError as error:
            log.error(f'rl_state_reward skipped: {error}')
            return
        for note in step.notes:
            warning = self._progress.out_of_range(note)
            if warning is not None:
                log.warning(warning)
        if step.action is not None:
            self._action_pub.publish(RLAction(action=step.action))
            self._actions_sent += 1
        if step.result is not None:
            self._episode_done(step.result)

    # --- how an episode ended ----------------------------------------------------------------

    def _environment_reports_endings(self) -> bool:
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

    def _wait_for_summary(self, msg: RLStateReward) -> None:
        try:  # a bad terminal state is refused now, not after the wait
            self._core.check_state_reward(msg.state, msg.reward)
        except BadInputError as error:
            self.get_logger().error(f'rl_state_reward skipped: {error}')
            return
        resolved = self._endings.terminal(msg.state, msg.reward, self._core.number_actions)
        if resolved is None:
            self._summary_wait.start(time.monotonic())
            self._summary_timer.reset()
        else:
            self._end_episode(resolved)

    def _check_summary_wait(self) -> None:
        """While a terminal state waits: give up only when no environment is left to send the
        summary (a slow one is waited for: wall time must not change what is learned)."""
        now = time.monotonic()
        waited = self._summary_wait.waited(now)
        verdict = self._summary_wait.tick(now, self._environment_reports_endings())
        if verdict == 'warn':
            self.get_logger().warning(
                f'still waiting for the EpisodeSummary of episode {self._core.episode} '
                f'({waited:.0f} s after its terminal state); the environment is there, so the '
                'agent keeps waiting (a stuck environment needs a restart)'
            )
        elif verdict == 'give up':
            self._summary_timer.cancel()
            resolved = self._endings.give_up()
            if resolved is not None:
                self.get_logger().warning(
                    f'the environment left {waited:.1f} s after the terminal state of episode '
                    f'{self._core.episode}, without its EpisodeSummary; learned as terminal'
                )
                self._end_episode(resolved)
        elif not self._endings.waiting:
            self._stop_waiting()

    def _stop_waiting(self) -> None:
        self._summary_timer.cancel()
        self._summary_wait.stop()

    def _end_episode(self, resolved: ResolvedEnd) -> None:
        self._stop_waiting()
        ending = resolved.ending
        if ending is Ending.TRUNCATED and self._param('timeout_is_terminal'):
            ending = Ending.TERMINATED
        if resolved.episode is not None:
            # The environment numbers the episodes: after a restart of either side (an episode
            # dropped by one of them) both still name each episode alike.
            self._core.episode = resolved.episode
        self._process(resolved.state, resolved.reward, True, ending)

    def _episode_done(self, result) -> None:
        learner, table_rows = self._core.learner, len(self._core.index)
        self._info_pub.publish(experiment_info(result))
        info = episode_info(result, learner, table_rows)
        info.header.stamp = self.get_clock().now().to_msg()
        self._episode_info_pub.publish(info)
        if self._learning_run and not result.learning:
            line = evaluation_line(result, reported_reward(result), learner.episodes)
            self.get_logger().info(line)
        line = self._progress.episode(
            result, table_rows=table_rows, log_every=self._param('log_every')
        )
        if line is not None:
            self.get_logger().info(line)
        save_every = self._param('save_every')
        if save_every and self._learning_run and self._core.episode % save_every == 0:
            self.save(f'every {save_every} episodes')

    def _on_summary(self, msg: EpisodeSummary) -> None:
        if self._core is None or msg.episode < self._param('first_episode'):
            return  # from before this agent's first episode (the history a late reader gets)
        self._progress.outcome(outcome_name(msg.outcome))
        resolved = self._endings.report(msg.steps, outcome_ending(msg.outcome), int(msg.episode))
        if resolved is not None:
            self._end_episode(resolved)

    # --- policy file -------------------------------------------------------------------------

    def finish(self) -> None:
        """At exit: the totals (what a lost or doubled message would show in), then save."""
        self._exit_logger().info(totals_line(self._states_received, self._actions_sent))
        self.save('shutdown')

    def _exit_logger(self):
        """After Ctrl-C the context is already shut down and /rosout cannot take the message."""
        return self.get_logger() if self.context.ok() else rclpy.logging.get_logger('agent.exit')

    def save(self, reason: str) -> bool:
        """Save the learned policy atomically, if learning with a policy file."""
        path = self._param('policy_file')
        if self._core is None or not self._learning_run or not path:
            return False
        learner, index = self._core.learner, self._core.index
        log = self._exit_logger()
        try:
            save_policy(
                path,
                learner,
                index,
                scenario=self._description.identity(),
                rng=self._core.rng,
                extra={'seed': self._param('seed'), 'reason': reason},
            )
        except (OSError, ValueError) as error:
            log.error(f'could not save the policy to {path}: {error}')
            return False
        log.info(
            f'saved the policy to {path} ({reason}; {learner.episodes} episodes, '
            f'{len(index)} states)'
        )
        return True


def main(args=None) -> int:
    return run_node(AgentNode, 'agent', args=args, on_exit=AgentNode.finish)


if __name__ == '__main__':
    raise SystemExit(main())
