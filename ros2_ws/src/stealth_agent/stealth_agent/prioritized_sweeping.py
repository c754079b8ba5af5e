"""Prioritized sweeping (Moore & Atkeson 1993; Sutton & Barto 2nd ed., 8.4) on Dyna-Q's counted
model (plain Python + numpy, no rclpy).

Dyna-Q plans on remembered pairs drawn uniformly at random, so most of its planning updates
change nothing: far from the goal, before the goal's value has reached them, every target is
what the pair already holds. Prioritized sweeping plans where values changed instead: each
pair whose expected update would move it by more than theta waits in a queue, the largest
first; updating a pair that changes max_a Q(s, a) queues each remembered predecessor of s
(every pair the model has seen lead to s) with its own expected TD error as priority. One
discovery (the goal, a detection) thus travels back along every known way to it within the
planning updates of one real step, where Dyna-Q needs many steps and Q-learning an episode per
move.

The model is DynaQ's: per pair, each outcome seen with its count and mean reward, so a target is
the expected one over the outcomes seen (slip, the simulated robot's pose noise, moving lights
seen at another phase), never the last sample. A real step updates Q(s, a) as Q-learning does
(so n 0 is Q-learning), counts the outcome, queues the pair (what the sample left of its
expected TD error) and the predecessors of s, then makes up to n planning updates from the
queue. A popped pair gets Q += alpha * (expected target - Q). The queue outlives episodes (work
the n updates of one step left over is done at the next); equal priorities leave in the order
they came, so that a seed fixes everything. A saved policy keeps the table, the model and the
queue (``queue_s``, ``queue_a``, ``queue_priority``, in the order they would leave); the
predecessors are rebuilt from the model, so a resumed run learns as the uninterrupted one.

Exploration, as Moore and Atkeson's: optimism in the face of uncertainty. A pair the model has
not seen keeps its row's initial values (``initial_value``, or a prior given to
``ProtocolAgent``), which the planning updates carry back to every known way to it; set to an
upper bound on the true values with epsilon 0 (the harness's settings: the floor plan's values
with the lights dark, ``stealth_core.floor_plan_prior``, else the goal reward) every
untried pair that could still lie on a cheaper route than the best known is tried once, and the
table's route is the optimum once none is left. With Q 0 and step costs below 0 untried pairs
look better only until the goal is found, and the first route found stands.

The greedy policy (greedy evaluations, rollouts of a saved policy) is not the table's, which
is the next way to try, but the best way the model knows to the goal where it knows one
(``known_model``, as E3 keeps its exploitation policy apart), recomputed when the model changed.
"""

import bisect
import heapq

import numpy as np

from .known_model import greedy_known, known_values
from .learners import DynaQ, LearnerConfig, register_learner


