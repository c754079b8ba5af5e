"""The rl_msgs protocol of rl-texplore-ros-pkg's rl_agent, as plain Python (no rclpy).

rl_agent's processState: the first state of an episode gets first_action (its reward is
ignored); each later non-terminal state gets next_action(reward, state) (learn, then choose);
a terminal state gets last_action(reward) (Q += alpha * (r - Q)), no action, and the episode's
RLExperimentInfo: episode number, sum of rewards after the first state, number of actions.

rl_msgs has only `terminal`, so an episode cut off by the environment's step limit looks like a
terminal state, and an agent that learns it as one learns that timing out is cheap (the
time-limit bias of Pardo et al., "Time Limits in Reinforcement Learning", ICML 2018). When the
environment says how the episode ended (stealth_env's EpisodeSummary), the caller passes an
Ending: TRUNCATED bootstraps from the final state as a non-terminal step, ABORTED makes no
update at all; EpisodeEndMatcher pairs the two messages, and SummaryWait keeps a terminal state
waiting for its report as long as the environment is there (a late report never turns into a
guess, so what is learned does not depend on the load of the machine).

ProtocolAgent does exactly that on top of a learner, a state index and a random generator, and
checks every input first: a bad one raises BadInputError naming the problem and leaves the table,
the index and the episode untouched, so the caller can skip the message and carry on. The ROS
node only converts messages; an in-process trainer can drive the same object.
"""

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
import enum
import math

import numpy as np

from .learners import TabularLearner, check_num_actions
from .state_index import StateError, StateIndex


class BadInputError(ValueError):
    """A message the agent cannot use; the text names the problem."""


class Ending(enum.Enum):
    """How an episode ended, and so what its last update is."""

    TERMINATED = 'terminated'  # a terminal state of the task: Q += alpha * (r - Q)
    TRUNCATED = 'truncated'  # cut off by a time limit: bootstrap from the final state
    ABORTED = 'aborted'  # ended from outside (a failed move): no update, nothing learned


@dataclass(frozen=True)
class EnvDescription:
    """What RLEnvDescription says, checked."""

    num_actions: int
    num_states: float = 0.0
    min_state_range: tuple[float, ...] = ()
    max_state_range: tuple[float, ...] = ()
    max_reward: float = 0.0
    reward_range: float = 0.0
    stochastic: bool = False
    episodic: bool = True
    title: str = ''

    def identity(self) -> dict:
        """The scenario identity stored with a policy."""
        return {
            'title': self.title,
            'num_actions': self.num_actions,
            'num_states': self.num_states,
            'min_state_range': list(self.min_state_range),
            'max_state_range': list(self.max_state_range),
            'max_reward': self.max_reward,
            'reward_range': self.reward_range,
            'stochastic': self.stochastic,
            'episodic': self.episodic,
        }

    def other_environment(self, running: 'EnvDescription') -> str | None:
        """What makes this description another environment than the running one's (action
        count, title, state length differ), or None: the same one again (it restarted)."""
        if (
            self.num_actions == running.num_actions
            and self.title == running.title
            and len(self.min_state_range) == len(running.min_state_range)
        ):
            return None
        return (
            f'{self.title!r}, {self.num_actions} actions, {len(self.min_state_range)} state '
            f'ranges; running: {running.title!r}, {running.num_actions} actions, '
            f'{len(running.min_state_range)} state ranges'
        )


def parse_description(
    num_actions,
    num_states=0.0,
    min_state_range=(),
    max_state_range=(),
    max_reward=0.0,
    reward_range=0.0,
    stochastic=False,
    episodic=True,
    title='',
) -> EnvDescription:
    """An EnvDescription from RLEnvDescription's fields; BadInputError when unusable."""
    try:
        actions = check_num_actions(num_actions)
    except ValueError as error:
        raise BadInputError(f'environment description: {error}') from None
    return EnvDescription(
        actions,
        float(num_states),
        tuple(float(v) for v in min_state_range),
        tuple(float(v) for v in max_state_range),
        float(max_reward),
        float(reward_range),
        bool(stochastic),
        bool(episodic),
        str(title),
    )


