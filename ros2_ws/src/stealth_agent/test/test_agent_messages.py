"""The agent's messages: descriptions read, episode reports written, writers told apart."""

import math

import pytest
from stealth_agent.agent_messages import (
    FLOAT32_MAX,
    StateWriters,
    description_from_msg,
    ending_of,
    episode_info,
    experiment_info,
    outcome_ending,
    outcome_name,
)
from stealth_agent.learners import make_learner
from stealth_agent.protocol import BadInputError, Ending, EpisodeResult
from stealth_interfaces.msg import AgentEpisodeInfo, EpisodeSummary, RLEnvDescription


def test_a_description_message_becomes_a_checked_description():
    msg = RLEnvDescription(
        num_actions=5, min_state_range=[0.0, -1.0], max_state_range=[4.0, 1.0], title='lg'
    )
    description = description_from_msg(msg)
    assert description.num_actions == 5 and description.title == 'lg'
    assert description.min_state_range == (0.0, -1.0)
    assert description.max_state_range == (4.0, 1.0)
    with pytest.raises(BadInputError, match='environment description: action count'):
        description_from_msg(RLEnvDescription(num_actions=0))


def test_outcomes_are_named_and_learned_as_the_environment_says():
    assert outcome_name(EpisodeSummary.SUCCESS) == 'success'
    assert outcome_name(EpisodeSummary.DETECTED) == 'detected'
    assert outcome_name(77) == 'outcome 77'
    assert outcome_ending(EpisodeSummary.DETECTED) is Ending.TERMINATED
    assert outcome_ending(EpisodeSummary.TIMEOUT) is Ending.TRUNCATED
    assert outcome_ending(EpisodeSummary.ABORTED) is Ending.ABORTED
    assert outcome_ending(77) is Ending.TERMINATED  # unknown: as rl_msgs says, terminal


def test_episode_reports_carry_the_result_and_the_learner():
    learner = make_learner('qlearning', 2)
    result = EpisodeResult(3, 0, -2.5, 7, None, 0.1, truncated=True)
    info = experiment_info(result)
    assert (info.episode_number, info.episode_reward, info.number_actions) == (3, -2.5, 7)
    report = episode_info(result, learner, table_rows=11)
    assert report.episode == 3 and not report.greedy and report.steps == 7
    assert report.epsilon == pytest.approx(0.1) and report.alpha == pytest.approx(0.3)
    assert report.table_states == 11 and report.ending == AgentEpisodeInfo.END_TRUNCATED
    greedy = episode_info(EpisodeResult(4, 1, 1.0, 2, 1.0, 0.0, learning=False), learner, 11)
    assert greedy.greedy and greedy.alpha == 0.0 and greedy.ending == AgentEpisodeInfo.END_TERMINAL


def test_a_return_beyond_float32_is_clipped_in_both_reports():
    result = EpisodeResult(0, 0, -1e300, 1, -1e300, 0.1)
    assert experiment_info(result).episode_reward == -FLOAT32_MAX
    assert episode_info(result, make_learner('sarsa', 2), 1).total_reward == -FLOAT32_MAX
    assert math.isfinite(FLOAT32_MAX)


def test_endings_of_results():
    assert ending_of(EpisodeResult(0, 0, 0.0, 0, None, 0.0, aborted=True)) is Ending.ABORTED
    assert ending_of(EpisodeResult(0, 0, 0.0, 0, None, 0.0, truncated=True)) is Ending.TRUNCATED
    assert ending_of(EpisodeResult(0, 0, 0.0, 0, 1.0, 0.0)) is Ending.TERMINATED


def test_a_sequence_number_that_does_not_grow_is_a_new_writer():
    writers = StateWriters()
    assert not writers.new_writer(None) and writers.last is None  # no number: nothing to tell
    assert [writers.new_writer(n) for n in (1, 2, 3)] == [False, False, False]
    assert writers.new_writer(1)  # a restarted environment numbers from 1 again
    assert not writers.new_writer(2) and writers.last == 2
    assert not writers.new_writer(None) and writers.last == 2
