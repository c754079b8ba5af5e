"""What the agent does with each message (AgentLoop), driven by a fake node: no ROS."""

import errno

import pytest
from stealth_agent import policy_store
from stealth_agent.agent_loop import AgentLoop
from stealth_agent.agent_parameters import PARAMETERS
from stealth_agent.policy_store import load_policy
from stealth_interfaces.msg import (
    AgentEpisodeInfo,
    EpisodeSummary,
    RLEnvDescription,
    RLStateReward,
)
from stealth_node_kit.full_disk import DiskFullError

DEFAULTS = {name: param.default for name, param in PARAMETERS.items()}
DESCRIPTION = RLEnvDescription(
    num_actions=2, min_state_range=[0.0], max_state_range=[9.0], title='corridor'
)


class FakeNode:
    """The loop's Ports, recording what the loop does."""

    def __init__(self, **params):
        self.params = {**DEFAULTS, **params}
        self.logs: list[tuple[str, str]] = []
        self.actions: list[int] = []
        self.reports: list[tuple] = []
        self.summary_publisher = False
        self.timer_running = False
        self.accepting_states = False
        self.shown: list[int] = []  # the learner's episodes each time it was shown

    def param(self, name):
        return self.params[name]

    def values(self):
        return dict(self.params)

    def get_logger(self):
        return self

    exit_logger = get_logger

    def info(self, text):
        self.logs.append(('info', text))

    def warning(self, text):
        self.logs.append(('warning', text))

    def error(self, text):
        self.logs.append(('error', text))

    def debug(self, text):
        self.logs.append(('debug', text))

    def send_action(self, action):
        self.actions.append(action)

    def send_reports(self, info, episode):
        self.reports.append((info, episode))

    def environment_reports_endings(self):
        return self.summary_publisher

    def start_summary_timer(self):
        self.timer_running = True

    def stop_summary_timer(self):
        self.timer_running = False

    def accept_states(self):
        self.accepting_states = True

    def show_learner(self, learner):
        self.shown.append(learner.episodes)

    def told(self, level, part):
        return [text for lvl, text in self.logs if lvl == level and part in text]


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def state(x, reward=-1.0, terminal=False):
    return RLStateReward(state=[x], reward=reward, terminal=terminal)


def summary(episode, outcome, steps):
    return EpisodeSummary(episode=episode, outcome=outcome, steps=steps)


def started(clock=None, **params):
    node = FakeNode(**params)
    loop = AgentLoop(node, clock=clock or Clock())
    loop.on_description(DESCRIPTION)
    return node, loop


def run_episode(loop, steps=3, reward=10.0, sequence=None):
    """steps actions, then a terminal state."""
    for x in range(steps):
        loop.on_state(state(float(x)), sequence)
    loop.on_state(state(float(steps), reward, terminal=True), sequence)


def test_a_state_before_the_description_is_held_and_answered_after_it():
    node = FakeNode()
    loop = AgentLoop(node, clock=Clock())
    loop.on_state(state(0.0), None)
    assert node.actions == [] and node.told('warning', 'held until the description arrives')
    loop.on_description(DESCRIPTION)
    assert len(node.actions) == 1 and node.told('info', 'answering the state that came before')
    assert node.told('info', "environment 'corridor': 2 actions")
    assert loop.states_received == 1 and loop.actions_sent == 1


def test_an_episode_is_reported_and_counted():
    node, loop = started(log_every=1)
    run_episode(loop, steps=3, reward=10.0)
    assert len(node.actions) == 3 and len(node.reports) == 1
    info, episode = node.reports[0]
    assert (info.episode_number, info.episode_reward, info.number_actions) == (0, 8.0, 3)
    assert episode.ending == AgentEpisodeInfo.END_TERMINAL
    assert episode.table_states == 3  # (the terminal state gets no row)
    assert node.told('info', 'episodes 0-0 (learner total 1)')
    assert (loop.states_received, loop.actions_sent) == (4, 3)


def test_a_timeout_summary_makes_the_terminal_state_a_truncation():
    node, loop = started()
    node.summary_publisher = True
    run_episode(loop, steps=2)
    assert node.reports == [] and node.timer_running  # the terminal state waits
    loop.on_summary(summary(0, EpisodeSummary.TIMEOUT, 2))
    assert not node.timer_running
    assert node.reports[0][1].ending == AgentEpisodeInfo.END_TRUNCATED


