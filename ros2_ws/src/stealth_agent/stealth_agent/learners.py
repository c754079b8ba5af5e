"""Tabular learners: Q-learning, SARSA, Dyna-Q and (in `prioritized_sweeping`) prioritized
sweeping; plain Python + numpy, no rclpy.

Like rl-texplore-ros-pkg's rl_agent (QLearner, Sarsa, Dyna): the table holds one row of action
values per discrete state, epsilon-greedy action choice with random tie-breaking among the
maximal actions, defaults gamma 0.99, alpha 0.3, epsilon 0.1, initial Q 0.

Interface (shared by the ROS node and in-process trainers such as a Gymnasium loop)::

    learner = make_learner('qlearning', num_actions, LearnerConfig(...))
    a = learner.act(s, rng)                    # epsilon-greedy; s is a table row (int >= 0)
    a = learner.greedy_action(s, rng)          # evaluation: no exploration
    learner.update(s, a, r, s_next, terminated, a_next=None, rng=rng)
    a_next = learner.next_action(s, a, r, s_next, rng)   # learn + choose, rl_agent's order
    learner.end_episode()                      # advances the epsilon/alpha schedules

Targets: r + gamma * (not terminated) * max_a' Q(s', a') (Q-learning, Dyna-Q) or
Q(s', a_next) (SARSA, one step, i.e. rl_agent's Sarsa with lambda 0). A terminal transition
gets Q += alpha * (r - Q), as rl_agent's last_action. Rows are added on demand: the table grows
(capacity doubling), it never overflows. Every random choice draws from the
`np.random.Generator` passed in, so a seed fixes the whole learning curve bit for bit.
"""

from dataclasses import dataclass, field
import math
from typing import ClassVar

import numpy as np

from .schedules import Schedule

LEARNER_NAMES = ('qlearning', 'sarsa', 'dyna', 'prioritized', 'light-model')
# The learners that learn any MDP from its rewards alone; light-model needs the stealth task's
# world (``LightModelLearner.attach``).
TABULAR_LEARNERS = ('qlearning', 'sarsa', 'dyna', 'prioritized')
# Learners that explore by optimism (prioritized sweeping's docstring): started at an upper bound
# on the true values (the floor plan's, stealth_core.floor_plan_prior) they need no random moves,
# so the harness and `stealth train` run them with epsilon 0 and the floor plan's prior.
OPTIMISTIC = ('prioritized',)
# rl_agent's spellings and a few obvious ones.
LEARNER_ALIASES = {
    'qlearning': 'qlearning',
    'qlearner': 'qlearning',
    'q': 'qlearning',
    'sarsa': 'sarsa',
    'dyna': 'dyna',
    'dynaq': 'dyna',
    'dyna-q': 'dyna',
    'dyna_q': 'dyna',
    'prioritized': 'prioritized',
    'prioritized_sweeping': 'prioritized',
    'prioritized-sweeping': 'prioritized',
    'psweep': 'prioritized',
    'light-model': 'light-model',
    'light_model': 'light-model',
    'lightmodel': 'light-model',
}
_INITIAL_CAPACITY = 64
MAX_ROWS = 2**31 - 1


def canonical_learner_name(name: str) -> str:
    """A name of LEARNER_NAMES for any accepted spelling; ValueError otherwise."""
    key = str(name).strip().lower()
    if key not in LEARNER_ALIASES:
        raise ValueError(f'unknown learner {name!r} (expected one of {", ".join(LEARNER_NAMES)})')
    return LEARNER_ALIASES[key]


def check_num_actions(num_actions) -> int:
    """The action count as an int >= 1; ValueError naming the problem otherwise."""
    try:
        value = float(num_actions)
    except (TypeError, ValueError):
        raise ValueError(f'action count must be a number, got {num_actions!r}') from None
    if not math.isfinite(value) or value != int(value):
        raise ValueError(f'action count must be a whole number, got {num_actions!r}')
    if value < 1:
        raise ValueError(f'action count must be at least 1, got {int(value)}')
    return int(value)


