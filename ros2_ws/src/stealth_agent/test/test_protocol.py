"""rl_agent's processState semantics and bad input, without ROS."""

import math

import numpy as np
import pytest
from stealth_agent.learners import LearnerConfig, QLearning, Sarsa, make_learner
from stealth_agent.protocol import (
    BadInputError,
    Ending,
    EpisodeEndMatcher,
    EpisodeResult,
    ProtocolAgent,
    ResolvedEnd,
    SummaryWait,
    parse_description,
)
from stealth_agent.state_index import StateIndex, mapping_from_description


def make_agent(name='qlearning', learning=True, actions=2, **config):
    learner = make_learner(name, actions, LearnerConfig.constant(**config))
    return ProtocolAgent(learner, StateIndex(), np.random.default_rng(0), learning=learning)


def snapshot(agent):
    return (
        agent.learner.q.copy(),
        len(agent.index),
        agent.index.dim,
        agent.in_episode,
        agent.episode_reward,
        agent.number_actions,
        agent.episode,
        agent.rng.bit_generator.state,
    )


def assert_unchanged(agent, before):
    after = snapshot(agent)
    assert np.array_equal(after[0], before[0])
    assert after[1:] == before[1:]


def test_episode_sums_ignore_the_first_reward_and_count_actions():
    agent = make_agent()
    step = agent.handle([0.0], 1000.0, False)  # first state: its reward is ignored
    assert step.action in (0, 1) and step.result is None
    agent.handle([1.0], -1.0, False)
    agent.handle([2.0], -1.0, False)
    step = agent.handle([3.0], 10.0, True)
    assert step.action is None
    assert step.result.episode == 0
    assert step.result.reward == 8.0
    assert step.result.actions == 3  # first action plus two more; none at the terminal state
    assert step.result.terminal_reward == 10.0
    # The next state starts episode 1, again ignoring its reward.
    assert agent.handle([0.0], -55.0, False).action is not None
    assert agent.handle([1.0], 2.0, True).result == EpisodeResult(
        1, 1, 2.0, 1, 2.0, 0.1, learning=True
    )


def test_terminal_state_updates_towards_the_reward():
    agent = make_agent(alpha=0.5, epsilon=0.0)
    a = agent.handle([0.0], 0.0, False).action
    agent.handle([1.0], 4.0, True)
    row = agent.index.lookup([0.0])
    assert agent.learner.q[row, a] == 0.5 * 4.0
    assert agent.index.lookup([1.0]) is None  # terminal states need no row: no action there


def test_a_terminal_first_state_is_an_empty_episode():
    agent = make_agent()
    step = agent.handle([0.0], 3.0, True)
    assert step.action is None and step.result.actions == 0 and step.result.reward == 0.0
    assert agent.episode == 1 and not agent.learner.q.any()


def test_an_episode_aborted_before_its_first_action_moves_no_schedule():
    agent = make_agent()
    step = agent.handle([0.0], 0.0, True, Ending.ABORTED)
    assert step.result.aborted and step.result.actions == 0
    assert (agent.episode, agent.learner.episodes) == (1, 0)
    # The same state as an rl_msgs terminal one counts as a learning episode.
    agent.handle([0.0], 0.0, True)
    assert (agent.episode, agent.learner.episodes) == (2, 1)


@pytest.mark.parametrize(
    ('state', 'reward', 'message'),
    [
        ([1.0, 0.0], -1.0, 'state has 2 features, expected 1'),
        ([], -1.0, 'state has 0 features, expected 1'),
        ([float('nan')], -1.0, 'non-finite'),
        ([1.0], float('nan'), 'bad reward: nan is not finite'),
        ([1.0], float('inf'), 'bad reward: inf is not finite'),
        ([1.0], -float('inf'), 'bad reward: -inf is not finite'),
    ],
)
@pytest.mark.parametrize('terminal', [False, True])
@pytest.mark.parametrize('name', ['qlearning', 'sarsa', 'dyna'])
def test_bad_messages_mid_episode_change_nothing(name, terminal, state, reward, message):
    agent = make_agent(name)
    agent.handle([0.0], 0.0, False)
    agent.handle([1.0], -1.0, False)
    before = snapshot(agent)
    with pytest.raises(BadInputError, match=message):
        agent.handle(state, reward, terminal)
    assert_unchanged(agent, before)
    # The episode carries on with the next good message.
    assert agent.handle([2.0], -1.0, False).action is not None
    assert agent.handle([3.0], 5.0, True).result.reward == 3.0


def test_a_nan_reward_on_the_first_state_is_ignored_like_any_first_reward():
    agent = make_agent()
    assert agent.handle([0.0], float('nan'), False).action is not None