def test_timeout_is_terminal_learns_a_timeout_as_terminal():
    node, loop = started(timeout_is_terminal=True)
    node.summary_publisher = True
    loop.on_state(state(0.0), None)
    loop.on_state(state(1.0), None)
    loop.on_summary(summary(0, EpisodeSummary.TIMEOUT, 2))  # it may come before the state
    loop.on_state(state(2.0, terminal=True), None)
    assert not node.timer_running
    assert node.reports[0][1].ending == AgentEpisodeInfo.END_TERMINAL


def test_summaries_from_before_the_first_episode_are_ignored():
    node, loop = started(first_episode=5)
    node.summary_publisher = True
    loop.on_summary(summary(4, EpisodeSummary.ABORTED, 2))
    run_episode(loop, steps=2)
    assert node.reports == [] and node.timer_running
    loop.on_summary(summary(5, EpisodeSummary.SUCCESS, 2))
    assert node.reports[0][0].episode_number == 5


def test_the_wait_warns_while_the_environment_is_there_and_gives_up_when_it_left():
    clock = Clock()
    node, loop = started(clock, summary_wait=5.0)
    node.summary_publisher = True
    run_episode(loop, steps=2)
    clock.now += 6.0
    loop.check_summary_wait()
    assert node.told('warning', 'still waiting for the EpisodeSummary of episode 0 (6 s')
    assert node.reports == []
    node.summary_publisher = False
    clock.now += 1.5
    loop.check_summary_wait()
    assert node.told('warning', 'the environment left 7.5 s after the terminal state')
    assert node.reports[0][1].ending == AgentEpisodeInfo.END_TERMINAL
    assert not node.timer_running


def test_a_restarted_environment_drops_the_episode_in_progress():
    node, loop = started()
    loop.on_state(state(0.0), 1)
    loop.on_state(state(1.0), 2)
    loop.on_state(state(0.0), 1)  # numbered from 1 again: a new writer
    assert node.told('warning', 'a new environment is sending states (restarted); dropped the')
    assert len(node.actions) == 3 and loop.core.in_episode and loop.core.number_actions == 1
    # Its description, latched, may come after its states: the episode is kept.
    loop.on_description(DESCRIPTION)
    assert node.told('warning', "the new environment's first state ends the old episode")
    assert loop.core.in_episode


def test_without_sequence_numbers_the_description_again_drops_the_episode():
    node, loop = started()
    loop.on_state(state(0.0), None)
    loop.on_description(DESCRIPTION)
    assert node.told('warning', 'keeping the table; dropped the episode in progress (1 actions)')
    assert not loop.core.in_episode


def test_another_environment_is_refused():
    node, loop = started()
    other = RLEnvDescription(num_actions=4, min_state_range=[0.0], max_state_range=[1.0])
    loop.on_description(other)
    assert node.told('error', "a different environment description arrived ('', 4 actions")
    assert loop.description.title == 'corridor'


def test_bad_input_is_skipped_and_changes_nothing():
    node, loop = started()
    loop.on_description(RLEnvDescription(num_actions=0))
    assert node.told('error', 'description ignored, waiting for a usable one')
    loop.on_state(state(0.0), None)
    loop.on_state(RLStateReward(state=[1.0, 2.0], reward=-1.0), None)
    assert node.told('error', 'rl_state_reward skipped: bad state')
    assert len(node.actions) == 1 and loop.core.number_actions == 1


def test_every_eval_every_th_episode_is_greedy_and_logged():
    node, loop = started(eval_every=2)
    run_episode(loop)
    run_episode(loop)
    assert [episode.greedy for _, episode in node.reports] == [False, True]
    assert node.told('info', 'greedy evaluation, episode 1 (after 1 learning episodes)')


def test_an_unusable_policy_file_leaves_the_agent_idle(tmp_path):
    missing = tmp_path / 'missing.npz'
    node, loop = started(evaluate=True, policy_file=str(missing))
    assert loop.core is None and node.told('error', 'the agent will not act')
    loop.on_state(state(0.0), None)
    assert node.actions == [] and node.told('error', 'the agent is not usable (policy file')