@dataclass(frozen=True)
class LearnerConfig:
    """Hyperparameters (rl_agent's defaults); alpha and epsilon follow schedules."""

    gamma: float = 0.99
    alpha: Schedule = field(default_factory=lambda: Schedule.fixed(0.3))
    epsilon: Schedule = field(default_factory=lambda: Schedule.fixed(0.1))
    initial_value: float = 0.0
    n_planning: int = 10  # Dyna-Q: model updates per real step (rl_agent's --k, default 1000)
    theta: float = 0.01  # prioritized sweeping: smallest priority queued (|expected TD error|)

    def __post_init__(self):
        if not (isinstance(self.gamma, int | float) and 0.0 <= self.gamma <= 1.0):
            raise ValueError(f'gamma must be in [0, 1], got {self.gamma!r}')
        for name, schedule in (('alpha', self.alpha), ('epsilon', self.epsilon)):
            if not isinstance(schedule, Schedule):
                raise ValueError(f'{name} must be a Schedule, got {schedule!r}')
            for end in (schedule.start, schedule.final):
                if not 0.0 <= end <= 1.0:
                    raise ValueError(f'{name} must stay in [0, 1], got {end!r}')
        if not (isinstance(self.initial_value, int | float) and math.isfinite(self.initial_value)):
            raise ValueError(f'initial value must be finite, got {self.initial_value!r}')
        if isinstance(self.n_planning, bool) or not isinstance(self.n_planning, int | np.integer):
            raise ValueError(f'n (planning updates) must be an integer, got {self.n_planning!r}')
        if self.n_planning < 0:
            raise ValueError(f'n (planning updates) must be >= 0, got {self.n_planning}')
        if not (
            isinstance(self.theta, int | float)
            and not isinstance(self.theta, bool)
            and math.isfinite(self.theta)
            and self.theta >= 0
        ):
            raise ValueError(
                f'theta (priority threshold) must be finite and >= 0, got {self.theta!r}'
            )

    @classmethod
    def constant(
        cls,
        gamma: float = 0.99,
        alpha: float = 0.3,
        epsilon: float = 0.1,
        initial_value: float = 0.0,
        n_planning: int = 10,
        theta: float = 0.01,
    ) -> 'LearnerConfig':
        """A configuration with constant alpha and epsilon."""
        return cls(
            gamma, Schedule.fixed(alpha), Schedule.fixed(epsilon), initial_value, n_planning, theta
        )

    def to_dict(self) -> dict:
        return {
            'gamma': self.gamma,
            'alpha': self.alpha.to_dict(),
            'epsilon': self.epsilon.to_dict(),
            'initial_value': self.initial_value,
            'n_planning': int(self.n_planning),
            'theta': float(self.theta),
        }

    @classmethod
    def from_dict(cls, data: dict) -> 'LearnerConfig':
        return cls(
            float(data['gamma']),
            Schedule.from_dict(data['alpha']),
            Schedule.from_dict(data['epsilon']),
            float(data['initial_value']),
            int(data['n_planning']),
            float(data.get('theta', cls.theta)),  # files from before prioritized sweeping
        )


def argmax_random(values: np.ndarray, rng: np.random.Generator) -> int:
    """Index of a maximal entry, ties broken uniformly at random (rl_agent random_max_element)."""
    best = np.flatnonzero(values == values.max())
    if best.size == 1:
        return int(best[0])
    return int(best[rng.integers(best.size)])


def first_or_random(values: np.ndarray, rng: np.random.Generator | None) -> int:
    """argmax_random, or without ``rng`` the first maximal entry."""
    return int(np.argmax(values)) if rng is None else argmax_random(values, rng)


