"""Greedy evaluation episodes inside a learning run (agent_node's eval_every), without ROS."""

import numpy as np
import pytest
from stealth_agent.learners import LearnerConfig, make_learner
from stealth_agent.protocol import ProtocolAgent, is_greedy_episode
from stealth_agent.schedules import Schedule
from stealth_agent.state_index import StateIndex


def test_every_mth_episode_is_greedy_counting_from_zero():
    assert [e for e in range(12) if is_greedy_episode(e, 4)] == [3, 7, 11]
    assert [e for e in range(4) if is_greedy_episode(e, 1)] == [0, 1, 2, 3]
    assert not any(is_greedy_episode(e, 0) for e in range(100))


@pytest.mark.parametrize('bad', [-1, 1.5, True, '3', None])
def test_eval_every_must_be_a_non_negative_integer(bad):
    with pytest.raises(ValueError, match='eval_every must be an integer >= 0'):
        is_greedy_episode(0, bad)


def corridor_episode(agent, length=4):
    """Start at 0; action 1 moves right, 0 left; -1 per step, +10 at `length`."""
    position, steps = 0, agent.handle([0.0], 0.0, False)
    while True:
        position = max(0, position - 1) if steps.action == 0 else position + 1
        done = position == length or agent.number_actions >= 30
        steps = agent.handle([float(position)], 10.0 if position == length else -1.0, done)
        if done:
            return steps.result


def test_a_greedy_episode_neither_learns_nor_moves_the_schedules():
    config = LearnerConfig(
        0.9, Schedule('linear', 0.5, 0.1, 10.0), Schedule('linear', 0.5, 0.1, 10.0), 0.0, 5
    )
    learner = make_learner('dyna', 2, config)
    agent = ProtocolAgent(learner, StateIndex(), np.random.default_rng(4))
    for _ in range(3):
        corridor_episode(agent)
    q, model, episodes = learner.q.copy(), learner.model_size, learner.episodes
    epsilon, alpha = learner.epsilon, learner.alpha
    agent.set_learning(False)
    result = corridor_episode(agent)
    assert not result.learning and result.epsilon == 0.0
    assert result.episode == 3 and result.learner_episode == episodes
    assert np.array_equal(learner.q[: q.shape[0]], q) and learner.model_size == model
    assert (learner.episodes, learner.epsilon, learner.alpha) == (episodes, epsilon, alpha)
    agent.set_learning(True)
    result = corridor_episode(agent)
    assert result.learning and result.episode == 4 and learner.episodes == episodes + 1


def test_the_mode_changes_only_between_episodes():
    agent = ProtocolAgent(make_learner('qlearning', 2), StateIndex(), np.random.default_rng(0))
    agent.handle([0.0], 0.0, False)
    with pytest.raises(RuntimeError, match='only change between episodes'):
        agent.set_learning(False)
    assert agent.learning
    agent.handle([1.0], 1.0, True)
    agent.set_learning(False)
    assert not agent.learning and agent.epsilon == 0.0