def test_the_saved_policy_names_its_scenario_by_content_when_the_run_gives_it(tmp_path):
    path = tmp_path / 'p.npz'
    _, loop = started(policy_file=str(path), grid_sha256='ab' * 32, lights_sha256='cd' * 32)
    run_episode(loop)
    assert loop.save('shutdown')
    saved = load_policy(path).scenario
    assert saved['grid_sha256'] == 'ab' * 32 and saved['lights_sha256'] == 'cd' * 32
    assert saved['title'] == loop.description.title
    _, plain = started(policy_file=str(path))  # a run that does not know them saves none
    run_episode(plain)
    assert plain.save('shutdown')
    assert 'grid_sha256' not in load_policy(path).scenario


def test_the_policy_is_saved_every_save_every_and_at_the_end(tmp_path):
    path = tmp_path / 'p.npz'
    node, loop = started(save_every=2, policy_file=str(path))
    run_episode(loop)
    assert not path.exists()
    run_episode(loop)
    assert load_policy(path).meta['extra']['reason'] == 'every 2 episodes'
    assert loop.save('shutdown') and load_policy(path).learner.episodes == 2
    assert node.told('info', f'saved the policy to {path} (shutdown; 2 episodes')
    node.params['evaluate'] = True  # an evaluation never overwrites the file
    assert not loop.save('shutdown')


def test_a_full_disk_keeps_the_policy_saved_before_and_stops_the_agent(tmp_path, monkeypatch):
    path = tmp_path / 'p.npz'
    node, loop = started(save_every=1, policy_file=str(path))
    run_episode(loop)
    saved = path.read_bytes()

    def no_space(*args, **kwargs):
        raise OSError(errno.ENOSPC, 'No space left on device')

    monkeypatch.setattr(policy_store.np, 'savez', no_space)
    with pytest.raises(DiskFullError, match=r'^the disk is full: could not write .*p\.npz \('):
        run_episode(loop)  # its save: the node stops (EXIT_DISK_FULL), the run with it
    assert path.read_bytes() == saved and load_policy(path).learner.episodes == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ['p.npz']  # no temporary file left
    assert not loop.save('shutdown')  # no second try at exit


# A sensed-track environment: [x], then 299 sensed values (-1: never sensed).
SENSED = RLEnvDescription(
    num_actions=2,
    min_state_range=[0.0, *[-2.0] * 299],
    max_state_range=[9.0, *[3.0] * 299],
    title='corridor',
)


def sensed_state(x, sensed, reward=-1.0, terminal=False):
    return RLStateReward(state=[x, *[sensed] * 299], reward=reward, terminal=terminal)


def test_a_state_too_long_to_key_a_table_on_is_refused_in_one_line():
    node = FakeNode()
    loop = AgentLoop(node, clock=Clock())
    loop.on_description(SENSED)
    (line,) = node.told('error', 'the state has 300 features (the sensed track?)')
    assert 'set the agent parameter state_features' in line and '\n' not in line
    assert loop.core is None


def test_state_features_keys_the_table_on_the_leading_features():
    node = FakeNode(state_features=1)
    loop = AgentLoop(node, clock=Clock())
    loop.on_description(SENSED)
    assert node.told('info', "the table keys on the state's first 1 of 300 features")
    assert node.told('info', 'state ranges [0.0]..[9.0]')
    for step, sensed in enumerate((-1.0, 0.5, 0.7)):  # what was sensed changes, x does not
        loop.on_state(sensed_state(0.0, sensed), None)
        assert len(node.actions) == step + 1
    loop.on_state(sensed_state(1.0, 0.2, 10.0, terminal=True), None)
    assert len(loop.core.index) == 1 and not node.told('error', '')


def test_the_learners_notes_are_warned_once_each_then_cleared():
    node, loop = started()
    assert node.shown == [0]  # shown once set up
    learner = loop.core.learner
    learner.notes = ['step from (1.00, 2.00) direction 0: light 0.100, the best says 0.500']
    run_episode(loop)
    learner.notes.extend(['step from (1.00, 2.00) direction 0: light 0.100, the best says '
                          '0.500', 'another contradiction'])  # fmt: skip
    run_episode(loop)
    warned = node.told('warning', 'qlearning: ')
    assert warned == [
        'qlearning: step from (1.00, 2.00) direction 0: light 0.100, the best says 0.500',
        'qlearning: another contradiction',
    ]
    assert learner.notes == []
    assert node.shown == [0, 1, 2]  # after each learning episode


def test_a_greedy_evaluation_does_not_show_the_learner_again():
    node, loop = started(eval_every=2)
    run_episode(loop)
    run_episode(loop)  # episode 1: greedy
    assert node.shown == [0, 1]
