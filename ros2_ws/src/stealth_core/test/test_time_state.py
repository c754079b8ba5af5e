"""Time in the state: the phase feature, the wait action, steps judged along the way, and the
Gymnasium environment on the time-expanded lattice."""

import warnings

import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv, lattice_model
from stealth_core.scenario import load_scenario
from stealth_core.task import WAIT, StealthTask
from stealth_core.visibility import scenario_point_visibility

SCENARIO = 'simple-maze-moving'


@pytest.fixture(scope='module')
def task():
    return StealthTask(load_scenario(SCENARIO))


def test_the_state_grows_by_the_phase(task):
    timing = task.timing
    assert task.state_features == ('x', 'y', 'phase')
    x, y = task.scenario.start[:2]
    assert task.state_of(x, y) == (x, y, 0.0)
    assert task.state_of(x, y, 3 * timing.bin_seconds + 0.1) == (x, y, 3.0)
    assert task.state_of(x, y, timing.cycle + timing.bin_seconds) == (x, y, 1.0)
    description = task.description()
    assert description['num_actions'] == 5
    assert len(description['min_state_range']) == len(description['max_state_range']) == 3
    assert description['min_state_range'][2] == 0.0
    assert description['max_state_range'][2] == timing.cycle_bins - 1
    static = StealthTask(load_scenario('simple-maze')).description()
    assert static['num_actions'] == 4 and len(static['min_state_range']) == 2
    assert description['num_states'] == static['num_states'] * timing.cycle_bins


def test_wait_stays_at_the_node(task):
    x, y = task.scenario.start[:2]
    assert task.move_target(x + 0.1, y - 0.1, WAIT) == (x, y)


def test_many_points_are_the_per_point_model(task):
    see = scenario_point_visibility(task.scenario)
    rng = np.random.default_rng(4)
    x_min, y_min, x_max, y_max = task.scenario.map.bounds
    xs = rng.uniform(x_min, x_max, 400)
    ys = rng.uniform(y_min, y_max, 400)
    for t in (0.0, 4.7, 13.0):
        expected = [see(x, y, t) for x, y in zip(xs, ys, strict=True)]
        np.testing.assert_allclose(see.many(xs, ys, t), expected, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match='outside the map'):
        see.many([x_max + 1.0], [y_min], 0.0)


def test_a_step_is_judged_on_its_brightest_sample(task):
    x, y = 13.5, 13.5  # the hard goal, beside the guard's lamp
    timing = task.timing
    samples = task.step_samples_of(x - 1.0, y, 0.0, x, y, timing.step_seconds)
    assert samples[0].shape == (task.step_samples,) and samples[0][-1] == x
    peak = task.step_visibility(x - 1.0, y, 0.0, x, y, timing.step_seconds)
    each = [task.visibility(*p) for p in zip(*samples, strict=True)]
    assert peak == max(each) >= task.visibility(x, y, timing.step_seconds)


def test_the_model_steps_are_the_tasks_steps():
    model = lattice_model(SCENARIO)
    task = model.task
    n = len(model.nodes)
    rng = np.random.default_rng(2)
    for place in rng.choice(model.size, 25, replace=False):
        cycle_bin, node = divmod(int(place), n)
        for direction in range(model.num_actions):
            target = int(model.successors[place, direction])
            assert target // n == (cycle_bin + task.timing.bins_per_step) % model.cycle_bins
            t0 = cycle_bin * task.timing.bin_seconds
            expected = task.step_visibility(
                *model.points[place], t0, *model.points[target], t0 + task.step_seconds
            )
            assert model.step_visibility[place, direction] == pytest.approx(expected, abs=1e-9)
        assert tuple(model.states[place]) == (*model.points[place], cycle_bin)


def test_the_gym_env_has_the_phase_and_the_wait():
    env = StealthNavEnv(SCENARIO)
    assert env.action_space.n == 5 and env.observation_space.shape == (3,)
    observation, _ = env.reset(seed=0)
    assert observation[2] == 0.0
    bins = env.task.timing.bins_per_step
    observation, reward, terminated, truncated, info = env.step(WAIT)
    assert tuple(observation[:2]) == tuple(env.model.points[env.model.start])
    assert observation[2] == bins % env.task.timing.cycle_bins
    assert info['steps'] == 1 and not terminated
    with pytest.raises(ValueError, match='0, 1, 2, 3, 4'):
        env.step(5)
    static = StealthNavEnv('simple-maze')
    assert static.action_space.n == 4 and static.observation_space.shape == (2,)


def test_the_gym_env_passes_the_checker_without_any_warning():
    env = gym.make('StealthNav-v0', scenario=SCENARIO, slip=0.1, render_mode='ansi')
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        check_env(env.unwrapped)
    env.reset(seed=0)
    env.unwrapped.step(WAIT)
    assert 'R' in env.render()
