"""The agent's side of the RL loop, as plain Python (no rclpy): what the agent node does with
each message it gets.

A description builds the core (agent_setup) and answers a state that came before it. A state
is answered by ProtocolAgent, every eval_every-th episode of a learning run greedily. A
terminal state waits for the environment's EpisodeSummary as long as an environment reports
endings (EpisodeEndMatcher pairs the two, SummaryWait paces the wait, on the wall clock: only
the environment's leaving ends it, so the load of the machine never changes what is learned).
A restarted environment (its description again, or its states' DDS sequence numbers starting
again) drops the episode in progress. Each finished episode is reported, logged (progress) and,
every save_every, saved; the learner's notes (the light model's contradictions) are logged once
each, and after a learning episode the node shows the learner (the light model's belief). A
policy plugin's core (``grid_agent``) also needs the environment's GridObservation: a state
that comes before it (on the sensed track: before the grid it matches) is held, and answered
when it arrives.

The node passes itself in as the Ports (its parameters, logger, publishers, the summary timer
that calls check_summary_wait, and whether an environment publishes summaries), so all of
this runs and is tested without ROS.
"""

from collections.abc import Callable
import time
from typing import Protocol

from stealth_interfaces.msg import AgentEpisodeInfo, RLExperimentInfo
from stealth_node_kit.full_disk import DiskFullError, is_disk_full

from .agent_messages import (
    StateWriters,
    description_from_msg,
    episode_info,
    experiment_info,
    grid_from_msg,
    keyed_description,
    keyed_state,
    outcome_ending,
    outcome_name,
    reported_reward,
)
from .agent_parameters import learns
from .agent_setup import set_up_agent
from .grid_agent import GridPolicyAgent
from .policy_store import CONTENT_KEYS, save_policy
from .progress import ProgressLog, evaluation_line
from .protocol import (
    BadInputError,
    Ending,
    EnvDescription,
    EpisodeEndMatcher,
    EpisodeResult,
    ProtocolAgent,
    ResolvedEnd,
    SummaryWait,
    is_greedy_episode,
)


class Ports(Protocol):
    """What the loop needs of its node."""

    def param(self, name: str): ...  # a parameter's current value (agent_parameters)

    def values(self) -> dict: ...  # every parameter's value by name

    def get_logger(self): ...  # .info, .warning, .error

    def exit_logger(self): ...  # the logger that still works after Ctrl-C

    def send_action(self, action: int) -> None: ...

    def send_reports(self, info: RLExperimentInfo, episode: AgentEpisodeInfo) -> None: ...

    def environment_reports_endings(self) -> bool: ...  # some EpisodeSummary publisher is there

    def start_summary_timer(self) -> None: ...

    def stop_summary_timer(self) -> None: ...

    def accept_states(self) -> None: ...  # subscribe to the states, if not yet (a plugin's)

    def show_learner(self, learner) -> None: ...  # after it changed: what a viewer may watch