class TabularLearner:
    """Common table handling, action choice and serialisation; subclasses define the target."""

    name: ClassVar[str] = ''
    on_policy: ClassVar[bool] = False

    def __init__(self, num_actions: int, config: LearnerConfig | None = None):
        self.num_actions = check_num_actions(num_actions)
        self.config = config if config is not None else LearnerConfig()
        self._q = np.full(
            (_INITIAL_CAPACITY, self.num_actions), self.config.initial_value, dtype=np.float64
        )
        self._rows = 0
        self.episodes = 0  # finished episodes; the schedules' t
        self.updates = 0  # real (not planning) updates
        self._refresh_rates()

    # --- table -------------------------------------------------------------------------------

    @property
    def q(self) -> np.ndarray:
        """The Q-table, shape (rows, actions); a view, do not resize."""
        return self._q[: self._rows]

    @property
    def num_rows(self) -> int:
        return self._rows

    def ensure_rows(self, rows: int) -> None:
        """Make rows 0..rows-1 exist (new ones at the initial value)."""
        if rows > MAX_ROWS:
            raise ValueError(f'table row {rows - 1} exceeds the limit {MAX_ROWS - 1}')
        capacity = self._q.shape[0]
        if rows > capacity:
            grown = np.full(
                (max(rows, 2 * capacity), self.num_actions),
                self.config.initial_value,
                dtype=np.float64,
            )
            grown[: self._rows] = self._q[: self._rows]
            self._q = grown
        self._rows = max(self._rows, rows)

    def set_initial_row(self, s: int, values) -> None:
        """Start row s (a state just seen, nothing learned of it yet) at ``values``, one per
        action, instead of initial_value: a prior, such as the value of the floor plan with the
        lights dark. ValueError for the wrong number of values or one that is not finite."""
        row = np.asarray(values, dtype=np.float64)
        if row.shape != (self.num_actions,) or not np.all(np.isfinite(row)):
            raise ValueError(
                f'initial row: expected {self.num_actions} finite action values, got {values!r}'
            )
        s = self._check_row(s)
        self.ensure_rows(s + 1)
        self._q[s] = row

    def values(self, s: int) -> np.ndarray:
        """A copy of the action values of row s."""
        s = self._check_row(s)
        self.ensure_rows(s + 1)
        return self._q[s].copy()

    # --- rates -------------------------------------------------------------------------------

    @property
    def epsilon(self) -> float:
        """Exploration rate of the current episode (from the schedule)."""
        return self._epsilon

    @property
    def alpha(self) -> float:
        """Learning rate of the current episode (from the schedule)."""
        return self._alpha

    def set_config(self, config: LearnerConfig) -> None:
        """Change hyperparameters (e.g. at runtime); the table is kept."""
        if config.initial_value != self.config.initial_value:
            # Only rows created from now on use it; make the spare capacity agree.
            self._q[self._rows :] = config.initial_value
        self.config = config
        self._refresh_rates()

    def _refresh_rates(self) -> None:
        self._epsilon = self.config.epsilon(self.episodes)
        self._alpha = self.config.alpha(self.episodes)

    def end_episode(self) -> None:
        """Count a finished episode; epsilon and alpha move along their schedules."""
        self.episodes += 1
        self._refresh_rates()

    # --- acting ------------------------------------------------------------------------------

    def greedy_action(self, s: int, rng: np.random.Generator | None = None) -> int:
        """A maximal action of row s, ties broken at random (without ``rng``: the first, for a
        planner that must answer alike every time)."""
        s = self._check_row(s)
        self.ensure_rows(s + 1)
        return first_or_random(self._q[s], rng)

    def act(self, s: int, rng: np.random.Generator, *, greedy: bool = False) -> int:
        """Epsilon-greedy action in row s (rl_agent: uniform draw < epsilon -> random action)."""
        s = self._check_row(s)
        self.ensure_rows(s + 1)
        if not greedy and rng.random() < self._epsilon:
            return int(rng.integers(self.num_actions))
        return argmax_random(self._q[s], rng)

    # --- learning ----------------------------------------------------------------------------

    def update(
        self,
        s: int,
        a: int,
        r: float,
        s_next: int | None,
        terminated: bool,
        a_next: int | None = None,
        rng: np.random.Generator | None = None,
    ) -> float:
        """One TD update of Q(s, a); returns the TD error. Validates before changing anything."""
        s, a, r = self._check_row(s), self._check_action(a), self._check_reward(r)
        terminated = bool(terminated)
        if not terminated:
            if s_next is None:
                raise ValueError('a non-terminal update needs the next state')
            s_next = self._check_row(s_next)
            if self.on_policy:
                if a_next is None:
                    raise ValueError(f'{self.name} needs the next action (a_next) to update')
                a_next = self._check_action(a_next)
        self._check_update_extra(rng)
        self.ensure_rows(s + 1 if terminated else max(s, s_next) + 1)
        target = r if terminated else r + self.config.gamma * self._bootstrap(s_next, a_next)
        error = target - self._q[s, a]
        self._q[s, a] += self._alpha * error
        self.updates += 1
        self._after_update(s, a, r, s_next, terminated, rng)
        return float(error)

    def next_action(self, s: int, a: int, r: float, s_next: int, rng: np.random.Generator) -> int:
        """Learn from the non-terminal step (s, a, r, s_next), then choose the action in s_next.

        rl_agent's QLearner order: update first, then choose from the updated values.
        """
        self.update(s, a, r, s_next, False, rng=rng)
        return self.act(s_next, rng)

    def _bootstrap(self, s_next: int, a_next: int | None) -> float:
        return float(self._q[s_next].max())

    def _check_update_extra(self, rng) -> None:
        pass

    def _after_update(self, s, a, r, s_next, terminated, rng) -> None:
        pass

    # --- checks ------------------------------------------------------------------------------

    def _check_row(self, s) -> int:
        if isinstance(s, bool) or not isinstance(s, int | np.integer):
            raise ValueError(f'state row must be an integer, got {s!r}')
        if not 0 <= s < MAX_ROWS:
            raise ValueError(f'state row must be in [0, {MAX_ROWS}), got {s}')
        return int(s)

    def _check_action(self, a) -> int:
        if isinstance(a, bool) or not isinstance(a, int | np.integer):
            raise ValueError(f'action must be an integer, got {a!r}')
        if not 0 <= a < self.num_actions:
            raise ValueError(f'action {a} out of range [0, {self.num_actions})')
        return int(a)

    @staticmethod
    def _check_reward(r) -> float:
        r = float(r)
        if not math.isfinite(r):
            raise ValueError(f'reward must be finite, got {r}')
        return r

    # --- serialisation -----------------------------------------------------------------------

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Everything learned, as arrays (the Q-table, the Dyna model)."""
        return {'q': self.q.copy()}

    def to_meta(self) -> dict:
        """Everything else about the learner, JSON-serialisable."""
        return {
            'learner': self.name,
            'num_actions': self.num_actions,
            'config': self.config.to_dict(),
            'episodes': self.episodes,
            'updates': self.updates,
        }

    def load_arrays(self, arrays: dict[str, np.ndarray], episodes: int, updates: int) -> None:
        """Replace the table (and model) with saved ones; ValueError if they do not fit."""
        q = np.asarray(arrays['q'])
        if q.ndim != 2 or q.shape[1] != self.num_actions:
            raise ValueError(f'Q-table shape {q.shape} does not fit {self.num_actions} actions')
        if not np.all(np.isfinite(q)):
            raise ValueError('Q-table holds non-finite values')
        self._load_extra(arrays, q.shape[0])
        fresh = np.full(
            (max(_INITIAL_CAPACITY, q.shape[0]), self.num_actions),
            self.config.initial_value,
            dtype=np.float64,
        )
        fresh[: q.shape[0]] = q
        self._q, self._rows = fresh, q.shape[0]
        self.episodes, self.updates = int(episodes), int(updates)
        self._refresh_rates()

    def _load_extra(self, arrays, rows: int) -> None:
        pass


class QLearning(TabularLearner):
    """Watkins' Q-learning (rl_agent's QLearner)."""

    name = 'qlearning'


class Sarsa(TabularLearner):
    """One-step SARSA: on-policy, bootstraps on the action actually chosen next."""

    name = 'sarsa'
    on_policy = True

    def _bootstrap(self, s_next: int, a_next: int | None) -> float:
        return float(self._q[s_next, a_next])

    def next_action(self, s: int, a: int, r: float, s_next: int, rng: np.random.Generator) -> int:
        """Choose the action in s_next first, then learn from (s, a, r, s_next, a_next)."""
        # Validate before drawing from rng, so a rejected step changes nothing.
        self._check_row(s)
        self._check_action(a)
        self._check_reward(r)
        s_next = self._check_row(s_next)
        a_next = self.act(s_next, rng)
        self.update(s, a, r, s_next, False, a_next=a_next, rng=rng)
        return a_next


class DynaQ(QLearning):
    """Dyna-Q (Sutton & Barto 8.2): Q-learning plus n planning updates per real step.

    The model counts, for every (s, a) tried, each outcome seen (next row and terminal flag) and
    its mean reward. Each planning update picks a remembered (s, a) uniformly at random and
    applies the Q-learning update to the expected outcome, the outcomes weighted by how often
    they were seen. In a deterministic environment that is the textbook model (one outcome per
    pair, the same updates and random draws); in a stochastic one (slip, or the simulated robot
    through ROS, whose pose noise now and then carries a move into another cell or a beam), the
    last sample would stand for the pair until the pair is tried again, and n planning updates
    would spread a rare outcome (a detection, say) as if it were certain.
    """

    name = 'dyna'

    def __init__(self, num_actions: int, config: LearnerConfig | None = None):
        super().__init__(num_actions, config)
        self._model_index: dict[tuple[int, int], int] = {}
        self._model_s: list[int] = []
        self._model_a: list[int] = []
        # Per pair: {(next row or -1 when terminal, terminal): [count, mean reward]}.
        self._model_outcomes: list[dict[tuple[int, bool], list]] = []

    @property
    def model_size(self) -> int:
        """State-action pairs in the model."""
        return len(self._model_s)

    def _forget_model(self) -> None:
        self._model_index, self._model_s, self._model_a, self._model_outcomes = {}, [], [], []

    def _check_update_extra(self, rng) -> None:
        if self.config.n_planning > 0 and rng is None:
            raise ValueError('Dyna-Q planning needs the random generator (rng=...)')

    def _after_update(self, s, a, r, s_next, terminated, rng) -> None:
        self._remember(s, a, (-1 if terminated else s_next, bool(terminated)), r, 1)
        self.plan(self.config.n_planning, rng)

    def _remember(
        self, s: int, a: int, outcome: tuple[int, bool], reward: float, count: int
    ) -> int:
        """Count an outcome of (s, a); the pair's model index."""
        i = self._model_index.get((s, a))
        if i is None:
            i = self._model_index[(s, a)] = len(self._model_s)
            self._model_s.append(s)
            self._model_a.append(a)
            self._model_outcomes.append({})
        seen = self._model_outcomes[i].setdefault(outcome, [0, 0.0])
        seen[0] += count
        # A running mean: an outcome whose reward never changes keeps it exactly.
        seen[1] += (reward - seen[1]) * count / seen[0]
        return i

    def plan(self, n: int, rng: np.random.Generator) -> None:
        """n simulated Q-learning updates from the model's expected outcomes."""
        if n <= 0 or not self._model_s:
            return
        q, alpha = self._q, self._alpha
        for i in rng.integers(len(self._model_s), size=n).tolist():
            s, a = self._model_s[i], self._model_a[i]
            q[s, a] += alpha * (self.expected_target(i) - q[s, a])

    def expected_target(self, i: int) -> float:
        """r + gamma * (not terminal) * max_a' Q(s', a') of model pair i, its outcomes weighted
        by how often they were seen."""
        q, gamma = self._q, self.config.gamma
        outcomes = self._model_outcomes[i]
        if len(outcomes) == 1:
            (((next_row, terminal), (_, reward)),) = outcomes.items()
            return reward if terminal else reward + gamma * q[next_row].max()
        total = weighted = 0.0
        for (next_row, terminal), (count, reward) in outcomes.items():
            value = reward if terminal else reward + gamma * q[next_row].max()
            weighted += count * value
            total += count
        return weighted / total

    def model_outcomes(self) -> dict[str, np.ndarray]:
        """The model, one entry per (s, a, outcome) in the order pairs were first tried:
        ``pair`` (its model index), ``s``, ``a``, ``next`` (-1 when terminal), ``terminal``,
        ``count`` and (mean) ``reward``."""
        rows = [
            (i, s, a, next_row, terminal, count, reward)
            for i, (s, a, outcomes) in enumerate(
                zip(self._model_s, self._model_a, self._model_outcomes, strict=True)
            )
            for (next_row, terminal), (count, reward) in outcomes.items()
        ]
        columns = list(zip(*rows, strict=True)) if rows else [()] * 7
        types = (np.int64, np.int64, np.int64, np.int64, bool, np.int64, np.float64)
        names = ('pair', 's', 'a', 'next', 'terminal', 'count', 'reward')
        return {
            name: np.asarray(column, dtype=kind)
            for name, column, kind in zip(names, columns, types, strict=True)
        }

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The table and the model, one row per (s, a, outcome)."""
        arrays = super().to_arrays()
        model = self.model_outcomes()
        for name in ('s', 'a', 'reward', 'next', 'terminal', 'count'):
            arrays[f'model_{name}'] = model[name]
        return arrays

    def _load_extra(self, arrays, rows: int) -> None:
        names = ('model_s', 'model_a', 'model_reward', 'model_next', 'model_terminal')
        missing = [n for n in names if n not in arrays]
        if missing:
            raise ValueError(f'Dyna-Q model arrays missing: {", ".join(missing)}')
        s, a, r, nxt, term = (np.asarray(arrays[n]) for n in names)
        size = s.shape[0]
        # Files from before outcomes were counted hold one outcome per pair, seen once.
        count = np.asarray(arrays['model_count']) if 'model_count' in arrays else np.ones(size)
        if any(x.ndim != 1 or x.shape[0] != size for x in (s, a, r, nxt, term, count)):
            raise ValueError('Dyna-Q model arrays have inconsistent shapes')
        if size and (
            s.min() < 0
            or s.max() >= rows
            or a.min() < 0
            or a.max() >= self.num_actions
            or nxt.min() < -1
            or nxt.max() >= rows
            or not np.all(np.isfinite(r))
            or np.any(term != (nxt == -1))
        ):
            raise ValueError('Dyna-Q model refers to rows or actions outside the table')
        if size and count.min() < 1:
            raise ValueError('Dyna-Q model holds an outcome seen fewer than once')
        outcomes = list(zip(nxt.astype(int).tolist(), term.astype(bool).tolist(), strict=True))
        if len(set(zip(s.tolist(), a.tolist(), outcomes, strict=True))) != size:
            raise ValueError('Dyna-Q model holds an outcome of a state-action pair twice')
        self._forget_model()
        for row in zip(
            s.astype(int).tolist(),
            a.astype(int).tolist(),
            outcomes,
            r.astype(float).tolist(),
            count.astype(int).tolist(),
            strict=True,
        ):
            self._remember(*row)


# Every learner by name; prioritized_sweeping adds its own when the package is imported.
_LEARNER_CLASSES: dict[str, type[TabularLearner]] = {
    cls.name: cls for cls in (QLearning, Sarsa, DynaQ)
}


def register_learner(cls: type[TabularLearner]) -> type[TabularLearner]:
    """Make a learner class (one of LEARNER_NAMES) known to make_learner; the class."""
    if cls.name not in LEARNER_NAMES:
        raise ValueError(f'{cls.name!r} is not one of {", ".join(LEARNER_NAMES)}')
    _LEARNER_CLASSES[cls.name] = cls
    return cls


def make_learner(
    name: str, num_actions: int, config: LearnerConfig | None = None
) -> TabularLearner:
    """A fresh learner by name (one of LEARNER_NAMES or an alias)."""
    return _LEARNER_CLASSES[canonical_learner_name(name)](num_actions, config)
