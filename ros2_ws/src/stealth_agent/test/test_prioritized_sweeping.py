"""Prioritized sweeping on hand-built MDPs: its queue, its predecessors, its threshold."""

from grid_mdps import DYNA_MAZE, GridMDP, greedy_return, run_episode
import numpy as np
import pytest
from stealth_agent.learners import LearnerConfig, QLearning, canonical_learner_name, make_learner
from stealth_agent.prioritized_sweeping import PrioritizedSweeping
from stealth_agent.protocol import ProtocolAgent
from stealth_agent.schedules import Schedule
from stealth_agent.state_index import StateIndex


def chain(theta: float = 0.01) -> PrioritizedSweeping:
    """Rows 0 -> 1 -> 2 -> goal, one action, walked once without planning (n 0): each step
    costs 1 and the goal pays 10, gamma 0.5, alpha 1."""
    learner = PrioritizedSweeping(
        1, LearnerConfig.constant(gamma=0.5, alpha=1.0, n_planning=0, theta=theta)
    )
    learner.update(0, 0, -1.0, 1, False)
    learner.update(1, 0, -1.0, 2, False)
    learner.update(2, 0, 10.0, None, True)
    return learner


def test_the_names():
    assert canonical_learner_name('prioritized_sweeping') == 'prioritized'
    assert canonical_learner_name('Prioritized-Sweeping') == 'prioritized'
    assert isinstance(make_learner('prioritized', 4), PrioritizedSweeping)


def test_the_largest_expected_change_leaves_the_queue_first():
    learner = chain()
    np.testing.assert_array_equal(learner.q[:, 0], [-1.0, -1.0, 10.0])
    # (1, 0) would move from -1 to -1 + 0.5 * 10 = 4; (0, 0) from -1 to -1 + 0.5 * -1 = -1.5.
    assert learner.queued() == [(1, 0, 5.0), (0, 0, 0.5)]
    assert learner.predecessors(2) == [(1, 0)] and learner.predecessors(1) == [(0, 0)]
    assert learner.predecessors(0) == []  # nothing led back to the start
    assert learner.plan(1) == 1
    assert learner.q[1, 0] == 4.0
    # Its value changed, so its predecessor's priority was raised to |(-1 + 0.5 * 4) - -1| = 2.
    assert learner.queued() == [(0, 0, 2.0)]
    assert learner.plan(10) == 1  # the queue ran dry after one more update
    assert learner.q[0, 0] == 1.0 and learner.queue_size == 0


def test_equal_priorities_leave_in_the_order_they_came():
    learner = PrioritizedSweeping(2, LearnerConfig.constant(gamma=0.5, alpha=1.0, n_planning=0))
    learner.update(5, 1, 0.0, 7, False)
    learner.update(3, 0, 0.0, 7, False)
    learner.update(7, 0, 4.0, None, True)
    assert learner.queued() == [(5, 1, 2.0), (3, 0, 2.0)]


def test_nothing_at_or_below_theta_is_queued():
    learner = chain(theta=2.0)
    # (0, 0)'s 0.5 was cut off; (1, 0)'s 5 waits, but the 2 it gives (0, 0) is not above 2.
    assert learner.queued() == [(1, 0, 5.0)]
    assert learner.plan(10) == 1
    assert learner.q[0, 0] == -1.0 and learner.queue_size == 0


def test_planning_uses_the_expected_outcome_over_the_counted_ones():
    """Three times to row 1 (reward 1), once to a detection (-9): the queued change and the
    update are those of the expectation, not of the last sample."""
    learner = PrioritizedSweeping(1, LearnerConfig.constant(gamma=0.5, alpha=1.0, n_planning=0))
    learner.ensure_rows(2)
    learner.q[1, 0] = 6.0
    for _ in range(3):
        learner.update(0, 0, 1.0, 1, False)
    learner.update(0, 0, -9.0, None, True)
    assert learner.q[0, 0] == -9.0  # the last real update, alpha 1
    expected = (3 * (1.0 + 0.5 * 6.0) + 1 * -9.0) / 4
    assert learner.expected_target(0) == expected
    assert learner.queued() == [(0, 0, expected + 9.0)]
    assert learner.predecessors(1) == [(0, 0)]  # the terminal outcome is no row's predecessor
    learner.plan(1)
    assert learner.q[0, 0] == expected


def test_a_real_step_plans_n_updates_and_without_planning_it_is_qlearning():
    config = LearnerConfig.constant(gamma=0.5, alpha=1.0, n_planning=1)
    learner = PrioritizedSweeping(1, config)
    learner.update(0, 0, -1.0, 1, False)
    learner.update(1, 0, -1.0, 2, False)  # queues (0, 0) (to -1.5) and plans it at once
    assert learner.q[0, 0] == -1.5 and learner.queue_size == 0
    learner.update(2, 0, 10.0, None, True)  # queues (1, 0) (to 4) and plans it at once
    assert learner.q[1, 0] == 4.0 and learner.queued() == [(0, 0, 2.5)]
    mdp = GridMDP(DYNA_MAZE.layout, step_reward=-1.0, goal_reward=10.0, max_steps=500)
    config = LearnerConfig.constant(gamma=0.95, n_planning=0)
    tables = []
    for learner in (PrioritizedSweeping(4, config), QLearning(4, config)):
        agent = ProtocolAgent(learner, StateIndex(), np.random.default_rng(4))
        curve = [run_episode(agent, mdp) for _ in range(5)]
        tables.append((curve, learner.q.tobytes()))
    assert tables[0] == tables[1]


