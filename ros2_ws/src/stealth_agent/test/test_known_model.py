"""The best way a counted model knows (known_model), and prioritized sweeping's greedy policy
built on it: plain pytest on hand-built models."""

import numpy as np
from stealth_agent.known_model import greedy_known, known_values
from stealth_agent.learners import LearnerConfig
from stealth_agent.prioritized_sweeping import PrioritizedSweeping


def values_of(shape, outcomes, gamma=1.0):
    """known_values of outcomes given as (s, a, next row or None, count, reward)."""
    pairs = sorted({(s, a) for s, a, *_ in outcomes}, key=[(s, a) for s, a, *_ in outcomes].index)
    index = {pair: i for i, pair in enumerate(pairs)}
    columns = [
        [index[(s, a)] for s, a, *_ in outcomes],
        [-1 if n is None else n for _, _, n, _, _ in outcomes],
        [n is None for _, _, n, _, _ in outcomes],
        [c for *_, c, _ in outcomes],
        [r for *_, r in outcomes],
    ]
    s, a = zip(*pairs, strict=True)
    return known_values(shape, (np.array(s), np.array(a)), tuple(map(np.array, columns)), gamma)


def test_a_known_way_to_the_goal_is_worth_its_return_and_an_untried_pair_nothing_known():
    # 0 -a0-> 1 -a0-> goal (10), each move -1; 0's a1 and 1's a1 never tried.
    q = values_of((2, 2), [(0, 0, 1, 1, -1.0), (1, 0, None, 1, 10.0)])
    np.testing.assert_array_equal(q, [[9.0, -np.inf], [10.0, -np.inf]])


def test_outcomes_count_by_how_often_they_were_seen():
    # From row 0: three times on to row 1 (then the goal, 10), once detected (-10).
    q = values_of((2, 1), [(0, 0, 1, 3, 0.0), (0, 0, None, 1, -10.0), (1, 0, None, 1, 10.0)])
    assert q[0, 0] == (3 * 10.0 - 10.0) / 4


def test_where_no_known_way_beats_stopping_the_table_chooses():
    # A known detection (-2000) and a known way to the goal that costs more than it pays (-3):
    # neither is followed; the table's next try is.
    q = values_of((2, 3), [(0, 0, None, 1, -2000.0), (1, 0, None, 1, -3.0)])
    assert greedy_known(q[0], table=np.array([5.0, 1.0, 8.0])) == 2
    assert greedy_known(q[1], table=np.array([0.0, 4.0, 1.0])) == 1


def test_a_cycle_of_rewards_0_earns_nothing_it_never_earned():
    """Holding in the dark where lights move: rows 0 and 1 lead only to each other, every
    action tried; from the least fixed point they are worth -inf (no known end), never the 0
    a fixed point from above could keep."""
    q = values_of((3, 1), [(0, 0, 1, 1, 0.0), (1, 0, 0, 1, 0.0), (2, 0, None, 1, 5.0)])
    assert np.isneginf(q[0, 0]) and np.isneginf(q[1, 0]) and q[2, 0] == 5.0


def test_discounting_applies_along_the_way():
    q = values_of((2, 1), [(0, 0, 1, 1, -1.0), (1, 0, None, 1, 10.0)], gamma=0.5)
    assert q[0, 0] == -1.0 + 0.5 * 10.0


def test_ties_go_to_the_table_then_the_first_without_a_generator():
    values = np.array([7.0, 7.0, -5.0, 7.0])
    assert greedy_known(values, table=np.array([1.0, 3.0, 9.0, 3.0])) == 1
    picks = {
        greedy_known(values, np.array([1.0, 3.0, 9.0, 3.0]), np.random.default_rng(seed))
        for seed in range(20)
    }
    assert picks == {1, 3}


def optimistic_learner() -> PrioritizedSweeping:
    """Rows 0 -a0-> 1 -a0-> goal found; every other pair untried at the optimistic 100."""
    config = LearnerConfig.constant(gamma=1.0, alpha=1.0, n_planning=10, initial_value=100.0)
    learner = PrioritizedSweeping(2, config)
    learner.update(0, 0, -1.0, 1, False)
    learner.update(1, 0, 10.0, None, True)
    return learner


def test_prioritized_sweeping_s_greedy_policy_is_the_best_known_way_not_the_table_s_next_try():
    learner = optimistic_learner()
    assert int(np.argmax(learner.q[0])) == 1  # the table would try the untried shortcut
    assert learner.greedy_action(0) == 0  # the greedy policy takes the known way
    learner.update(0, 1, -2000.0, None, True)  # the shortcut was tried: detected
    assert learner.greedy_action(0) == 0
    learner.update(1, 1, -2000.0, None, True)
    assert learner.greedy_action(1) == 0


def test_where_no_way_is_known_the_greedy_policy_tries_what_the_table_says():
    config = LearnerConfig.constant(gamma=1.0, alpha=1.0, n_planning=0, initial_value=100.0)
    learner = PrioritizedSweeping(3, config)
    learner.update(0, 0, -2000.0, None, True)  # a detection
    learner.set_initial_row(4, [1.0, 7.0, 3.0])  # a state never left: the table decides
    assert learner.greedy_action(0) in (1, 2) and learner.greedy_action(4) == 1
    assert learner.greedy_action(9) == 0  # a state first seen now, its row at 100 everywhere


def test_a_saved_and_loaded_learner_has_the_same_greedy_policy():
    learner = optimistic_learner()
    assert learner.greedy_action(0) == 0  # its known values cached
    loaded = PrioritizedSweeping(2, learner.config)
    loaded.load_arrays(learner.to_arrays(), learner.episodes, learner.updates)
    assert loaded.greedy_action(0) == 0
    fresh = PrioritizedSweeping(2, learner.config)
    fresh.set_initial_row(0, [1.0, 7.0])
    learner.load_arrays(fresh.to_arrays(), 0, 0)
    assert learner.greedy_action(0) == 1  # no model any more: nothing cached is used
