"""Learners on hand-made grid MDPs with optimal values from value iteration."""

from grid_mdps import DYNA_MAZE, STEALTH_GRID, GridMDP, greedy_return, run_episode
import numpy as np
import pytest
from stealth_agent.learners import (
    TABULAR_LEARNERS,
    DynaQ,
    LearnerConfig,
    QLearning,
    Sarsa,
    argmax_random,
    canonical_learner_name,
    make_learner,
)
from stealth_agent.protocol import ProtocolAgent
from stealth_agent.schedules import Schedule
from stealth_agent.state_index import StateIndex, StateMapping

GAMMA = 0.99
# One-step SARSA learns the values of the policy it follows; with epsilon fixed it may keep a
# detour away from the lights. Decaying epsilon to 0 makes it converge to the optimal policy.
SARSA_EPSILON = Schedule('linear', 0.2, 0.0, 150)
# The maze with a cost per step (so the initial Q 0 is optimistic and exploration systematic).
COST_MAZE = GridMDP(DYNA_MAZE.layout, step_reward=-1.0, goal_reward=10.0, max_steps=3000)


def config_for(name: str, **changes) -> LearnerConfig:
    epsilon = SARSA_EPSILON if name == 'sarsa' else Schedule.fixed(0.1)
    return LearnerConfig(gamma=GAMMA, epsilon=epsilon, **changes)


def train(name, mdp, episodes, seed, config=None, mapping=None):
    learner = make_learner(name, 4, config or config_for(name))
    agent = ProtocolAgent(learner, StateIndex(mapping), np.random.default_rng(seed))
    results = [run_episode(agent, mdp) for _ in range(episodes)]
    return agent, results


def episodes_to_optimal(name, mdp, seed, limit=400):
    """Episodes of learning until the greedy policy's return is the optimal one."""
    learner = make_learner(name, 4, config_for(name))
    agent = ProtocolAgent(learner, StateIndex(), np.random.default_rng(seed))
    optimal = mdp.optimal_return(GAMMA)
    for episode in range(1, limit + 1):
        run_episode(agent, mdp)
        achieved = greedy_return(learner, agent.index, mdp, GAMMA)
        if achieved is not None and abs(achieved - optimal) < 1e-9:
            return episode
    return limit + 1


def test_rl_agent_defaults():
    config = LearnerConfig()
    assert config.gamma == 0.99
    assert config.alpha(0) == 0.3 and config.alpha(10_000) == 0.3
    assert config.epsilon(0) == 0.1
    assert config.initial_value == 0.0
    assert make_learner('qlearner', 4).name == 'qlearning'  # rl_agent's spelling
    assert canonical_learner_name('Dyna-Q') == 'dyna'
    with pytest.raises(ValueError, match='unknown learner'):
        make_learner('texplore', 4)


@pytest.mark.parametrize('name', TABULAR_LEARNERS)
@pytest.mark.parametrize(
    'mapping', [None, StateMapping('grid', (0.5,))], ids=['exact-index', 'grid-0.5m']
)
def test_greedy_policy_reaches_the_optimal_return(name, mapping):
    optimal = STEALTH_GRID.optimal_return(GAMMA)
    agent, results = train(name, STEALTH_GRID, 250, seed=3, mapping=mapping)
    achieved = greedy_return(agent.learner, agent.index, STEALTH_GRID, GAMMA)
    assert achieved == pytest.approx(optimal, abs=1e-9), (name, achieved, optimal)
    # Undiscounted too: the shortest unseen path, 8 steps (7 costs and the goal).
    assert optimal == pytest.approx(sum(-(GAMMA**t) for t in range(7)) + 10 * GAMMA**7)
    # The learned values on the optimal path are close to the optimal ones.
    start_row = agent.index.lookup(STEALTH_GRID.observation(STEALTH_GRID.start))
    assert agent.learner.q[start_row].max() == pytest.approx(optimal, abs=0.05)


def test_dyna_needs_markedly_fewer_episodes_than_qlearning():
    seeds = range(4)
    q_counts = [episodes_to_optimal('qlearning', COST_MAZE, seed) for seed in seeds]
    dyna_counts = [episodes_to_optimal('dyna', COST_MAZE, seed) for seed in seeds]
    q_mean, dyna_mean = np.mean(q_counts), np.mean(dyna_counts)
    print(
        f'\nepisodes until the greedy policy is optimal (Dyna maze, step cost, seeds 0-3): '
        f'Q-learning {q_counts} mean {q_mean:.1f}; Dyna-Q (n=10) {dyna_counts} '
        f'mean {dyna_mean:.1f}'
    )
    assert max(q_counts) <= 400 and max(dyna_counts) <= 400
    assert dyna_mean * 2.5 <= q_mean