def test_a_saved_learner_keeps_its_queue_and_rebuilds_the_predecessors():
    learner = chain()
    arrays = learner.to_arrays()
    restored = PrioritizedSweeping(1, learner.config)
    restored.load_arrays(arrays, learner.episodes, learner.updates)
    assert restored.predecessors(2) == [(1, 0)] and restored.predecessors(1) == [(0, 0)]
    assert restored.queued() == learner.queued() == [(1, 0, 5.0), (0, 0, 0.5)]
    # A Dyna-Q file (no queue) loads with an empty queue; a queue the model lacks is refused.
    dyna_only = {k: v for k, v in arrays.items() if not k.startswith('queue_')}
    restored.load_arrays(dyna_only, 0, 0)
    assert restored.queue_size == 0 and restored.predecessors(2) == [(1, 0)]
    with pytest.raises(ValueError, match='which the model does not'):
        restored.load_arrays({**arrays, 'queue_s': np.array([9, 0])}, 0, 0)
    with pytest.raises(ValueError, match='not > 0'):
        restored.load_arrays({**arrays, 'queue_priority': np.array([5.0, 0.0])}, 0, 0)


def test_predecessors_are_in_the_order_the_pairs_were_first_tried():
    learner = PrioritizedSweeping(2, LearnerConfig.constant(n_planning=0))
    learner.update(4, 0, 0.0, 1, False)  # pair 0
    learner.update(5, 1, 0.0, 2, False)  # pair 1
    learner.update(5, 1, 0.0, 3, False)  # pair 1 again, elsewhere
    learner.update(4, 0, 0.0, 3, False)  # pair 0 again, elsewhere: before pair 1 at row 3
    assert learner.predecessors(3) == [(4, 0), (5, 1)]


def episodes_to_optimal(name: str, seed: int, limit: int = 200) -> int:
    mdp = GridMDP(DYNA_MAZE.layout, step_reward=-1.0, goal_reward=10.0, max_steps=3000)
    config = LearnerConfig(gamma=0.95, epsilon=Schedule.fixed(0.1), n_planning=20)
    learner = make_learner(name, 4, config)
    agent = ProtocolAgent(learner, StateIndex(), np.random.default_rng(seed))
    optimal = mdp.optimal_return(0.95)
    for episode in range(1, limit + 1):
        run_episode(agent, mdp)
        achieved = greedy_return(learner, agent.index, mdp, 0.95)
        if achieved is not None and abs(achieved - optimal) < 1e-9:
            return episode
    return limit + 1


def test_fewer_episodes_than_dyna_with_as_many_planning_updates():
    """On the Dyna maze with a cost per step: a tenth of Q-learning's episodes, and never more
    than Dyna-Q's with the same 20 planning updates per step."""
    seeds = range(6)
    counts = {
        name: [episodes_to_optimal(name, seed) for seed in seeds]
        for name in ('prioritized', 'dyna', 'qlearning')
    }
    sweeping, dyna, qlearning = (np.array(c) for c in counts.values())
    assert np.all(sweeping <= dyna) and sweeping.mean() < dyna.mean(), counts
    assert sweeping.mean() * 10 <= qlearning.mean(), counts


def settled_on_the_optimum(initial_value: float, seed: int, episodes: int = 60) -> int | None:
    """The episode from which the greedy route stays optimal (undiscounted, epsilon 0, so only
    the initial Q explores), or None when the last one is not."""
    mdp = GridMDP(DYNA_MAZE.layout, step_reward=-1.0, goal_reward=10.0, max_steps=200)
    config = LearnerConfig(
        gamma=1.0,
        alpha=Schedule.fixed(1.0),
        epsilon=Schedule.fixed(0.0),
        initial_value=initial_value,
        n_planning=200,
    )
    learner = make_learner('prioritized', 4, config)
    agent = ProtocolAgent(learner, StateIndex(), np.random.default_rng(seed))
    optimal, since = mdp.optimal_return(1.0), None
    for episode in range(1, episodes + 1):
        run_episode(agent, mdp)
        achieved = greedy_return(learner, agent.index, mdp, 1.0)
        good = achieved is not None and abs(achieved - optimal) < 1e-9
        since = (since or episode) if good else None
    return since


def test_optimism_at_the_goal_reward_finds_the_optimum_where_q_0_keeps_the_first_route():
    """The harness's exploration (tuned_config): untried pairs worth the goal reward, epsilon 0.
    Q 0 is optimistic only until the goal is found; then the first route found stands (seed 7:
    2 steps longer for good)."""
    seeds = range(8)
    optimistic = [settled_on_the_optimum(10.0, seed) for seed in seeds]
    assert all(s is not None and s <= 5 for s in optimistic), optimistic
    assert settled_on_the_optimum(0.0, 7) is None
