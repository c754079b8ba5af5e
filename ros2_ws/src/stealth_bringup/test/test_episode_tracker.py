"""Pairing the environment's and the agent's episode reports; the end criteria (no ROS)."""

import math

from stealth_bringup.episode_tracker import OUTCOMES, Tracker, unfinished_fields


def summary(episode, outcome='SUCCESS', steps=10, reward=1.0):
    return {
        'episode': episode,
        'outcome': outcome,
        'steps': steps,
        'total_reward': reward,
        'peak_visibility': 0.1,
        'accumulated_visibility': 0.5,
        'path_length': 5.0,
        'final_distance_to_goal': 0.2,
    }


def agent(greedy=False, epsilon=0.1):
    return {
        'greedy': greedy,
        'epsilon': 0.0 if greedy else epsilon,
        'alpha': 0.0 if greedy else 0.3,
        'learner_episodes': 1,
        'learner_updates': 7,
        'table_states': 3,
    }


def feed(tracker, episode, outcome, greedy, summary_first=True):
    if summary_first:
        assert tracker.add_summary(summary(episode, outcome), 1.0) == []
        return tracker.add_agent_info(episode, agent(greedy), 2.0)
    assert tracker.add_agent_info(episode, agent(greedy), 1.0) == []
    return tracker.add_summary(summary(episode, outcome), 2.0)


def test_reports_are_paired_by_episode_in_either_order():
    tracker = Tracker()
    (first,) = feed(tracker, 0, 'DETECTED', False)
    (second,) = feed(tracker, 1, 'SUCCESS', True, summary_first=False)
    assert (first.episode, first.outcome, first.greedy) == (0, 'DETECTED', False)
    assert first.epsilon == 0.1
    assert (second.episode, second.greedy, second.epsilon, second.wall_time) == (1, True, 0.0, 2.0)
    assert tracker.episodes == 2
    # A report for an episode already complete changes nothing.
    assert tracker.add_summary(summary(1), 3.0) == [] and tracker.episodes == 2


def test_an_aborted_episode_completes_without_the_agent():
    tracker = Tracker()
    (record,) = tracker.add_summary(summary(0, 'ABORTED'), 1.0)
    assert record.outcome == 'ABORTED' and math.isnan(record.epsilon) and not record.greedy
    assert tracker.add_agent_info(0, agent(), 2.0) == []


def test_the_streak_counts_greedy_successes_in_a_row_only():
    tracker = Tracker(budget=100, streak_goal=3)
    feed(tracker, 0, 'SUCCESS', True)
    feed(tracker, 1, 'TIMEOUT', True)  # resets
    assert tracker.streak == 0 and tracker.stop_reason() is None
    for episode, greedy in ((2, True), (3, False), (4, True)):
        feed(tracker, episode, 'SUCCESS' if greedy else 'DETECTED', greedy)
    assert (tracker.streak, tracker.streak_start) == (2, 2)
    assert tracker.stop_reason() is None
    feed(tracker, 5, 'SUCCESS', True)
    assert tracker.stop_reason() == 'streak' and tracker.streak_start == 2
    assert tracker.last_greedy().episode == 5


def test_the_budget_counts_every_episode():
    tracker = Tracker(budget=3, streak_goal=None)
    for episode in range(2):
        feed(tracker, episode, 'DETECTED', episode == 1)
    assert tracker.stop_reason() is None
    feed(tracker, 2, 'SUCCESS', False)
    assert tracker.stop_reason() == 'budget'


def test_the_end_message_says_why_the_run_ended():
    tracker = Tracker(budget=100, streak_goal=2)
    for episode in range(3):
        feed(tracker, episode, 'SUCCESS', True)
    assert tracker.end_message('streak') == (
        'the greedy policy reached the goal undetected in 2 evaluations in a row (episodes 1, 2)'
    )
    assert tracker.end_message('budget') == (
        'episode budget of 100 spent before 2 greedy successes in a row (best streak at the end: '
        '3)'
    )
    assert Tracker(budget=5).end_message('budget') == 'episode budget of 5 spent'
    evaluation = tracker.end_message('budget', evaluating=True)
    assert evaluation == '100 greedy episodes: 3 reached the goal'


def test_progress_figures():
    tracker = Tracker(budget=10, streak_goal=2)
    assert tracker.postfix() == 'success 0%, return 0.0, eps -, greedy streak 0/2'
    feed(tracker, 0, 'SUCCESS', False)
    feed(tracker, 1, 'DETECTED', True)
    assert tracker.success_rate() == 0.5 and tracker.mean_return() == 1.0
    assert tracker.epsilon == 0.1  # of the latest training episode, not the greedy one
    assert tracker.postfix() == 'success 50%, return 1.0, eps 0.100, greedy streak 0/2'
    assert tracker.outcome_counts() == {'SUCCESS': 1, 'DETECTED': 1, 'TIMEOUT': 0, 'ABORTED': 0}
    assert set(tracker.outcome_counts()) == set(OUTCOMES)


def test_a_continued_run_goes_on_with_the_earlier_episodes_and_streak():
    earlier = Tracker()
    for episode, outcome, greedy in ((0, 'TIMEOUT', False), (1, 'SUCCESS', True),
                                     (2, 'SUCCESS', False), (3, 'SUCCESS', True)):  # fmt: skip
        feed(earlier, episode, outcome, greedy)
    tracker = Tracker(budget=10, streak_goal=3)
    tracker.load(reversed(earlier.records))
    assert tracker.episodes == 4
    assert (tracker.streak, tracker.streak_start, tracker.greedy_count) == (2, 1, 2)
    assert tracker.stop_reason() is None
    feed(tracker, 4, 'SUCCESS', True)
    assert tracker.stop_reason() == 'streak' and tracker.streak_start == 1
    assert feed(tracker, 3, 'SUCCESS', True) == []  # an episode counted before is not again


def test_an_episode_whose_environment_died_is_rebuilt_from_its_steps():
    steps = [(-1.0, 0.1, 4.0, 1.5, 2.0), (-1.0, 0.3, 3.5, 2.0, 2.0), (-2.0, 0.2, 3.0, 2.0, 2.5)]
    fields = unfinished_fields(12, steps, (1.5, 1.5))
    assert fields == {
        'episode': 12,
        'outcome': 'ABORTED',
        'steps': 3,
        'total_reward': -4.0,
        'peak_visibility': 0.3,
        'accumulated_visibility': fields['accumulated_visibility'],
        'path_length': 1.5,
        'final_distance_to_goal': 3.0,
    }
    assert math.isclose(fields['accumulated_visibility'], 0.6)
    tracker = Tracker(budget=20)
    (record,) = tracker.add_summary(fields, 5.0)  # complete without the agent's report
    assert record.outcome == 'ABORTED' and math.isnan(record.epsilon)
    assert unfinished_fields(3, [], (0.0, 0.0))['path_length'] == 0.0
