"""The lights-known generalist through ROS, as a user runs it: `stealth rollout --learner
generalist` on a shipped scenario it was never trained on (it was trained on generated
buildings only) starts simulator, environment (observation_layout grid), agent (agent:
generalist, the stealth_learn plugin) and recorder, and every episode reaches the goal
undetected; the grid observation is recorded once, with the run. On the sensed track the
belief grid goes out whenever what was sensed changes, and the robot crosses undetected too. With
moving lights and the time-aware weights, the phased grid goes out once and the robot crosses
with the benchmark's agent's actions, waits included; on the sensed track the phased grid of what
was sensed goes out before every state, and the robot crosses with the benchmark's agent's
actions on the sensed Gym env. Needs the learning extra (make learn; make test-system installs
it)."""

import json

import numpy as np
import pytest
import yaml

try:
    import jax  # noqa: F401
except ImportError:
    pytest.skip('the generalist needs jax: make learn', allow_module_level=True)

from stealth_learn.policy_file import SHIPPED  # noqa: E402
from test_system import read_bag, system  # noqa: E402, F401 - the fixture

MOVING_WEIGHTS = SHIPPED.with_name('generalist-moving.npz')  # the time-aware network


def _rollout(system, name: str, episodes: int, *arguments, succeed=True):  # noqa: F811
    """`stealth rollout --learner generalist ARGUMENTS` into run ``name``: its directory, after
    checking that it ran its ``episodes`` and (``succeed``) that every one succeeded."""
    result = system.run(
        'rollout', '--learner', 'generalist', *arguments, '--episodes', str(episodes),
        '--runs-dir', str(system.runs), '--name', name, timeout=120,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr + result.stdout
    run = system.runs / name
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['episodes'] == episodes, summary
    assert not succeed or summary['outcomes']['SUCCESS'] == episodes, summary['outcomes']
    return run


def test_the_generalist_crosses_a_shipped_scenario_undetected(system, tmp_path):  # noqa: F811
    run = _rollout(system, 'generalist', 2, '--scenario', 'simple-maze', '--goal', 'easy')
    params = {}
    for node in ('agent', 'environment'):
        text = (run / 'params' / f'{node}.yaml').read_text()
        params[node] = yaml.safe_load(text)[node]['ros__parameters']
    assert params['agent']['agent'] == 'generalist' and params['agent']['evaluate'] is True
    assert params['environment']['observation_layout'] == 'grid'

    _, messages, types = read_bag(run / 'recording.mcap')
    assert types['/rl_env/observation'] == 'stealth_interfaces/msg/GridObservation'
    (grid,) = messages['/rl_env/observation']  # sent once: static lights
    assert grid.layout.startswith('stealth-grid-v1/full/') and grid.channels == 7
    assert len(grid.data) == grid.rows * grid.cols * grid.channels
    # The two episodes counted (the loop may run on into a third while the run stops).
    steps = [step for step in messages['/rl_env/step_info'] if step.episode < 2]
    assert not any(step.detected for step in steps)
    assert [step.episode for step in steps if step.terminal] == [0, 1]
    ends = {m.episode: m.outcome for m in messages['/rl_env/episode_summary'] if m.episode < 2}
    assert ends == {0: 0, 1: 0}  # EpisodeSummary.SUCCESS
    agent_log = (run / 'logs' / 'agent.log').read_text()
    assert 'decision time per action' in agent_log


def test_the_generalist_crosses_on_the_sensed_track_undetected(system):  # noqa: F811
    """Track sensed: the environment sends the belief (what was sensed, -1 never) whenever it
    changes, the same full-track weights read it, and the robot reaches the goal undetected."""
    run = _rollout(
        system, 'sensed', 1, '--scenario', 'simple-maze', '--goal', 'easy',
        '--set', 'environment.track=sensed',
    )  # fmt: skip

    _, messages, _ = read_bag(run / 'recording.mcap')
    grids = [g for g in messages['/rl_env/observation'] if g.episode == 0]
    assert all(g.layout.startswith('stealth-grid-v1/sensed/') for g in grids)
    light = [np.asarray(g.data, np.float32).reshape(g.rows, g.cols, 7)[..., 3] for g in grids]
    assert all((each == -1).any() for each in light)  # never sensed goes out as such
    # With the description, nothing sensed (if the recorder caught it); then at the start and
    # whenever what was sensed changed, in step order.
    numbers = [g.step for g, each in zip(grids, light, strict=True) if (each >= 0).any()]
    steps = [step for step in messages['/rl_env/step_info'] if step.episode == 0]
    assert steps[-1].terminal and not any(step.detected for step in steps)
    assert numbers[0] == 0 and numbers == sorted(set(numbers))
    assert 1 < len(numbers) <= len(steps) + 1
    agent_log = (run / 'logs' / 'agent.log').read_text()
    assert 'grid observations planned on' in agent_log


def _in_process_actions(scenario: str, track: str) -> list[int]:
    """The actions of the benchmark's agent (``GeneralistAgent``, the time-aware weights) in
    one episode of the Gym env on ``track``."""
    from stealth_core.gym_env import StealthNavEnv
    from stealth_learn.generalist_agent import GeneralistAgent, load_policy

    env = StealthNavEnv(scenario, track=track)
    agent = GeneralistAgent(load_policy(MOVING_WEIGHTS), env)
    observation, _ = env.reset(seed=0)
    actions, done = [], False
    while not done:
        actions.append(agent.act(observation))
        observation, _, terminated, truncated, _ = env.step(actions[-1])
        done = terminated or truncated
    return actions


def test_the_time_aware_generalist_crosses_moving_lights_as_in_process(system):  # noqa: F811
    """Moving lights: the environment sends the phased grid once (8 layers, 12 channels), the
    agent decides at the state's (phase, cell), and the episode is the benchmark agent's
    (``GeneralistAgent`` in the Gym env): the same actions, waits included, undetected at the
    goal."""
    run = _rollout(
        system, 'moving', 1, '--policy', str(MOVING_WEIGHTS), '--scenario', 'simple-maze-moving'
    )

    _, messages, _ = read_bag(run / 'recording.mcap')
    (grid,) = messages['/rl_env/observation']  # sent once: the phased grid
    assert grid.layout.startswith('stealth-phased-v1/full/8phases-1perstep/')
    assert (grid.layers, grid.channels) == (8, 12) and grid.channel_names[-1] == 'step_wait'
    assert len(grid.data) == grid.layers * grid.rows * grid.cols * grid.channels
    steps = [step for step in messages['/rl_env/step_info'] if step.episode == 0]
    assert steps[-1].terminal and not any(step.detected for step in steps)
    actions = _in_process_actions('simple-maze-moving', 'full')
    assert [step.action for step in steps] == actions and 4 in actions  # the wait


def test_the_time_aware_generalist_crosses_moving_lights_sensed_as_in_process(system):  # noqa: F811
    """Moving lights, track sensed: before every state the environment sends the phased grid of
    what was sensed at each layer (-1 never), marked at that state's (phase, cell); the agent
    decides on the grid marking its state, and the episode is the benchmark agent's on the
    sensed Gym env (the robot's phased memory believed): the same actions (in-process it
    reaches the goal in 57; through ROS the true pose may stray into a beam's edge first)."""
    run = _rollout(
        system, 'moving-sensed', 1, '--policy', str(MOVING_WEIGHTS),
        '--scenario', 'map1-moving', '--set', 'environment.track=sensed', succeed=False,
    )  # fmt: skip

    _, messages, _ = read_bag(run / 'recording.mcap')
    steps = [step for step in messages['/rl_env/step_info'] if step.episode == 0]
    assert steps[-1].terminal and len(steps) >= 40
    grids = [g for g in messages['/rl_env/observation'] if g.episode == 0]
    assert all(g.layout.startswith('stealth-phased-v1/sensed/8phases-1perstep/') for g in grids)
    # With the description (nothing sensed, no mark), then one before each state decided on.
    marked = []
    for g in grids:
        grid = np.asarray(g.data, np.float32).reshape(g.layers, g.rows, g.cols, g.channels)
        assert (grid[..., 3] == -1).any() and (grid[..., 11][grid[..., 0] > 0] == -1).any()
        marked.append(int(grid[..., 1].sum()))
    numbers = [g.step for g, mark in zip(grids, marked, strict=True) if mark == 1]
    assert set(marked) <= {0, 1} and numbers == sorted(set(numbers))
    assert set(numbers) <= set(range(len(steps)))  # none before the terminal state
    recorder_log = (run / 'logs' / 'recorder.log').read_text()
    if "'/rl_env/observation': DDS lost" not in recorder_log:  # (a depth-1 topic: it may)
        assert numbers == list(range(len(steps)))
    in_process = _in_process_actions('map1-moving', 'sensed')
    assert [step.action for step in steps] == in_process[: len(steps)]
