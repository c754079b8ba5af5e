"""System tests of stealth_agent's agent_node: a real process driven over DDS by a fake
rl_msgs environment (a corridor MDP) living in the test process."""

import math
import os
import signal
import time

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from ros_support import REPO_ROOT, SpinningNode
from stealth_interfaces.msg import (
    AgentEpisodeInfo,
    EpisodeSummary,
    RLAction,
    RLEnvDescription,
    RLExperimentInfo,
    RLStateReward,
)

AGENT = REPO_ROOT / 'ros2_ws/install/stealth_agent/lib/stealth_agent/agent_node'
RL_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE
)
REPORT_QOS = QoSProfile(  # as stealth_env offers its EpisodeSummary
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
DESCRIPTION_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
TITLE = 'test corridor'
GOAL = 5  # corridor cells 0..5, start 0, goal 5: optimal episode 5 actions, return 4*-1 + 10
FIRST_REWARD = 1000.0  # sent with every episode's first state; the agent must ignore it


class FakeCorridorEnv(SpinningNode):
    """A tiny rl_msgs environment: action 0 left, 1 right, -1 per step, +10 at the goal."""

    def __init__(self, context, max_steps=25):
        super().__init__('fake_corridor_env', context)
        self.max_steps = max_steps
        self.description_pub = self.node.create_publisher(
            RLEnvDescription, 'rl_env/rl_env_description', DESCRIPTION_QOS
        )
        self.state_pub = self.node.create_publisher(
            RLStateReward, 'rl_env/rl_state_reward', RL_QOS
        )
        self.summary_pub = None  # set by report_outcomes(): then every episode's end is told
        self.actions: list[int] = []
        self.infos: list[RLExperimentInfo] = []
        self.action_sub = self.node.create_subscription(
            RLAction, 'rl_agent/rl_action', lambda m: self.actions.append(m.action), RL_QOS
        )
        self.info_sub = self.node.create_subscription(
            RLExperimentInfo, 'rl_agent/rl_experiment_info', self.infos.append, RL_QOS
        )

    def describe(self, num_actions=2.0, title=TITLE):
        self.description_pub.publish(
            RLEnvDescription(
                num_actions=float(num_actions),
                num_states=float(GOAL + 1),
                min_state_range=[0.0],
                max_state_range=[float(GOAL)],
                max_reward=10.0,
                reward_range=11.0,
                stochastic=False,
                episodic=True,
                title=title,
            )
        )

    def wait_for_agent(self, timeout=20.0):
        assert self.spin_until(
            lambda: (
                self.state_pub.get_subscription_count() >= 1
                and self.action_sub.get_publisher_count() >= 1
                and self.info_sub.get_publisher_count() >= 1
            ),
            timeout,
        ), 'the agent never connected'

    def wait_for_no_agent(self, timeout=10.0):
        assert self.spin_until(lambda: self.state_pub.get_subscription_count() == 0, timeout)

    def report_outcomes(self):
        """Publish EpisodeSummary at every episode end, as stealth_env's environment does."""
        self.summary_pub = self.node.create_publisher(
            EpisodeSummary, 'rl_env/episode_summary', REPORT_QOS
        )
        assert self.spin_until(lambda: self.summary_pub.get_subscription_count() >= 1, 10.0)

    def summarise(self, episode, outcome, steps):
        self.summary_pub.publish(EpisodeSummary(episode=episode, outcome=outcome, steps=steps))

    def send(self, state, reward, terminal=False):
        self.state_pub.publish(
            RLStateReward(state=[float(v) for v in state], reward=float(reward), terminal=terminal)
        )

    def answer(self, timeout=5.0) -> int | None:
        """The agent's next action, or None when none comes."""
        count = len(self.actions)
        if not self.spin_until(lambda: len(self.actions) > count, timeout):
            return None
        return self.actions[count]

    def experiment_info(self, timeout=5.0) -> RLExperimentInfo | None:
        count = len(self.infos)
        if not self.spin_until(lambda: len(self.infos) > count, timeout):
            return None
        return self.infos[count]

    def episode(self):
        """One episode; returns (sum of rewards after the first state, actions, info)."""
        position, total, steps = 0, 0.0, 0
        count = len(self.infos)
        self.send([position], FIRST_REWARD)
        while True:
            action = self.answer()
            assert action in (0, 1), f'bad or missing action {action!r} at step {steps}'
            steps += 1
            position = max(0, position - 1) if action == 0 else position + 1
            reward = 10.0 if position == GOAL else -1.0
            total += reward
            terminal = position == GOAL or steps == self.max_steps
            self.send([position], reward, terminal)
            if terminal and self.summary_pub is not None:
                outcome = EpisodeSummary.SUCCESS if position == GOAL else EpisodeSummary.TIMEOUT
                self.summarise(len(self.infos), outcome, steps)
            if terminal:
                assert self.spin_until(lambda: len(self.infos) > count, 5.0), 'no episode info'
                return total, steps, self.infos[count]


@pytest.fixture
def env(node_processes, ros_context):
    """The fake environment; set up after (so torn down before) node_processes, whose
    teardown checks that no DDS shared memory is left behind."""
    fake = FakeCorridorEnv(ros_context)
    yield fake
    fake.close()


def start_agent(node_processes, name, **params):
    assert AGENT.exists(), f'{AGENT} is missing: colcon build --packages-select stealth_agent'
    args = [str(AGENT), '--ros-args', '--log-level', 'agent:=info']
    for key, value in params.items():
        args += ['-p', f'{key}:={str(value).lower() if isinstance(value, bool) else value}']
    extra_env = {'RCUTILS_LOGGING_BUFFERED_STREAM': '0'}
    return node_processes.start(args, name, extra_env=extra_env)


def wait_for_log(process, text, timeout=20.0, count=1) -> str:
    """The process's log once `text` appears in it `count` times."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        log = process.log_path.read_text()
        if log.count(text) >= count:
            return log
        if process.poll() is not None:
            break
        time.sleep(0.05)
    log = process.log_path.read_text()
    assert log.count(text) >= count, f'{text!r} not {count} times in the agent log:\n{log}'
    return log


def stop(process):
    os.killpg(process.pid, signal.SIGINT)
    assert process.wait(15) == 0, process.log_path.read_text()


def test_agent_learns_reports_episodes_and_saves_a_reloadable_policy(
    env, node_processes, tmp_path
):
    from stealth_agent.policy_store import load_policy

    policy_file = tmp_path / 'corridor_policy.npz'
    env.describe()
    agent = start_agent(
        node_processes,
        'agent_learn',
        agent='qlearning',
        seed=3,
        policy_file=policy_file,
        save_every=10,
        log_every=10,
    )
    wait_for_log(agent, f"environment '{TITLE}'")
    env.wait_for_agent()

    episodes = [env.episode() for _ in range(40)]
    for number, (total, steps, info) in enumerate(episodes):
        assert info.episode_number == number
        assert info.number_actions == steps
        assert info.episode_reward == pytest.approx(total)  # the first reward is not in it
    steps = np.array([s for _, s, _ in episodes])
    print(f'\ncorridor steps per episode: {steps.tolist()}')
    assert steps[-10:].mean() <= 6.5 < steps[:10].mean()

    log = wait_for_log(agent, 'episodes 30-39 (learner total 40)')
    assert 'saved the policy' in log and policy_file.exists()
    stop(agent)
    assert 'shutdown; 40 episodes' in agent.log_path.read_text()
    policy = load_policy(policy_file)
    assert policy.learner.episodes == 40 and policy.scenario['title'] == TITLE
    saved = policy_file.read_bytes()

    # Evaluation mode (rl_agent's savedpolicy): greedy, no learning, the file untouched.
    env.wait_for_no_agent()
    evaluator = start_agent(
        node_processes, 'agent_evaluate', evaluate=True, policy_file=policy_file
    )
    wait_for_log(evaluator, f'from {policy_file} (40 episodes')
    env.wait_for_agent()
    for number in range(5):
        total, steps, info = env.episode()
        assert (steps, total, info.episode_number) == (GOAL, 4 * -1.0 + 10.0, number)
    stop(evaluator)
    assert policy_file.read_bytes() == saved
    # Its own totals: a first state and one per action in each episode, no action after the end.
    totals = f'totals: {5 * (GOAL + 1)} states received, {5 * GOAL} actions sent'
    assert totals in evaluator.log_path.read_text()

    # Resume learning from the file; named outcomes come from the optional EpisodeSummary.
    env.wait_for_no_agent()
    resumed = start_agent(
        node_processes,
        'agent_resume',
        load_policy=True,
        policy_file=policy_file,
        seed=3,
        log_every=5,
        save_every=0,
    )
    wait_for_log(resumed, f'from {policy_file} (40 episodes, 5 states), continuing its random')
    env.wait_for_agent()
    env.report_outcomes()
    # Episode numbers are the environment's, from its summaries (this one counts every episode
    # it ran, 45 so far).
    first = len(env.infos)
    for number in range(first, first + 5):
        total, steps, info = env.episode()
        assert info.episode_number == number and info.episode_reward == pytest.approx(total)
    wait_for_log(resumed, f'episodes {first}-{first + 4} (learner total 45)')
    stop(resumed)
    log = resumed.log_path.read_text()
    assert 'outcomes: success 5' in log, log
    assert load_policy(policy_file).learner.episodes == 45


def test_agent_learns_with_prioritized_sweeping_and_saves_its_queue(env, node_processes, tmp_path):
    from stealth_agent.policy_store import load_policy

    policy_file = tmp_path / 'sweeping_policy.npz'
    env.describe()
    agent = start_agent(
        node_processes,
        'agent_sweeping',
        agent='prioritized_sweeping',
        n=50,
        theta=0.001,
        seed=2,
        policy_file=policy_file,
        save_every=0,
    )
    log = wait_for_log(agent, f"environment '{TITLE}'")
    assert 'learner prioritized (' in log and 'n 50, theta 0.001, seed 2' in log, log
    env.wait_for_agent()
    steps = np.array([env.episode()[1] for _ in range(12)])
    print(f'\ncorridor steps per episode (prioritized sweeping): {steps.tolist()}')
    assert steps[-5:].mean() <= 6.5 < steps[0]
    stop(agent)
    policy = load_policy(policy_file)
    assert policy.learner.name == 'prioritized' and policy.learner.config.theta == 0.001
    assert policy.learner.model_size > 0


def test_agent_survives_bad_input(env, node_processes):
    agent = start_agent(node_processes, 'agent_bad_input', log_every=1)
    wait_for_log(agent, 'waiting for rl_env/rl_env_description')
    env.wait_for_agent()

    def rejected(state, reward, log_text, terminal=False):
        seen = agent.log_path.read_text().count(log_text)
        env.send(state, reward, terminal)
        assert env.answer(timeout=0.7) is None, f'the agent answered {state}, {reward}'
        wait_for_log(agent, log_text, timeout=5.0, count=seen + 1)
        assert agent.poll() is None

    rejected([0.0], 0.0, 'rl_state_reward received before any environment description')
    env.describe(num_actions=0)
    wait_for_log(agent, 'action count must be at least 1, got 0; description ignored')
    rejected([0.0], 0.0, 'rl_state_reward received before any environment description')

    env.describe()
    wait_for_log(agent, f"environment '{TITLE}'")
    # The latest state sent before the description was held, not dropped: it is answered now,
    # as the episode's first (a restarted agent may match the states' writer first).
    assert env.answer() is not None
    wait_for_log(agent, 'answering the state that came before the description')
    rejected([1.0], math.nan, 'rl_state_reward skipped: bad reward: nan is not finite')
    rejected([1.0], math.inf, 'rl_state_reward skipped: bad reward: inf is not finite')
    rejected([1.0, 0.0], -1.0, 'state has 2 features, expected 1 (the state vector length')
    rejected([math.nan], -1.0, 'state has non-finite values')
    rejected([5.0], -math.inf, 'bad reward: -inf is not finite', terminal=True)
    env.send([1.0], -1.0)
    assert env.answer() is not None
    env.send([5.0], 10.0, terminal=True)
    info = env.experiment_info()
    assert (info.episode_number, info.episode_reward, info.number_actions) == (0, 9.0, 2)
    wait_for_log(agent, 'episodes 0-0 (learner total 1)')

    # Parameters are checked at runtime too.
    client = AsyncParameterClient(env.node, 'agent')
    assert client.wait_for_services(timeout_sec=10.0)

    def set_parameter(name, value):
        future = client.set_parameters([Parameter(name, value=value)])
        assert env.spin_until(future.done, 10.0)
        return future.result().results[0]

    assert not set_parameter('epsilon', 1.5).successful
    assert 'read-only' in set_parameter('agent', 'sarsa').reason
    assert 'must be one of' in set_parameter('epsilon_schedule', 'cosine').reason
    assert 'must be > 0' in set_parameter('alpha_decay_episodes', 0.0).reason
    assert set_parameter('epsilon', 0.2).successful
    wait_for_log(agent, 'learner settings changed: epsilon=0.2')
    total, steps, info = env.episode()
    assert info.episode_number == 1 and info.episode_reward == pytest.approx(total)
    assert agent.poll() is None


def _mismatched_policy(path):
    from stealth_agent.learners import make_learner
    from stealth_agent.policy_store import save_policy
    from stealth_agent.state_index import StateIndex

    index = StateIndex()
    index.row([0.0])
    save_policy(path, make_learner('qlearning', 3), index, scenario={'title': TITLE})


@pytest.mark.parametrize(
    ('case', 'expected'),
    [
        ('corrupt', 'corrupt or not a policy archive'),
        ('mismatched', 'action count 3 in the file, 2 expected'),
        ('missing', 'no such file'),
    ],
)
def test_unusable_policy_files_are_refused_and_left_alone(
    env, node_processes, tmp_path, case, expected
):
    path = tmp_path / 'policy.npz'
    if case == 'corrupt':
        path.write_bytes(b'not a policy\n' * 50)
    elif case == 'mismatched':
        _mismatched_policy(path)
    before = path.read_bytes() if path.exists() else None
    env.describe()
    params = {'evaluate': True} if case == 'missing' else {'load_policy': True}
    agent = start_agent(node_processes, f'agent_{case}', policy_file=path, **params)
    log = wait_for_log(agent, expected)
    assert f'policy file {path}' in log
    env.wait_for_agent()
    env.send([0.0], 0.0)
    assert env.answer(timeout=0.7) is None
    wait_for_log(agent, 'rl_state_reward skipped: the agent is not usable')
    assert agent.poll() is None
    stop(agent)
    assert (path.read_bytes() if path.exists() else None) == before


def test_bad_startup_parameters_stop_the_node_with_a_reason(node_processes):
    agent = start_agent(node_processes, 'agent_bad_params', agent='texplore')
    assert agent.wait(20) == 2
    assert "unknown learner 'texplore'" in agent.log_path.read_text()


def test_eval_every_makes_every_mth_episode_greedy_and_reports_it(env, node_processes):
    """rl_agent/episode_info: greedy flag, epsilon, alpha, return, steps of every episode."""
    reports: list[AgentEpisodeInfo] = []
    env.node.create_subscription(AgentEpisodeInfo, 'rl_agent/episode_info', reports.append, RL_QOS)
    env.describe()
    agent = start_agent(
        node_processes, 'agent_eval_every', agent='dyna', seed=5, eval_every=3, epsilon=0.2
    )
    wait_for_log(agent, f"environment '{TITLE}'")
    env.wait_for_agent()
    episodes = [env.episode() for _ in range(6)]
    assert env.spin_until(lambda: len(reports) == 6, 10.0), reports
    assert [r.episode for r in reports] == list(range(6))
    assert [r.greedy for r in reports] == [False, False, True, False, False, True]
    for report, (total, steps, _) in zip(reports, episodes, strict=True):
        assert report.total_reward == pytest.approx(total) and report.steps == steps
        expected = (0.0, 0.0) if report.greedy else (0.2, 0.3)
        assert (report.epsilon, report.alpha) == pytest.approx(expected)
    # Greedy episodes neither learn nor count as learning episodes.
    assert [r.learner_episodes for r in reports] == [1, 2, 2, 3, 4, 4]
    assert reports[2].learner_updates == reports[1].learner_updates
    assert reports[3].learner_updates > reports[2].learner_updates
    assert all(r.table_states >= 2 for r in reports)
    log = wait_for_log(agent, 'greedy evaluation, episode 5 (after 4 learning episodes)')
    assert 'greedy evaluation, episode 2 (after 2 learning episodes)' in log


def test_a_late_summary_is_waited_for_while_the_environment_is_there(env, node_processes):
    """A summary later than summary_wait (a loaded machine) still decides how the episode is
    learned: the agent warns and keeps waiting. Only when the environment's summary publisher
    is gone does it learn the terminal state as terminal."""
    reports: list[AgentEpisodeInfo] = []
    env.node.create_subscription(AgentEpisodeInfo, 'rl_agent/episode_info', reports.append, RL_QOS)
    env.describe()
    agent = start_agent(node_processes, 'agent_late_summary', summary_wait=0.5, epsilon=0.0)
    wait_for_log(agent, f"environment '{TITLE}'")
    env.wait_for_agent()
    env.report_outcomes()
    env.send([0.0], FIRST_REWARD)
    assert env.answer() is not None
    env.send([1.0], -1.0, terminal=True)
    assert env.experiment_info(timeout=2.0) is None, 'the agent stopped waiting for the summary'
    log = wait_for_log(agent, 'still waiting for the EpisodeSummary of episode 0', count=2)
    assert 'learned as terminal' not in log
    env.summarise(0, EpisodeSummary.TIMEOUT, 1)
    assert env.experiment_info() is not None
    assert env.spin_until(lambda: reports, 5.0)
    assert reports[0].ending == AgentEpisodeInfo.END_TRUNCATED  # as the late summary said
    # The environment's summary publisher goes away while a terminal state waits.
    env.send([0.0], FIRST_REWARD)
    assert env.answer() is not None
    env.send([1.0], -1.0, terminal=True)
    wait_for_log(agent, 'still waiting for the EpisodeSummary of episode 1')
    env.node.destroy_publisher(env.summary_pub)
    assert env.experiment_info(timeout=10.0) is not None
    assert env.spin_until(lambda: len(reports) == 2, 5.0)
    assert reports[1].ending == AgentEpisodeInfo.END_TERMINAL
    wait_for_log(agent, 'without its EpisodeSummary; learned as terminal')


@pytest.mark.parametrize(
    ('timeout_is_terminal', 'expected_q'), [(False, -1.0 + 0.5 * 10.0), (True, -1.0)]
)
def test_a_timeout_is_learned_as_a_truncation_not_as_a_terminal_state(
    env, node_processes, tmp_path, timeout_is_terminal, expected_q
):
    """One-step episodes 0 -> 1 cut off by the step limit: with alpha 1, gamma 0.5 and every
    new value 10, a truncation learns Q(0, a) = -1 + 0.5 * 10, a terminal state -1 (rl_agent's
    biased way, kept behind timeout_is_terminal). An aborted episode teaches nothing."""
    from stealth_agent.policy_store import load_policy

    reports: list[AgentEpisodeInfo] = []
    env.node.create_subscription(AgentEpisodeInfo, 'rl_agent/episode_info', reports.append, RL_QOS)
    policy_file = tmp_path / 'timeout_policy.npz'
    env.describe()
    agent = start_agent(
        node_processes,
        f'agent_timeout_terminal_{timeout_is_terminal}',
        alpha=1.0,
        gamma=0.5,
        epsilon=0.0,
        initialvalue=10.0,
        seed=2,
        policy_file=policy_file,
        save_every=0,
        timeout_is_terminal=timeout_is_terminal,
    )
    wait_for_log(agent, f"environment '{TITLE}'")
    env.wait_for_agent()
    env.report_outcomes()
    taken = set()
    # The summary after the terminal state (the agent waits for it), then before it.
    for episode, summary_first in enumerate((False, True)):
        env.send([0.0], FIRST_REWARD)
        action = env.answer()
        taken.add(action)
        if summary_first:
            env.summarise(episode, EpisodeSummary.TIMEOUT, 1)
            env.spin_until(lambda: False, 0.2)
        env.send([1.0], -1.0, terminal=True)
        if not summary_first:
            env.spin_until(lambda: False, 0.2)
            assert len(env.infos) == episode, 'the agent did not wait for the summary'
            env.summarise(episode, EpisodeSummary.TIMEOUT, 1)
        assert env.experiment_info() is not None
    # An aborted episode: a terminal state with reward 0 that must not be learned.
    env.send([0.0], FIRST_REWARD)
    aborted_action = env.answer()
    env.send([0.0], 0.0, terminal=True)
    env.summarise(2, EpisodeSummary.ABORTED, 1)
    assert env.experiment_info().episode_number == 2
    assert env.spin_until(lambda: len(reports) == 3, 10.0)
    expected_end = (
        AgentEpisodeInfo.END_TERMINAL if timeout_is_terminal else AgentEpisodeInfo.END_TRUNCATED
    )
    ends = [expected_end, expected_end, AgentEpisodeInfo.END_ABORTED]
    assert [r.ending for r in reports] == ends
    assert [r.learner_episodes for r in reports] == [1, 2, 2]
    stop(agent)
    policy = load_policy(policy_file)
    row = policy.index.lookup([0.0])
    for action in taken:
        assert policy.learner.q[row, action] == pytest.approx(expected_q)
    if aborted_action not in taken:
        assert policy.learner.q[row, aborted_action] == 10.0


def test_restarts_of_either_side_keep_the_agent_in_step_with_the_environment(env, node_processes):
    """A restarted environment is told by its states' DDS sequence numbers starting again (its
    latched description may come after its first states, on a writer DDS matched later), and an
    episode the environment ends ABORTED before the agent saw its first state is closed, not
    learned."""
    reports: list[AgentEpisodeInfo] = []
    env.node.create_subscription(AgentEpisodeInfo, 'rl_agent/episode_info', reports.append, RL_QOS)
    env.describe()
    agent = start_agent(node_processes, 'agent_restarts', epsilon=0.0)
    wait_for_log(agent, f"environment '{TITLE}'")
    env.wait_for_agent()
    env.report_outcomes()
    env.send([0.0], FIRST_REWARD)
    assert env.answer() is not None
    env.send([1.0], -1.0)
    assert env.answer() is not None
    # The environment restarts mid-episode: a new writer of the states, numbering from 1.
    env.node.destroy_publisher(env.state_pub)
    env.state_pub = env.node.create_publisher(RLStateReward, 'rl_env/rl_state_reward', RL_QOS)
    env.wait_for_agent()
    env.send([0.0], FIRST_REWARD)
    assert env.answer() is not None
    wait_for_log(agent, 'a new environment is sending states (restarted); dropped the episode')
    # Its description comes late: the new environment's episode goes on.
    env.describe()
    wait_for_log(agent, "the new environment's first state ends the old episode")
    env.send([5.0], 10.0, terminal=True)
    env.summarise(1, EpisodeSummary.SUCCESS, 1)
    info = env.experiment_info()
    assert (info.episode_number, info.number_actions) == (1, 1)
    # An episode ended ABORTED before its first state reached the agent (its report first).
    env.summarise(2, EpisodeSummary.ABORTED, 0)
    env.send([0.0], 0.0, terminal=True)
    info = env.experiment_info()
    assert (info.episode_number, info.number_actions) == (2, 0)
    assert env.spin_until(lambda: len(reports) == 2, 5.0)
    assert [r.ending for r in reports] == [
        AgentEpisodeInfo.END_TERMINAL,
        AgentEpisodeInfo.END_ABORTED,
    ]
    assert reports[1].learner_episodes == reports[0].learner_episodes  # nothing learned
    env.send([0.0], FIRST_REWARD)  # and the next episode starts as usual
    assert env.answer() is not None
    stop(agent)