@register_learner
class PrioritizedSweeping(DynaQ):
    """Prioritized sweeping: Dyna-Q's model, planning in order of expected TD error."""

    name = 'prioritized'

    def __init__(self, num_actions: int, config: LearnerConfig | None = None):
        super().__init__(num_actions, config)
        self._forget_queue()

    def greedy_action(self, s: int, rng: np.random.Generator | None = None) -> int:
        """The action of the best way the model knows from row s to the goal; where it knows
        none, the table's (``known_model.greedy_known``). Ties at random (without ``rng``: the
        first)."""
        s = self._check_row(s)
        self.ensure_rows(s + 1)
        values = self._known()
        if s >= values.shape[0]:  # a state first seen now: nothing known of it
            return super().greedy_action(s, rng)
        return greedy_known(values[s], self._q[s], rng)

    def _known(self) -> np.ndarray:
        """known_model.known_values of the model as it is (cached until a real update)."""
        if self._known_at != self.updates or self._known_values is None:
            model = self.model_outcomes()
            self._known_values = known_values(
                (self._rows, self.num_actions),
                (np.asarray(self._model_s), np.asarray(self._model_a)),
                tuple(model[name] for name in ('pair', 'next', 'terminal', 'count', 'reward')),
                self.config.gamma,
            )
            self._known_at = self.updates
        return self._known_values

    def _forget_queue(self) -> None:
        self._known_values: np.ndarray | None = None  # known_model's values, at _known_at
        self._known_at = -1
        # Next row -> model indices of the pairs seen to lead there, ascending: the same order
        # whether learned or loaded from a file, so that a resumed run plans alike.
        self._predecessors: dict[int, list[int]] = {}
        # (-priority, arrival, model index); stale entries are skipped when popped.
        self._heap: list[tuple[float, int, int]] = []
        self._queued: dict[int, float] = {}  # model index -> its priority in the queue
        self._arrivals = 0

    @property
    def queue_size(self) -> int:
        """Pairs waiting in the queue."""
        return len(self._queued)

    def queued(self) -> list[tuple[int, int, float]]:
        """The queue as (s, a, priority), in the order it would be popped."""
        waiting = sorted(
            (entry for entry in self._heap if self._queued.get(entry[2]) == -entry[0]),
        )
        return [(self._model_s[i], self._model_a[i], -p) for p, _, i in waiting]

    def predecessors(self, s: int) -> list[tuple[int, int]]:
        """The (s, a) pairs the model has seen lead to row s, in the order they were first
        tried."""
        return [(self._model_s[i], self._model_a[i]) for i in self._predecessors.get(s, ())]

    def _remember(self, s, a, outcome, reward, count) -> int:
        i = super()._remember(s, a, outcome, reward, count)
        next_row, terminal = outcome
        if not terminal:
            known = self._predecessors.setdefault(next_row, [])
            where = bisect.bisect_left(known, i)
            if where == len(known) or known[where] != i:
                known.insert(where, i)
        return i

    def _forget_model(self) -> None:
        super()._forget_model()
        self._forget_queue()

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The table, the model and the queue."""
        arrays = super().to_arrays()
        waiting = self.queued()
        arrays['queue_s'] = np.asarray([s for s, _, _ in waiting], dtype=np.int64)
        arrays['queue_a'] = np.asarray([a for _, a, _ in waiting], dtype=np.int64)
        arrays['queue_priority'] = np.asarray([p for _, _, p in waiting], dtype=np.float64)
        return arrays

    def _load_extra(self, arrays, rows: int) -> None:
        super()._load_extra(arrays, rows)  # forgets the queue, rebuilds the predecessors
        names = ('queue_s', 'queue_a', 'queue_priority')
        if not any(name in arrays for name in names):
            return  # a Dyna-Q model alone: start with an empty queue
        s, a, priority = (np.asarray(arrays.get(name, ())) for name in names)
        if not (s.ndim == a.ndim == priority.ndim == 1 and s.size == a.size == priority.size):
            raise ValueError('prioritized sweeping queue arrays have inconsistent shapes')
        if s.size and not (np.all(np.isfinite(priority)) and priority.min() > 0):
            raise ValueError('prioritized sweeping queue holds a priority that is not > 0')
        for row, action, value in zip(s.tolist(), a.tolist(), priority.tolist(), strict=True):
            i = self._model_index.get((row, action))
            if i is None or i in self._queued:
                raise ValueError(
                    f'prioritized sweeping queue holds ({row}, {action}), which the model does '
                    'not, or twice'
                )
            self._push(i, float(value))

    def _after_update(self, s, a, r, s_next, terminated, rng) -> None:
        i = self._remember(s, a, (-1 if terminated else s_next, bool(terminated)), r, 1)
        self._queue(i)
        self._queue_predecessors(s)
        self.plan(self.config.n_planning, rng)

    def _queue(self, i: int) -> None:
        """Queue pair i if its expected TD error exceeds theta (keeping the larger priority)."""
        priority = abs(self.expected_target(i) - self._q[self._model_s[i], self._model_a[i]])
        if priority <= self.config.theta or self._queued.get(i, -1.0) >= priority:
            return
        self._push(i, priority)

    def _push(self, i: int, priority: float) -> None:
        self._queued[i] = priority
        heapq.heappush(self._heap, (-priority, self._arrivals, i))
        self._arrivals += 1

    def _queue_predecessors(self, s: int) -> None:
        for i in self._predecessors.get(s, ()):
            self._queue(i)

    def _pop(self) -> int | None:
        """The model index of the pair with the largest priority, or None when none waits."""
        while self._heap:
            negative, _, i = heapq.heappop(self._heap)
            if self._queued.get(i) == -negative:
                del self._queued[i]
                return i
        return None

    def plan(self, n: int, rng: np.random.Generator | None = None) -> int:
        """Up to n updates of the queue's first pairs; the number made (fewer when the queue
        runs dry). rng is unused: the queue's order decides."""
        del rng
        q, alpha = self._q, self._alpha
        done = 0
        while done < n:
            i = self._pop()
            if i is None:
                break
            s, a = self._model_s[i], self._model_a[i]
            before = q[s].max()
            q[s, a] += alpha * (self.expected_target(i) - q[s, a])
            done += 1
            if q[s].max() != before:
                self._queue_predecessors(s)
        return done

    def _check_update_extra(self, rng) -> None:
        pass  # no random draws: unlike Dyna-Q, planning needs no generator