class AgentLoop:
    """rl_agent's message handling over the plain-Python core; see the module docstring."""

    def __init__(self, ports: Ports, clock: Callable[[], float] = time.monotonic):
        self._ports = ports
        self._clock = clock  # wall time of the summary wait (s)
        self.core: ProtocolAgent | None = None
        self.description: EnvDescription | None = None
        self._setup_error = ''
        self._progress = ProgressLog()
        self.disk_full = False  # a save failed for want of space: no more saves
        self.states_received = 0  # for the shutdown totals, as the environment logs its own
        self.actions_sent = 0
        self._early_state = None  # the latest state before any description (or grid)
        self._early_grid = None  # a GridObservation before the core
        self.plan_seconds: list[float] = []  # a policy plugin's time to plan on each grid (s)
        self._state_writers = StateWriters()
        self._endings = EpisodeEndMatcher()
        self._summary_wait = SummaryWait(ports.param('summary_wait'))
        self._notes_told: set[str] = set()  # the learner's notes logged so far

    @property
    def learning_run(self) -> bool:
        """Whether this run learns (greedy evaluation episodes in between or not)."""
        return learns(self._ports.values())

    # --- the environment ---------------------------------------------------------------------

    def on_description(self, msg) -> None:
        """An RLEnvDescription."""
        log = self._ports.get_logger()
        try:
            features = self._ports.param('state_features')
            described = description_from_msg(msg)
            description = keyed_description(described, features)
        except BadInputError as error:
            log.error(f'{error}; description ignored, waiting for a usable one')
            return
        length = len(described.min_state_range)
        if self.core is None and features and length > features:
            log.info(f"the table keys on the state's first {features} of {length} features")
        if self.core is not None:
            self._description_again(description)
            return
        self.description = description
        self._setup(description)
        grid, self._early_grid = self._early_grid, None
        if grid is not None and self.core is not None:
            self.on_observation(grid)
        early, self._early_state = self._early_state, None
        if early is not None and self.core is not None:
            log.info('answering the state that came before the description')
            self.on_state(early, None, count=False)

    def _description_again(self, description: EnvDescription) -> None:
        log = self._ports.get_logger()
        other = description.other_environment(self.description)
        if other is not None:
            log.error(
                f'a different environment description arrived ({other}); ignored, restart the '
                'agent to switch environments'
            )
            return
        if self._state_writers.last is not None:
            # The states' sequence numbers tell when a new environment's states begin (see
            # on_state), and this latched description may come after them, on a writer DDS
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
        aborted = self.core.abort()
        self._endings.new_episode()
        self._stop_waiting()
        return f'; dropped the episode in progress ({aborted.actions} actions)' if aborted else ''

    def _setup(self, description: EnvDescription) -> None:
        """Build (or load) the learner for this environment; on failure stay idle, alive."""
        log = self._ports.get_logger()
        setup = set_up_agent(description, self._ports.values())
        for warning in setup.warnings:
            log.warning(warning)
        if setup.core is None:
            self._setup_error = setup.error
            log.error(
                f'{setup.error}; the agent will not act (and will not overwrite the file): '
                'fix or remove it, then restart the agent'
            )
            return
        self.core = setup.core
        self._setup_error = ''
        log.info(setup.summary)
        self._ports.show_learner(self.core.learner)

    # --- states ------------------------------------------------------------------------------

    def on_observation(self, msg) -> None:
        """A GridObservation: the grid a policy plugin decides on (ignored by a learner)."""
        if self.core is None:
            self._early_grid = msg
            return
        if not isinstance(self.core, GridPolicyAgent):
            return
        log = self._ports.get_logger()
        started = time.perf_counter()
        try:
            self.core.set_grid(grid_from_msg(msg))
        except ValueError as error:  # BadInputError, or the policy refused the layout
            log.error(f'{error}; grid observation ignored, the agent cannot act on it')
            return
        seconds = time.perf_counter() - started
        self.plan_seconds.append(seconds)
        (log.info if len(self.plan_seconds) == 1 else log.debug)(
            f'grid observation {msg.layout} ({msg.rows} x {msg.cols}; episode {msg.episode}, '
            f'step {msg.step}) planned on in {seconds:.3f} s'
        )
        self._ports.accept_states()
        early = self._early_state
        if early is not None and self.core.serves(early.state):
            self._early_state = None
            log.debug('answering the state that came before its grid observation')
            self.on_state(early, None, count=False)

    def on_state(self, msg, sequence: int | None, count: bool = True) -> None:
        """An RLStateReward, with its DDS sequence number (None where the middleware gives
        none)."""
        log = self._ports.get_logger()
        self.states_received += count
        plugin = isinstance(self.core, GridPolicyAgent)
        if plugin and not msg.terminal and not self.core.serves(msg.state):
            self._early_state = msg  # answered when its grid arrives (on_observation)
            if not self.core.ready:
                log.warning('rl_state_reward before any rl_env/observation; held until it arrives')
            return
        msg.state = keyed_state(msg.state, self._ports.param('state_features'))
        if self._state_writers.new_writer(sequence):
            note = self._drop_episode() if self.core is not None else ''
            if note:
                log.warning(f'a new environment is sending states (restarted){note}')
        if self.core is None:
            if self.description is None:
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

    def _handle_state(self, msg) -> None:
        if not self.core.in_episode:
            if not msg.terminal:  # (a report may have come before a terminal first state)
                self._endings.new_episode()
            if self.learning_run:
                greedy = is_greedy_episode(self.core.episode, self._ports.param('eval_every'))
                self.core.set_learning(not greedy)
        if msg.terminal and self._ports.environment_reports_endings():
            # Before any action too: an environment ends an episode whose first state got no
            # answer (lost to a restarted agent) ABORTED, and that is what is learned (nothing).
            self._wait_for_summary(msg)
            return
        self._process(msg.state, msg.reward, msg.terminal)

    def _process(self, state, reward, terminal: bool, ending=Ending.TERMINATED) -> None:
        log = self._ports.get_logger()
        try:
            step = self.core.handle(state, reward, terminal, ending)
        except BadInputError as error:
            log.error(f'rl_state_reward skipped: {error}')
            return
        for note in step.notes:
            warning = self._progress.out_of_range(note)
            if warning is not None:
                log.warning(warning)
        if step.action is not None:
            self._ports.send_action(step.action)
            self.actions_sent += 1
        if step.result is not None:
            self._episode_done(step.result)

    # --- how an episode ended ----------------------------------------------------------------

    def _wait_for_summary(self, msg) -> None:
        try:  # a bad terminal state is refused now, not after the wait
            self.core.check_state_reward(msg.state, msg.reward)
        except BadInputError as error:
            self._ports.get_logger().error(f'rl_state_reward skipped: {error}')
            return
        resolved = self._endings.terminal(msg.state, msg.reward, self.core.number_actions)
        if resolved is None:
            self._summary_wait.start(self._clock())
            self._ports.start_summary_timer()
        else:
            self._end_episode(resolved)

    def check_summary_wait(self) -> None:
        """While a terminal state waits (the summary timer): give up only when no environment
        is left to send the summary (a slow one is waited for: wall time must not change what
        is learned)."""
        now = self._clock()
        waited = self._summary_wait.waited(now)
        verdict = self._summary_wait.tick(now, self._ports.environment_reports_endings())
        if verdict == 'warn':
            self._ports.get_logger().warning(
                f'still waiting for the EpisodeSummary of episode {self.core.episode} '
                f'({waited:.0f} s after its terminal state); the environment is there, so the '
                'agent keeps waiting (a stuck environment needs a restart)'
            )
        elif verdict == 'give up':
            self._ports.stop_summary_timer()
            resolved = self._endings.give_up()
            if resolved is not None:
                self._ports.get_logger().warning(
                    f'the environment left {waited:.1f} s after the terminal state of episode '
                    f'{self.core.episode}, without its EpisodeSummary; learned as terminal'
                )
                self._end_episode(resolved)
        elif not self._endings.waiting:
            self._stop_waiting()

    def _stop_waiting(self) -> None:
        self._ports.stop_summary_timer()
        self._summary_wait.stop()

    def _end_episode(self, resolved: ResolvedEnd) -> None:
        self._stop_waiting()
        ending = resolved.ending
        if ending is Ending.TRUNCATED and self._ports.param('timeout_is_terminal'):
            ending = Ending.TERMINATED
        if resolved.episode is not None:
            # The environment numbers the episodes: after a restart of either side (an episode
            # dropped by one of them) both still name each episode alike.
            self.core.episode = resolved.episode
        self._process(resolved.state, resolved.reward, True, ending)

    def _episode_done(self, result: EpisodeResult) -> None:
        learner, table_rows = self.core.learner, len(self.core.index)
        self._ports.send_reports(
            experiment_info(result), episode_info(result, learner, table_rows)
        )
        log = self._ports.get_logger()
        if self.learning_run and not result.learning:
            log.info(evaluation_line(result, reported_reward(result), learner.episodes))
        line = self._progress.episode(
            result, table_rows=table_rows, log_every=self._ports.param('log_every')
        )
        if line is not None:
            log.info(line)
        self._report_notes(learner)
        if result.learning:
            self._ports.show_learner(learner)
        save_every = self._ports.param('save_every')
        if save_every and self.learning_run and self.core.episode % save_every == 0:
            self.save(f'every {save_every} episodes')

    def _report_notes(self, learner) -> None:
        """The learner's notes (the light model's contradictions: steps its belief cannot
        explain) as warnings, each line once per run, then cleared."""
        notes = getattr(learner, 'notes', None)
        if not notes:
            return
        log = self._ports.get_logger()
        for note in notes:
            if note not in self._notes_told:
                self._notes_told.add(note)
                log.warning(f'{learner.name}: {note}')
        notes.clear()

    def on_summary(self, msg) -> None:
        """An EpisodeSummary."""
        if self.core is None or msg.episode < self._ports.param('first_episode'):
            return  # from before this agent's first episode (the history a late reader gets)
        self._progress.outcome(outcome_name(msg.outcome))
        resolved = self._endings.report(msg.steps, outcome_ending(msg.outcome), int(msg.episode))
        if resolved is not None:
            self._end_episode(resolved)

    # --- policy file -------------------------------------------------------------------------

    def save(self, reason: str) -> bool:
        """Save the learned policy atomically, if learning with a policy file. A full disk
        keeps the file saved before and raises DiskFullError: the node stops (EXIT_DISK_FULL)
        and the orchestrator stops the run, rather than learning on without a saved policy."""
        path = self._ports.param('policy_file')
        if self.core is None or not self.learning_run or not path or self.disk_full:
            return False
        learner, index = self.core.learner, self.core.index
        log = self._ports.exit_logger()
        identity = self.description.identity()  # and by content, when the run gave it
        content = {key: self._ports.param(key) for key in CONTENT_KEYS}
        identity.update({key: value for key, value in content.items() if value})
        try:
            save_policy(
                path,
                learner,
                index,
                scenario=identity,
                rng=self.core.rng,
                extra={'seed': self._ports.param('seed'), 'reason': reason},
            )
        except (OSError, ValueError) as error:
            if is_disk_full(error):
                self.disk_full = True
                raise DiskFullError(path) from None
            log.error(f'could not save the policy to {path}: {error}')
            return False
        log.info(
            f'saved the policy to {path} ({reason}; {learner.episodes} episodes, '
            f'{len(index)} states)'
        )
        return True