def test_evaluation_is_greedy_and_never_learns():
    agent = make_agent(learning=False, epsilon=1.0)
    agent.learner.ensure_rows(1)
    agent.index.row([0.0])
    agent.learner.q[0] = [0.0, 1.0]
    for _ in range(20):
        assert agent.handle([0.0], 0.0, False).action == 1
        result = agent.handle([0.0], 7.0, True).result
        assert result.epsilon == 0.0 and not result.learning
    assert agent.learner.q[0].tolist() == [0.0, 1.0]
    assert agent.learner.episodes == 0 and agent.learner.updates == 0


def test_truncation_bootstraps_instead_of_ending_at_the_reward():
    agent = ProtocolAgent(
        QLearning(2, LearnerConfig.constant(gamma=0.5, alpha=1.0, epsilon=0.0)),
        StateIndex(),
        np.random.default_rng(0),
    )
    agent.learner.ensure_rows(2)
    agent.index.row([0.0]), agent.index.row([1.0])
    agent.learner.q[1] = [4.0, 2.0]
    a = agent.handle([0.0], 0.0, False).action
    result = agent.truncate(1.0, [1.0])
    assert result.truncated and result.terminal_reward is None
    assert agent.learner.q[0, a] == 1.0 + 0.5 * 4.0


def corridor_agent_with_a_valued_next_state():
    """Q-learning with gamma 0.5, alpha 1, state [1.0] worth max 4: a timeout there must be
    learned as 1 + 0.5 * 4 = 3, a terminal state as 1."""
    agent = ProtocolAgent(
        QLearning(2, LearnerConfig.constant(gamma=0.5, alpha=1.0, epsilon=0.0)),
        StateIndex(),
        np.random.default_rng(0),
    )
    agent.learner.ensure_rows(2)
    agent.index.row([0.0]), agent.index.row([1.0])
    agent.learner.q[1] = [4.0, 2.0]
    return agent


@pytest.mark.parametrize(
    ('ending', 'learned', 'counted'),
    [(Ending.TERMINATED, 1.0, 1), (Ending.TRUNCATED, 3.0, 1), (Ending.ABORTED, 0.0, 0)],
)
def test_a_terminal_rl_state_is_learned_as_its_ending_says(ending, learned, counted):
    agent = corridor_agent_with_a_valued_next_state()
    a = agent.handle([0.0], 0.0, False).action
    step = agent.handle([1.0], 1.0, True, ending)
    assert step.action is None and step.result.episode == 0 and agent.episode == 1
    assert agent.learner.q[0, a] == learned  # a timeout is not learned as terminal
    assert step.result.truncated == (ending is Ending.TRUNCATED)
    assert step.result.aborted == (ending is Ending.ABORTED)
    assert agent.learner.episodes == counted  # an aborted episode moves no schedule


def test_the_end_matcher_pairs_a_terminal_state_with_its_report_in_either_order():
    matcher = EpisodeEndMatcher()
    assert matcher.terminal([1.0], -1.0, actions=7) is None and matcher.waiting
    assert matcher.report(3, Ending.TERMINATED) is None  # another episode's report
    assert matcher.report(7, Ending.TRUNCATED) == ResolvedEnd((1.0,), -1.0, Ending.TRUNCATED)
    assert not matcher.waiting
    # The report first, then its terminal state.
    assert matcher.report(4, Ending.ABORTED) is None
    assert matcher.terminal([2.0], 0.0, actions=4) == ResolvedEnd((2.0,), 0.0, Ending.ABORTED)
    # A report left over from before an episode's first state never pairs with its end.
    matcher.report(5, Ending.TRUNCATED)
    matcher.new_episode()
    assert matcher.terminal([3.0], 9.0, actions=5) is None
    assert matcher.give_up() == ResolvedEnd((3.0,), 9.0, Ending.TERMINATED)
    assert matcher.give_up() is None
    # An abort during a move: the environment judged one action less than the agent took.
    assert matcher.terminal([4.0], 0.0, actions=6) is None
    assert matcher.report(5, Ending.TRUNCATED) is None
    assert matcher.report(5, Ending.ABORTED) == ResolvedEnd((4.0,), 0.0, Ending.ABORTED)
    # The environment's episode number comes with the pairing, in either order.
    matcher.new_episode()
    assert matcher.terminal([5.0], 1.0, actions=2) is None
    assert matcher.report(2, Ending.TERMINATED, episode=41).episode == 41
    matcher.new_episode()
    assert matcher.report(3, Ending.TRUNCATED, episode=42) is None
    assert matcher.terminal([6.0], 1.0, actions=3).episode == 42