@dataclass(frozen=True)
class EpisodeResult:
    """One finished episode, as reported in RLExperimentInfo and the progress log."""

    episode: int  # episode number of this run (RLExperimentInfo.episode_number), from 0
    learner_episode: int  # the learner's count of finished episodes before this one
    reward: float  # sum of rewards after the first state
    actions: int  # actions taken
    terminal_reward: float | None  # reward of the terminal state (None: truncated or aborted)
    epsilon: float  # exploration rate used (0 when evaluating)
    truncated: bool = False  # ended by a time limit without a terminal state (trainers only)
    aborted: bool = False  # dropped without a final update (environment restarted)
    learning: bool = True  # False when evaluating (greedy, no updates)


@dataclass(frozen=True)
class Step:
    """What to send back for one RLStateReward."""

    action: int | None = None  # RLAction to publish, None at a terminal state
    result: EpisodeResult | None = None  # RLExperimentInfo to publish, at a terminal state
    notes: tuple[str, ...] = ()  # warnings worth logging (e.g. a state outside the ranges)


class ProtocolAgent:
    """rl_agent's processState over a learner, a state index and a seeded generator."""

    def __init__(
        self,
        learner: TabularLearner,
        index: StateIndex,
        rng: np.random.Generator,
        *,
        learning: bool = True,
        prior: Callable[[np.ndarray], np.ndarray | None] | None = None,
    ):
        self.learner = learner
        self.index = index
        self.rng = rng
        self.learning = learning
        # The initial action values of a state seen for the first time (None: the learner's
        # initial_value), e.g. stealth_core.floor_plan_prior's; never of a known row.
        self.prior = prior
        self.episode = 0  # episodes finished in this run
        self.in_episode = False
        self.episode_reward = 0.0
        self.number_actions = 0
        self._s: int | None = None
        self._a: int | None = None

    @property
    def epsilon(self) -> float:
        return self.learner.epsilon if self.learning else 0.0

    def handle(self, state, reward, terminal: bool, ending: Ending = Ending.TERMINATED) -> Step:
        """One RLStateReward in, what to publish out; BadInputError leaves everything unchanged.

        `ending` says how a terminal state is to be learned (rl_msgs alone: TERMINATED)."""
        vector = self._check_state(state)
        notes = ()
        if self.index.mapping.out_of_range(vector):
            notes = (f'state {vector.tolist()} lies outside the description state ranges',)
        if not self.in_episode:
            if terminal:  # an episode ended before its first action: nothing to learn
                aborted = ending is Ending.ABORTED
                return Step(None, self._finish(0.0, terminal_reward=None, aborted=aborted), notes)
            return Step(self.first_action(vector), None, notes)
        if not terminal:
            return Step(self.next_action(reward, vector), None, notes)
        if ending is Ending.TRUNCATED:
            return Step(None, self.truncate(reward, vector), notes)
        if ending is Ending.ABORTED:
            return Step(None, self.end_aborted(reward), notes)
        return Step(None, self.last_action(reward), notes)

    def check_state_reward(self, state, reward) -> None:
        """BadInputError when a state or reward is unusable (nothing changes either way)."""
        self._check_state(state)
        self._check_reward(reward)

    def first_action(self, state) -> int:
        """The first state of an episode: choose an action, its reward is ignored."""
        vector = self._check_state(state)
        row = self._row(vector)
        action = self.learner.act(row, self.rng) if self.learning else self._greedy(row, vector)
        self._s, self._a = row, action
        self.in_episode = True
        self.episode_reward = 0.0
        self.number_actions = 1
        return action

    def next_action(self, reward, state) -> int:
        """A non-terminal state after an action: learn, then choose the next action."""
        self._check_in_episode()
        r = self._check_reward(reward)
        vector = self._check_state(state)
        row = self._row(vector)
        if self.learning:
            action = self.learner.next_action(self._s, self._a, r, row, self.rng)
        else:
            action = self._greedy(row, vector)
        self._s, self._a = row, action
        self.episode_reward += r
        self.number_actions += 1
        return action

    def _row(self, vector: np.ndarray) -> int:
        """The table row of a state; a new one starts at the prior's values, if any."""
        known = len(self.index)
        row = self.index.row(vector)
        if self.prior is not None and len(self.index) > known:
            values = self.prior(vector)
            if values is not None:
                self.learner.set_initial_row(row, values)
        return row

    def _greedy(self, row: int, vector: np.ndarray) -> int:
        """The greedy action in a state (its table row and its vector): the table's, ties
        broken by the generator (grid_agent's policies override it)."""
        return self.learner.greedy_action(row, self.rng)

    def last_action(self, reward) -> EpisodeResult:
        """A terminal state: Q += alpha * (r - Q), end the episode."""
        self._check_in_episode()
        r = self._check_reward(reward)
        if self.learning:
            self.learner.update(self._s, self._a, r, None, True, rng=self.rng)
        return self._finish(r, terminal_reward=r)

    def truncate(self, reward, state) -> EpisodeResult:
        """The episode was cut off (time limit) in a non-terminal state: bootstrap, then end.

        For in-process trainers whose environment separates truncation from termination; the
        rl_msgs protocol has only `terminal`.
        """
        self._check_in_episode()
        r = self._check_reward(reward)
        vector = self._check_state(state)
        row = self._row(vector)
        if self.learning:
            a_next = self.learner.act(row, self.rng) if self.learner.on_policy else None
            self.learner.update(self._s, self._a, r, row, False, a_next=a_next, rng=self.rng)
        return self._finish(r, terminal_reward=None, truncated=True)

    def end_aborted(self, reward) -> EpisodeResult:
        """The environment ended the episode from outside (a failed move): it counts as an
        episode of the run, but nothing is learned from it and the schedules stand still."""
        self._check_in_episode()
        r = self._check_reward(reward)
        return self._finish(r, terminal_reward=None, aborted=True)

    def abort(self) -> EpisodeResult | None:
        """Drop the episode in progress without a final update (the environment restarted)."""
        if not self.in_episode:
            return None
        result = EpisodeResult(
            self.episode,
            self.learner.episodes,
            self.episode_reward,
            self.number_actions,
            None,
            self.epsilon,
            aborted=True,
            learning=self.learning,
        )
        self.in_episode = False
        self._s = self._a = None
        return result

    def set_learning(self, learning: bool) -> None:
        """Switch between learning and greedy evaluation (epsilon 0, no updates, the schedules
        stand still); only between episodes, RuntimeError in the middle of one."""
        if self.in_episode:
            raise RuntimeError('the learning mode can only change between episodes')
        self.learning = bool(learning)

    def _finish(
        self, r: float, *, terminal_reward, truncated=False, aborted=False
    ) -> EpisodeResult:
        actions = self.number_actions if self.in_episode else 0
        total = self.episode_reward + r if self.in_episode else 0.0
        result = EpisodeResult(
            self.episode,
            self.learner.episodes,
            total,
            actions,
            terminal_reward,
            self.epsilon,
            truncated=truncated,
            aborted=aborted,
            learning=self.learning,
        )
        if self.learning and not aborted:
            self.learner.end_episode()
        self.episode += 1
        self.in_episode = False
        self.episode_reward = 0.0
        self.number_actions = 0
        self._s = self._a = None
        return result

    def _check_state(self, state) -> np.ndarray:
        try:
            return self.index.check(state)
        except StateError as error:
            raise BadInputError(f'bad state: {error}') from None

    @staticmethod
    def _check_reward(reward) -> float:
        try:
            r = float(reward)
        except (TypeError, ValueError):
            raise BadInputError(f'bad reward: not a number ({reward!r})') from None
        if not math.isfinite(r):
            raise BadInputError(f'bad reward: {r} is not finite')
        return r

    def _check_in_episode(self) -> None:
        if not self.in_episode:
            raise BadInputError('no episode in progress (expected the first state of an episode)')


