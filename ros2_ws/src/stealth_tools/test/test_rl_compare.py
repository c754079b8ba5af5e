"""rl_compare: two recordings' RL episodes message for message (plain pytest, sample bags)."""

import math

import numpy as np
import pytest
from sample_bags import START_NS, Sample, write_bag
from stealth_tools.bag_format import BagError
from stealth_tools.rl_compare import (
    ACTION,
    EPISODE_INFO,
    EXPERIMENT_INFO,
    STATE,
    STEP_INFO,
    SUMMARY,
    complete_episodes,
    first_difference,
    locate,
    plain,
    read_rl_topics,
)


def episode_messages(lengths, rewards=None, stamp_sec=0, tail=0):
    """{topic: [fields]} of episodes of the given numbers of actions, as the loop sends them;
    `tail` actions of one more episode the run stopped in."""
    topics = {topic: [] for topic in (STATE, ACTION, STEP_INFO, SUMMARY, EXPERIMENT_INFO)}
    topics[EPISODE_INFO] = []
    header = {'stamp': {'sec': stamp_sec, 'nanosec': 7}, 'frame_id': 'map'}
    for episode, length in enumerate([*lengths, tail]):
        topics[STATE].append({'state': [0.0, 0.0], 'reward': 0.0, 'terminal': False})
        finished = episode < len(lengths)
        for step in range(1, length + 1):
            reward = rewards[episode][step - 1] if rewards else -0.5
            terminal = finished and step == length
            topics[ACTION].append({'action': step % 4})
            topics[STATE].append({'state': [0.5 * step, 0.0], 'reward': reward,
                                  'terminal': terminal})  # fmt: skip
            topics[STEP_INFO].append({'header': header, 'episode': episode, 'step': step,
                                      'action': step % 4, 'reward': reward})  # fmt: skip
        if finished:
            topics[SUMMARY].append({'header': header, 'episode': episode, 'steps': length,
                                    'outcome': 2})  # fmt: skip
            topics[EXPERIMENT_INFO].append({'episode_number': episode, 'number_actions': length})
            topics[EPISODE_INFO].append({'header': header, 'episode': episode, 'steps': length})
    return topics


def test_the_same_episodes_compare_equal_whatever_the_stamps_and_the_unfinished_tail():
    first = episode_messages([3, 2, 4], stamp_sec=1)
    second = episode_messages([3, 2, 4], stamp_sec=99, tail=2)
    assert complete_episodes(first) == complete_episodes(second) == 3
    assert first_difference(first, second, 3) is None
    assert first_difference(first, second, 2) is None


def test_the_first_differing_message_is_named_with_its_episode_step_and_field():
    rewards = [[-0.5] * 3, [-0.5, -0.25], [-0.5] * 4]
    changed = [[-0.5] * 3, [-0.5, -0.125], [-0.5] * 4]
    first = episode_messages([3, 2, 4], rewards)
    second = episode_messages([3, 2, 4], changed)
    problem = first_difference(first, second, 3)
    assert problem == (
        'rl_env/rl_state_reward, message 6 (episode 1, step 2): reward is -0.25 in the first '
        'recording, -0.125 in the second (1 other topic differs too)'
    )
    # Only up to the episode before, they are the same.
    assert first_difference(first, second, 1) is None


def test_an_action_answered_differently_is_found_in_the_actions():
    first = episode_messages([3, 2])
    second = episode_messages([3, 2])
    second[ACTION][4] = {'action': 3}  # episode 1, its second action
    problem = first_difference(first, second, 2)
    assert problem.startswith('rl_agent/rl_action, message 4 (episode 1, step 2): action is 2 ')


def test_episodes_of_different_lengths_are_a_difference_not_a_crash():
    problem = first_difference(episode_messages([3, 2]), episode_messages([3, 4]), 2)
    assert problem.startswith('rl_env/rl_state_reward, message 6 (episode 1, step 2): terminal')


def test_a_recording_with_too_few_complete_episodes_is_said_so():
    problem = first_difference(episode_messages([3, 2]), episode_messages([3], tail=2), 2)
    assert problem == ('the second recording holds 1 complete episodes, fewer than the 2 compared')