@pytest.mark.parametrize('name', TABULAR_LEARNERS)
def test_same_seed_same_learning_curve_bit_for_bit(name):
    agent_a, curve_a = train(name, STEALTH_GRID, 40, seed=11)
    agent_b, curve_b = train(name, STEALTH_GRID, 40, seed=11)
    assert curve_a == curve_b  # every episode's return, steps, terminal reward, epsilon
    assert agent_a.learner.q.tobytes() == agent_b.learner.q.tobytes()
    assert np.array_equal(agent_a.index.keys_array(), agent_b.index.keys_array())
    _, curve_c = train(name, STEALTH_GRID, 40, seed=12)
    assert [r.actions for r in curve_c] != [r.actions for r in curve_a]


def test_terminal_update_is_alpha_times_reward_minus_q():
    learner = QLearning(2, LearnerConfig.constant(alpha=0.3, initial_value=1.0))
    learner.update(0, 1, 5.0, None, True)
    assert learner.q[0, 1] == 1.0 + 0.3 * (5.0 - 1.0)
    assert learner.q[0, 0] == 1.0


def test_qlearning_target_bootstraps_on_the_maximum():
    learner = QLearning(3, LearnerConfig.constant(gamma=0.9, alpha=0.5))
    learner.ensure_rows(2)
    learner.q[1] = [1.0, 4.0, 2.0]
    error = learner.update(0, 2, 1.0, 1, False)
    assert error == 1.0 + 0.9 * 4.0
    assert learner.q[0, 2] == 0.5 * (1.0 + 0.9 * 4.0)


def test_sarsa_target_uses_the_next_action():
    learner = Sarsa(3, LearnerConfig.constant(gamma=0.9, alpha=0.5))
    learner.ensure_rows(2)
    learner.q[1] = [1.0, 4.0, 2.0]
    learner.update(0, 0, 1.0, 1, False, a_next=2)
    assert learner.q[0, 0] == 0.5 * (1.0 + 0.9 * 2.0)
    with pytest.raises(ValueError, match='next action'):
        learner.update(0, 0, 1.0, 1, False)


def learn_alike(learner, other, seed: int) -> ProtocolAgent:
    """Train both on STEALTH_GRID with the same seed; assert equal episodes and tables."""
    agent = ProtocolAgent(learner, StateIndex(), np.random.default_rng(seed))
    reference = ProtocolAgent(other, StateIndex(), np.random.default_rng(seed))
    for _ in range(15):
        assert run_episode(agent, STEALTH_GRID) == run_episode(reference, STEALTH_GRID)
    assert agent.learner.q.tobytes() == reference.learner.q.tobytes()
    return agent


def test_dyna_without_planning_is_qlearning_bit_for_bit():
    config = config_for('dyna', n_planning=0)
    dyna = learn_alike(DynaQ(4, config), QLearning(4, config), seed=5)
    assert dyna.learner.model_size > 0


def test_dyna_planning_needs_the_generator():
    learner = DynaQ(2)
    with pytest.raises(ValueError, match='random generator'):
        learner.update(0, 0, 1.0, 1, False)
    assert learner.num_rows == 0 and learner.model_size == 0


def test_random_tie_breaking_picks_every_maximal_action_and_nothing_else():
    rng = np.random.default_rng(0)
    values = np.array([1.0, 3.0, 3.0, 0.0, 3.0])
    picks = {argmax_random(values, rng) for _ in range(200)}
    assert picks == {1, 2, 4}
    learner = QLearning(4, LearnerConfig.constant(epsilon=0.0))
    assert {learner.act(0, rng) for _ in range(200)} == {0, 1, 2, 3}


def test_epsilon_greedy_explores_at_rate_epsilon():
    rng = np.random.default_rng(1)
    learner = QLearning(4, LearnerConfig.constant(epsilon=0.2))
    learner.ensure_rows(1)
    learner.q[0] = [0.0, 0.0, 1.0, 0.0]
    actions = np.array([learner.act(0, rng) for _ in range(20_000)])
    # Greedy 80 % plus a quarter of the 20 % random picks.
    assert np.mean(actions == 2) == pytest.approx(0.8 + 0.2 / 4, abs=0.01)
    assert all(learner.act(0, rng, greedy=True) == 2 for _ in range(50))


def test_the_table_grows_and_keeps_its_values():
    learner = QLearning(2, LearnerConfig.constant(initial_value=-1.0))
    learner.update(0, 0, 3.0, None, True)
    before = learner.q[0].copy()
    learner.update(5000, 1, 1.0, 70_000, False)
    assert learner.num_rows == 70_001
    assert np.array_equal(learner.q[0], before)
    assert learner.q[69_999, 0] == -1.0