@dataclass(frozen=True)
class ResolvedEnd:
    """A terminal RLStateReward together with how its episode ended."""

    state: tuple[float, ...]
    reward: float
    ending: Ending
    episode: int | None = None  # the environment's number of the episode, when it reported it


class EpisodeEndMatcher:
    """Pairs a terminal RLStateReward with the environment's report of how the episode ended.

    The two come on different topics, so either may arrive first. They belong together when the
    report's action count equals the agent's for the episode (or is one less for an ABORTED
    episode: the move in flight when it was aborted is an action the environment never
    judged); reports of other episodes (one
    the agent never saw, one that came after the agent stopped waiting) match nothing and are
    dropped when the next episode starts. Plain Python: the node feeds it messages.
    """

    def __init__(self, keep: int = 8):
        self._pending: tuple[tuple[float, ...], float, int] | None = None
        self._reports: deque[tuple[int, Ending, int | None]] = deque(maxlen=keep)

    @property
    def waiting(self) -> bool:
        """True while a terminal state waits for its report."""
        return self._pending is not None

    def terminal(self, state, reward, actions: int) -> ResolvedEnd | None:
        """A terminal state after `actions` actions: resolved when its report is already here,
        else None (it waits)."""
        for steps, ending, episode in reversed(self._reports):
            if _same_episode(steps, ending, actions):
                self._reports.clear()
                return ResolvedEnd(tuple(state), reward, ending, episode)
        self._pending = (tuple(state), reward, int(actions))
        return None

    def report(self, steps: int, ending: Ending, episode: int | None = None) -> ResolvedEnd | None:
        """The environment's report of its episode number `episode` that took `steps` actions."""
        if self._pending is not None and _same_episode(steps, ending, self._pending[2]):
            state, reward, _ = self._pending
            self._pending = None
            self._reports.clear()
            return ResolvedEnd(state, reward, ending, episode)
        self._reports.append((int(steps), ending, episode))
        return None

    def give_up(self) -> ResolvedEnd | None:
        """No report can come (the environment is gone): the waiting terminal state is learned
        as rl_msgs says (terminal)."""
        if self._pending is None:
            return None
        state, reward, _ = self._pending
        self._pending = None
        return ResolvedEnd(state, reward, Ending.TERMINATED)

    def new_episode(self) -> None:
        """A first state: no report from before it can be about the episode it starts."""
        self._pending = None
        self._reports.clear()