def test_locate_places_every_message_in_its_episode_and_step():
    located = locate(episode_messages([2, 1], tail=1))
    assert [(m.episode, m.step) for m in located[STATE]] == [
        (0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (2, 0), (2, 1)
    ]  # fmt: skip
    assert [(m.episode, m.step) for m in located[ACTION]] == [(0, 1), (0, 2), (1, 1), (2, 1)]
    assert [(m.episode, m.step) for m in locate(episode_messages([2, 1]), 1)[SUMMARY]] == [(0, 2)]


def test_plain_drops_header_stamps_and_makes_nan_comparable():
    class Header:
        __slots__ = ('stamp', 'frame_id')

        def __init__(self, sec):
            self.stamp, self.frame_id = {'sec': sec}, 'map'

    class Message:
        __slots__ = ('header', 'values')

        def __init__(self, sec, values):
            self.header, self.values = Header(sec), values

    assert plain(Message(1, [1.0, math.nan])) == plain(Message(2, [1.0, math.nan]))
    assert plain(np.array([0.5, np.nan], dtype=np.float32)) == [0.5, 'nan']
    assert plain(np.array([3], dtype=np.uint8)) == [3] and plain(True) is True
    assert plain(Message(1, [1.0, math.nan])) == {
        'header': {'frame_id': 'map'},
        'values': [1.0, 'nan'],
    }


def rl_samples(topics):
    types = {
        STATE: 'stealth_interfaces/msg/RLStateReward',
        ACTION: 'stealth_interfaces/msg/RLAction',
        STEP_INFO: 'stealth_interfaces/msg/StepInfo',
        SUMMARY: 'stealth_interfaces/msg/EpisodeSummary',
        EXPERIMENT_INFO: 'stealth_interfaces/msg/RLExperimentInfo',
        EPISODE_INFO: 'stealth_interfaces/msg/AgentEpisodeInfo',
    }
    samples, time = [], START_NS
    for topic, messages in topics.items():
        for fields in messages:
            time += 1000
            samples.append(Sample(topic, types[topic], fields, time))
    return samples


def test_recordings_are_read_back_and_compared(tmp_path):
    first, second = tmp_path / 'first.mcap', tmp_path / 'second.mcap'
    write_bag(first, rl_samples(episode_messages([3, 2], stamp_sec=1)))
    changed = episode_messages([3, 2], stamp_sec=5, tail=1)
    changed[STEP_INFO][1]['reward'] = -0.75
    write_bag(second, rl_samples(changed))
    a, b = read_rl_topics(first), read_rl_topics(second)
    assert [len(a[t]) for t in (STATE, ACTION, SUMMARY)] == [8, 5, 2]  # 3 + 4 + a first
    assert first_difference(a, b, 1) == (
        'rl_env/step_info, message 1 (episode 0, step 2): reward is -0.5 in the first '
        'recording, -0.75 in the second'
    )


def test_a_recording_that_cannot_be_read_is_one_line(tmp_path):
    path = tmp_path / 'cut.mcap'
    write_bag(path, rl_samples(episode_messages([3, 2])))
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])  # cut off mid-file
    with pytest.raises(BagError, match=r'cut.mcap: cannot be read as an MCAP recording \(') as e:
        read_rl_topics(path)
    assert str(e.value).endswith(f'`stealth bag recover {path}` writes a complete copy')


def test_stealth_bag_compare_names_the_first_difference_or_says_they_are_the_same(
    capsys, tmp_path
):
    from test_cli_offline import run_cli

    same, other = tmp_path / 'same.mcap', tmp_path / 'other.mcap'
    write_bag(tmp_path / 'run.mcap', rl_samples(episode_messages([3, 2], stamp_sec=1)))
    write_bag(same, rl_samples(episode_messages([3, 2], stamp_sec=2, tail=1)))
    write_bag(other, rl_samples(episode_messages([3, 1])))
    run = str(tmp_path / 'run.mcap')
    assert run_cli(capsys, 'bag', 'compare', run, str(same)) == (
        0, 'the first 2 episodes are the same, message for message\n', ''
    )  # fmt: skip
    status, out, _ = run_cli(capsys, 'bag', 'compare', run, str(other), '--episodes', '1')
    assert (status, out) == (0, 'the first 1 episodes are the same, message for message\n')
    status, out, _ = run_cli(capsys, 'bag', 'compare', run, str(other))
    assert status == 1
    assert out.startswith('rl_env/rl_state_reward, message 5 (episode 1, step 1): terminal is')
    status, out, err = run_cli(capsys, 'bag', 'compare', run, str(tmp_path / 'nope.mcap'))
    assert (status, out) == (1, '')
    assert err == f'stealth bag compare: {tmp_path}/nope.mcap: no such file or directory\n'
