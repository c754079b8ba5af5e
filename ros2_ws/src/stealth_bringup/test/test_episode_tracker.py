"""Pairing the environment's and the agent's episode reports; the end criteria (no ROS)."""

import math

import pytest
from stealth_bringup.episode_scores import EpisodeScorer
from stealth_bringup.episode_tracker import OUTCOMES, Tracker, unfinished_fields
from stealth_core.path_scores import Criterion
from stealth_core.scenario import load_scenario


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
        'episode budget of 100 spent before 2 greedy evaluations in a row reached the goal '
        'undetected (streak at the end: 3)'
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


# --- the success criterion through ROS ---------------------------------------------------------


@pytest.fixture(scope='module')
def scorer():
    """map1's optimum (64 moves, 32 m, in the dark) and its actions on the lattice."""
    found = EpisodeScorer(load_scenario('map1'), None)
    model = found.model
    path = [int(model.start)]
    for point in found.optimum.points[1:]:
        here = path[-1]
        path.append(next(int(j) for j in model.successors[here]
                         if (model.points[j] == point).all() and j != here))  # fmt: skip
    actions = [model.direction(a, b) for a, b in zip(path, path[1:], strict=False)]
    return found, actions


def ros_summary(episode, actions, outcome='SUCCESS', path_length=None):
    return {
        **summary(episode, outcome, steps=len(actions), reward=1035.0),
        'path_length': 0.5 * len(actions) if path_length is None else path_length,
    }


def play(tracker, scorer_actions, episode, actions, outcome='SUCCESS', greedy=True, **kwargs):
    """An episode's StepInfo reports (the estimate 1 cm off each node), then its summary and
    the agent's report; the records completed."""
    scorer_, _ = scorer_actions
    model = scorer_.model
    place, done = model.start, []
    for action in actions:
        place = int(model.successors[place, action])
        x, y = model.points[place]
        done += tracker.add_step(episode, action, x + 0.01, y, 0.5)
    done += tracker.add_summary(ros_summary(episode, actions, outcome, **kwargs), 1.0)
    return done + tracker.add_agent_info(episode, agent(greedy), 2.0)


def test_an_episode_is_scored_on_the_lattice_nodes_it_was_sent_to(scorer):
    """The return through ROS (1035 here) is not the optimum's: the lattice replay of the
    actions is, with the true and the estimated path lengths beside it."""
    found, actions = scorer
    tracker = Tracker(budget=10, scorer=found)
    (record,) = play(tracker, scorer, 0, actions, path_length=33.0)
    assert (record.lattice_outcome, record.lattice_steps) == ('SUCCESS', 64)
    assert record.lattice_path_length == pytest.approx(32.0)
    assert record.path_over_optimum == pytest.approx(1.0)
    assert record.exposure_over_optimum == pytest.approx(0.0)
    assert record.true_path_over_optimum == pytest.approx(33.0 / 32.0)
    assert record.estimated_path_length == pytest.approx(32.0, abs=0.05)
    assert record.meets_criterion and record.brief()['lattice']['path_over_optimum'] == 1.0


def test_a_detour_or_a_detection_does_not_meet_the_criterion(scorer):
    found, actions = scorer
    tracker = Tracker(budget=10, scorer=found)
    # Out and back along the first move's direction, 4 steps each way, then the optimum.
    back = {0: 1, 1: 0, 2: 3, 3: 2}[actions[0]]
    detour = [actions[0]] * 4 + [back] * 4 + actions
    (long,) = play(tracker, scorer, 0, detour)
    assert long.outcome == 'SUCCESS' and long.path_over_optimum > 1.1
    assert not long.meets_criterion
    (seen,) = play(tracker, scorer, 1, actions, outcome='DETECTED')
    assert seen.path_over_optimum == pytest.approx(1.0) and not seen.meets_criterion
    # Sent through a lit node on the lattice, though the true pose got away with it.
    model = found.model
    place, lit = model.start, None
    for k, action in enumerate(actions):
        for other in range(4):
            if model.step_seen[place, other]:
                lit = [*actions[:k], other]
                break
        if lit:
            break
        place = int(model.successors[place, action])
    (lucky,) = play(tracker, scorer, 2, lit, outcome='SUCCESS')
    assert lucky.lattice_outcome == 'DETECTED' and not lucky.meets_criterion


def test_the_streak_counts_greedy_episodes_that_meet_the_criterion(scorer):
    found, actions = scorer
    tracker = Tracker(budget=100, streak_goal=2, scorer=found)
    back = {0: 1, 1: 0, 2: 3, 3: 2}[actions[0]]
    play(tracker, scorer, 0, actions)
    play(tracker, scorer, 1, [actions[0]] * 4 + [back] * 4 + actions)  # reached, too long
    assert tracker.streak == 0
    play(tracker, scorer, 2, actions)
    play(tracker, scorer, 3, actions, greedy=False)  # training: does not count
    play(tracker, scorer, 4, actions)
    assert tracker.stop_reason() == 'streak' and tracker.streak_start == 2
    assert tracker.end_message('streak') == (
        'the greedy policy met the success criterion (path <= 1.1x, exposure <= opt + 0.1) in '
        '2 evaluations in a row (episodes 2, 4)'
    )
    loose = Tracker(budget=100, streak_goal=2, scorer=EpisodeScorer(
        found.scenario, None, Criterion(max_path_ratio=1.5)))  # fmt: skip
    loose.scorer._model, loose.scorer._optimum = found.model, found.optimum
    play(loose, scorer, 0, [actions[0]] * 4 + [back] * 4 + actions)
    assert loose.streak == 1
    assert tracker.end_message('budget', evaluating=True) == (
        '100 greedy episodes: 5 reached the goal, 3 met the success criterion (path <= 1.1x, '
        'exposure <= opt + 0.1)'
    )


def test_a_scenario_without_an_optimum_leaves_the_episodes_unscored(scorer):
    found, actions = scorer
    broken = EpisodeScorer(found.scenario, 'no-such-goal')
    tracker = Tracker(budget=10, scorer=broken)
    (record,) = play(tracker, scorer, 0, actions)
    assert record.outcome == 'SUCCESS' and record.lattice_steps == -1
    assert not record.meets_criterion and "goal 'no-such-goal'" in broken.error


def test_an_episode_waits_for_its_last_step(scorer):
    """The summary may come before the last StepInfo (two topics): the record waits for it,
    or for a later episode's first step when it never comes."""
    found, actions = scorer
    tracker = Tracker(budget=10, scorer=found)
    assert tracker.add_summary(ros_summary(0, actions), 1.0) == []
    assert tracker.add_agent_info(0, agent(True), 1.0) == []
    model, place = found.model, found.model.start
    for k, action in enumerate(actions):
        place = int(model.successors[place, action])
        done = tracker.add_step(0, action, *model.points[place], 1.5)
        assert done == [] if k < len(actions) - 1 else done[0].meets_criterion
    tracker.add_summary(ros_summary(1, actions), 2.0)
    assert tracker.add_agent_info(1, agent(True), 2.0) == []  # no step of it yet
    (record,) = tracker.add_step(2, actions[0], 0.0, 0.0, 3.0)
    assert record.episode == 1 and record.lattice_steps == -1 and not record.meets_criterion