class SummaryWait:
    """How long a terminal state waits for its report: as long as the environment is there.

    A report that is merely late (a loaded machine) must not change what is learned, so there
    is no deadline: waiting ends with the report, or when no environment is left to send one
    (``tick`` then says 'give up'). Meanwhile ``tick`` says 'warn' every ``warn_every``
    seconds, so a wait that never ends is seen. Times are the caller's clock (the node's wall
    clock); nothing here decides what is learned.
    """

    def __init__(self, warn_every: float):
        if not warn_every > 0:
            raise ValueError(f'warn_every must be > 0 s, got {warn_every}')
        self.warn_every = float(warn_every)
        self.since: float | None = None  # when the wait began (None: not waiting)
        self._next_warning = math.inf

    def start(self, now: float) -> None:
        self.since = now
        self._next_warning = now + self.warn_every

    def stop(self) -> None:
        self.since = None
        self._next_warning = math.inf

    def tick(self, now: float, environment_present: bool) -> str | None:
        """'give up' (the environment is gone), 'warn' (another warn_every passed) or None."""
        if self.since is None:
            return None
        if not environment_present:
            self.stop()
            return 'give up'
        if now >= self._next_warning:
            self._next_warning = now + self.warn_every
            return 'warn'
        return None

    def waited(self, now: float) -> float:
        return 0.0 if self.since is None else now - self.since


def _same_episode(reported_steps: int, ending: Ending, actions: int) -> bool:
    if ending is Ending.ABORTED and reported_steps == actions - 1:
        return True
    return reported_steps == actions


def is_greedy_episode(episode: int, eval_every: int) -> bool:
    """Whether episode number `episode` (from 0) of a learning run is a greedy evaluation: every
    eval_every-th episode, i.e. episodes eval_every - 1, 2 * eval_every - 1, ...; never when
    eval_every is 0 (so with 5, episodes 4, 9, 14, ... evaluate the policy learned so far)."""
    if isinstance(eval_every, bool) or not isinstance(eval_every, int | np.integer):
        raise ValueError(f'eval_every must be an integer >= 0, got {eval_every!r}')
    if eval_every < 0:
        raise ValueError(f'eval_every must be an integer >= 0, got {eval_every}')
    return eval_every > 0 and (int(episode) + 1) % eval_every == 0
