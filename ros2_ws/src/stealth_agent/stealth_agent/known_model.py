"""The best way a counted model knows to the goal, for a learner that explores by optimism
(plain numpy, no rclpy): its greedy policy, kept apart from its exploration as E3's exploitation
policy is (Kearns & Singh 2002).

Prioritized sweeping starts every pair it has not tried at an upper bound (the floor plan's
value with the lights dark), so the greedy route of its table is the next way it would try,
not the best it knows: on map1-exposure it reached the goal unseen in its third episode, then
walked into a light in each of the next 38 while it ruled out every shorter way, and its greedy
evaluations, which followed the table, failed until episode 70. Its greedy policy is instead:
from a state with a known way worth more than stopping (STOPPING_VALUE, 0: a way to the goal,
whose reward outweighs the way's costs, where a detection's penalty does not), the best known
way; from any other state, the table's choice (the way it would try next, as before).

The known values come from value iteration over the pairs the model has seen, each worth its
expected outcome (the outcomes weighted by how often they were seen); a pair never tried leads
nowhere known (-inf). Values start below every return (-inf) and rise to the least fixed point,
so a cycle of rewards 0 (holding in the dark where lights move) carries no value it never
earned.
"""

from __future__ import annotations

import numpy as np

from .learners import first_or_random

STOPPING_VALUE = 0.0  # a known way must be worth more than this to be followed
TOLERANCE = 1e-6  # a sweep that moves no value by more than this ends the iteration


def known_values(
    shape: tuple[int, int],
    pairs: tuple[np.ndarray, np.ndarray],
    outcomes: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    gamma: float,
    max_sweeps: int = 100_000,
) -> np.ndarray:
    """The known values of every (row, action), shape ``shape``.

    ``pairs``: (s, a) of each pair the model has seen (distinct); ``outcomes``: (pair index,
    next row, terminal, count, mean reward) of each outcome seen, one entry per outcome of a
    pair. A pair never tried, or from which no known way reaches an end, is worth -inf.
    """
    s, a = (np.asarray(x, dtype=np.int64) for x in pairs)
    pair, next_row, terminal, count, reward = (np.asarray(x) for x in outcomes)
    q = np.full(shape, -np.inf)
    if s.size == 0:
        return q
    count = count.astype(np.float64)
    seen = np.bincount(pair, weights=count, minlength=s.size)
    terminal = terminal.astype(bool)
    following = np.where(terminal, 0, next_row)  # a terminal outcome's next row is not read
    known = q[s, a]
    for _ in range(max_sweeps):
        # -inf (a way that reaches no known end yet) stays -inf: counts are >= 1, no 0 * inf.
        value = np.where(terminal, reward, reward + gamma * q.max(axis=1)[following])
        updated = np.bincount(pair, weights=count * value, minlength=s.size) / seen
        finite = np.isfinite(updated) & np.isfinite(known)
        settled = np.array_equal(np.isfinite(updated), np.isfinite(known)) and (
            not finite.any() or np.abs(updated[finite] - known[finite]).max() <= TOLERANCE
        )
        q[s, a] = known = updated
        if settled:
            break
    return q


def greedy_known(
    values: np.ndarray, table: np.ndarray, rng: np.random.Generator | None = None
) -> int:
    """The greedy action of one state: of its known ``values`` the largest where it is worth
    more than STOPPING_VALUE, ties going to the larger value in ``table`` (the learner's row);
    otherwise the table's largest. Remaining ties at random (without ``rng``: the first)."""
    if values.max() <= STOPPING_VALUE:
        return first_or_random(table, rng)
    best = np.flatnonzero(values == values.max())
    if best.size == 1:
        return int(best[0])
    return int(best[first_or_random(table[best], rng)])