@pytest.mark.parametrize(
    ('args', 'message'),
    [
        ((0, 0, float('nan'), 1, False), 'reward must be finite'),
        ((0, 0, float('inf'), None, True), 'reward must be finite'),
        ((0, 4, 1.0, 1, False), 'action 4 out of range'),
        ((-1, 0, 1.0, 1, False), 'state row'),
        ((0, 0, 1.0, None, False), 'next state'),
        ((0, 0, 1.0, 1.5, False), 'state row must be an integer'),
    ],
)
@pytest.mark.parametrize('cls', [QLearning, Sarsa, DynaQ])
def test_bad_updates_are_rejected_and_change_nothing(cls, args, message):
    learner = cls(4)
    learner.ensure_rows(2)
    learner.q[:] = 7.0
    before = learner.q.copy()
    with pytest.raises(ValueError, match=message):
        learner.update(*args, a_next=0, rng=np.random.default_rng(0))
    assert np.array_equal(learner.q, before) and learner.updates == 0


@pytest.mark.parametrize('count', [0, -3, 2.5, float('nan'), 'four'])
def test_an_unusable_action_count_is_rejected(count):
    with pytest.raises(ValueError, match='action count'):
        QLearning(count)


class LastSampleDyna(QLearning):
    """The textbook Dyna-Q model (the last outcome of each pair), as the reference."""

    def __init__(self, num_actions, config):
        super().__init__(num_actions, config)
        self.pairs, self.model = [], {}

    def _after_update(self, s, a, r, s_next, terminated, rng) -> None:
        if (s, a) not in self.model:
            self.pairs.append((s, a))
        self.model[(s, a)] = (r, None if terminated else s_next)
        for i in rng.integers(len(self.pairs), size=self.config.n_planning).tolist():
            s, a = self.pairs[i]
            reward, next_row = self.model[(s, a)]
            target = reward if next_row is None else reward + GAMMA * self._q[next_row].max()
            self._q[s, a] += self._alpha * (target - self._q[s, a])


def test_dyna_on_a_deterministic_task_is_the_textbook_model_bit_for_bit():
    config = config_for('dyna', n_planning=10)
    learn_alike(DynaQ(4, config), LastSampleDyna(4, config), seed=7)


def test_dyna_plans_on_the_expected_outcome_not_the_last_one():
    """A pair that led 9 times to safety (reward 0) and once to a detection (-1000): planning
    moves Q towards -100, where the last sample alone would say -1000 or 0."""
    learner = DynaQ(1, LearnerConfig.constant(gamma=0.9, alpha=1.0, n_planning=0))
    rng = np.random.default_rng(0)
    for reward in [0.0] * 8 + [-1000.0, 0.0]:
        learner.update(0, 0, reward, None, True, rng=rng)
    assert learner.q[0, 0] == 0.0  # the last real update, alpha 1
    learner.plan(1, rng)
    assert learner.q[0, 0] == pytest.approx(-100.0)
    # Different next states count apart, with their rewards averaged per outcome.
    other = DynaQ(1, learner.config)
    other.update(1, 0, 2.0, 2, False, rng=rng)
    other.update(1, 0, 4.0, 2, False, rng=rng)
    other.update(1, 0, -1.0, 3, False, rng=rng)
    other.q[2, 0], other.q[3, 0] = 10.0, 20.0
    other.plan(1, rng)
    expected = (2 * (3.0 + 0.9 * 10.0) + 1 * (-1.0 + 0.9 * 20.0)) / 3
    assert other.q[1, 0] == pytest.approx(expected)


def test_the_counted_model_survives_saving_and_an_old_file_loads_as_seen_once():
    learner = DynaQ(2, LearnerConfig.constant(gamma=0.9, alpha=0.5, n_planning=3))
    rng = np.random.default_rng(1)
    for reward, s_next in ((1.0, 1), (3.0, 1), (-5.0, 2), (0.5, 1)):
        learner.update(0, 1, reward, s_next, False, rng=rng)
    learner.update(2, 0, -1000.0, None, True, rng=rng)
    arrays = learner.to_arrays()
    assert sorted(arrays['model_count'].tolist()) == [1, 1, 3]
    restored = DynaQ(2, learner.config)
    restored.load_arrays(arrays, learner.episodes, learner.updates)
    assert restored.to_arrays().keys() == arrays.keys()
    for name, values in restored.to_arrays().items():
        np.testing.assert_array_equal(values, arrays[name], err_msg=name)
    old = {k: v for k, v in arrays.items() if k != 'model_count'}
    single = {k: v[[0, 2]] if k.startswith('model_') else v for k, v in old.items()}
    restored.load_arrays(single, 0, 0)
    assert restored.to_arrays()['model_count'].tolist() == [1, 1]
    twice = {k: np.concatenate([v, v]) if k.startswith('model_') else v for k, v in old.items()}
    with pytest.raises(ValueError, match='twice'):
        restored.load_arrays(twice, 0, 0)
    with pytest.raises(ValueError, match='fewer than once'):
        restored.load_arrays({**arrays, 'model_count': np.zeros(3, dtype=np.int64)}, 0, 0)