def test_a_terminal_state_waits_for_its_report_as_long_as_the_environment_is_there():
    """No deadline: a late summary (a loaded machine) must not turn into a guess; only the
    environment leaving ends the wait, with a warning every warn_every meanwhile."""
    wait = SummaryWait(warn_every=5.0)
    assert wait.tick(100.0, environment_present=False) is None  # not waiting: nothing to say
    wait.start(100.0)
    assert [wait.tick(t, True) for t in (100.5, 104.9, 105.0, 107.0, 110.0)] == [
        None, None, 'warn', None, 'warn'
    ]  # fmt: skip
    assert wait.tick(3600.0, True) == 'warn' and wait.waited(3600.0) == 3500.0
    assert wait.tick(3600.5, environment_present=False) == 'give up'
    assert wait.tick(3601.0, False) is None and wait.waited(3601.0) == 0.0
    # The report came: stop() ends the wait, nothing more is said.
    wait.start(10.0)
    wait.stop()
    assert wait.tick(20.0, False) is None
    with pytest.raises(ValueError, match='warn_every must be > 0 s'):
        SummaryWait(0.0)


def test_sarsa_through_the_protocol_bootstraps_on_the_action_it_sends():
    agent = ProtocolAgent(
        Sarsa(2, LearnerConfig.constant(gamma=1.0, alpha=1.0, epsilon=0.0)),
        StateIndex(),
        np.random.default_rng(0),
    )
    agent.learner.ensure_rows(2)
    agent.index.row([0.0]), agent.index.row([1.0])
    agent.learner.q[1] = [3.0, 5.0]
    a0 = agent.handle([0.0], 0.0, False).action
    a1 = agent.handle([1.0], 1.0, False).action
    assert a1 == 1 and agent.learner.q[0, a0] == 1.0 + 5.0


def test_abort_drops_the_episode_without_learning():
    agent = make_agent()
    agent.handle([0.0], 0.0, False)
    agent.handle([1.0], -1.0, False)
    q = agent.learner.q.copy()
    aborted = agent.abort()
    assert aborted.aborted and aborted.actions == 2
    assert np.array_equal(agent.learner.q, q) and not agent.in_episode
    assert agent.abort() is None


def test_states_outside_the_ranges_come_with_a_note():
    mapping, _ = mapping_from_description([0.0], [5.0])
    agent = ProtocolAgent(QLearning(2), StateIndex(mapping), np.random.default_rng(0))
    assert agent.handle([9.0], 0.0, False).notes == (
        'state [9.0] lies outside the description state ranges',
    )
    assert agent.handle([1.0], 0.0, False).notes == ()


@pytest.mark.parametrize('count', [0, -1, 2.5, math.nan, math.inf])
def test_descriptions_with_an_unusable_action_count_are_rejected(count):
    with pytest.raises(BadInputError, match='environment description: action count'):
        parse_description(count, 0, [0.0], [1.0], 1.0, 2.0, False, True, 'x')


def test_a_description_parses():
    description = parse_description(4.0, 0, [0.0, 0.0], [10.0, 5.0], 1, 2, True, True, 'lg')
    assert description.num_actions == 4 and description.identity()['title'] == 'lg'


def test_a_prior_starts_each_new_state_and_never_touches_a_known_one():
    """A state seen for the first time starts at the prior's values (None: initial_value);
    a known state's row is never reset by it."""
    seen = []

    def prior(vector):
        seen.append(vector.tolist())
        return None if vector[0] < 0 else np.array([vector[0], 10.0 * vector[0]])

    learner = make_learner('qlearning', 2, LearnerConfig.constant(alpha=1.0, initial_value=-7.0))
    agent = ProtocolAgent(learner, StateIndex(), np.random.default_rng(0), prior=prior)
    agent.first_action([1.0])
    np.testing.assert_array_equal(learner.values(0), [1.0, 10.0])
    agent.next_action(-1.0, [-2.0])  # no prior for this state: the initial value
    np.testing.assert_array_equal(learner.values(1), [-7.0, -7.0])
    learned = learner.values(0)
    agent.next_action(-1.0, [1.0])  # known: learned values stay
    np.testing.assert_array_equal(learner.values(0), learned)
    assert seen == [[1.0], [-2.0]]


def test_an_initial_row_of_the_wrong_shape_or_not_finite_is_refused():
    learner = make_learner('qlearning', 3)
    for values in ([1.0, 2.0], [1.0, 2.0, math.nan], [[1.0, 2.0, 3.0]]):
        with pytest.raises(ValueError, match='initial row: expected 3 finite action values'):
            learner.set_initial_row(0, values)
    learner.set_initial_row(4, [1.0, 2.0, 3.0])
    assert learner.num_rows == 5
    np.testing.assert_array_equal(learner.values(4), [1.0, 2.0, 3.0])
