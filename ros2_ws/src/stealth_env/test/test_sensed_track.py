"""The environment node's sensed track (no rclpy): the state it sends is the Gym env's sensed
observation, flattened, for the same moves; its description and its sensed_light levels."""

import numpy as np
import pytest
from stealth_core.grid_observation import (
    AGE,
    FREE,
    LIGHT,
    MOVE_RIGHT,
    MOVE_UP,
    ROBOT,
    observed_grid,
)
from stealth_core.gym_env import StealthNavEnv
from stealth_core.sensing import NO_PLACE, flat_observation
from stealth_env.sensed_track import SensedTrack

ACTIONS = [3, 3, 0, 0, 3, 1, 2, 0]


def poses_and_states(scenario: str, each=None):
    """(Gym env, its flat observations, the node's states) along ACTIONS, the node judging the
    Gym env's poses at its times (a robot that reaches every node exactly); ``each(env, track,
    state)`` after every state, if given."""
    env = StealthNavEnv(scenario, track='sensed')
    track = SensedTrack(env.task, env.model)
    observation, _ = env.reset(seed=0)
    expected = [flat_observation(observation)]
    sent = [track.first_state(env.model.states[env.node], env.scenario.start)]
    if each is not None:
        each(env, track, sent[-1])
    yaw = env.scenario.start[2]
    for step, action in enumerate(ACTIONS, start=1):
        if action < 4:  # the heading a move leaves the robot with (exposure scenarios)
            yaw = {0: np.pi / 2, 1: -np.pi / 2, 2: np.pi, 3: 0.0}[action]
        observation, _, terminated, truncated, info = env.step(action)
        expected.append(flat_observation(observation))
        state = env.model.states[env.node]
        t = step * env.step_seconds
        sent.append(track.step_state(state, (*info['pose'], yaw), t, step, info['visibility']))
        if each is not None:
            each(env, track, sent[-1])
        if terminated or truncated:
            break
    return env, track, expected, sent


@pytest.mark.parametrize('scenario', ['map1', 'map1-moving', 'map1-exposure'])
def test_the_state_is_the_gym_envs_flat_sensed_observation(scenario):
    env, track, expected, sent = poses_and_states(scenario)
    for step, (want, got) in enumerate(zip(expected, sent, strict=True)):
        got = np.asarray(got, dtype=np.float32)
        assert len(got) == track.length == len(want), step
        np.testing.assert_array_equal(got, want, err_msg=f'step {step}')


def test_each_episode_starts_knowing_no_light():
    env, track, _, sent = poses_and_states('map1')
    k = len(env.task.state_features)
    assert (np.asarray(sent[-1][k + 1 :]) >= 0).any()
    again = track.first_state(env.model.states[env.model.start], env.scenario.start)
    assert again == sent[0]


def test_the_belief_grid_is_the_states_sensed_part_sent_when_it_changed():
    env, track, _, _ = poses_and_states('map1')
    grid = observed_grid(env.task, 'sensed', 'grid', env.model)
    k = len(env.task.state_features)
    fresh = SensedTrack(env.task, env.model)  # what goes out with the description
    assert not (fresh.light >= 0).any() and not (fresh.moves >= 0).any() and not fresh.changed
    state = track.first_state(env.model.states[env.model.start], env.scenario.start)
    assert track.changed and track.step == 0  # an episode's first state: always sent
    belief = grid.belief(track.light, track.moves)
    tail = [belief[..., c].ravel() for c in (LIGHT, MOVE_UP, MOVE_RIGHT)]
    np.testing.assert_array_equal(np.asarray(state[k + 1 :], np.float32), np.concatenate(tail))
    np.testing.assert_array_equal(belief[..., FREE], grid.static()[..., FREE])
    assert (belief[..., LIGHT] == -1).any() and not belief[..., AGE].any()
    start = env.model.states[env.model.start]
    again = track.step_state(start, env.scenario.start, 0.0, 1, 0.0)  # sensed from where it was
    assert not track.changed and again[k + 1 :] == state[k + 1 :]
    points = track.sensor.sensing.points
    before, changes = again, []
    for step, (x, y) in enumerate(points[:: max(len(points) // 6, 1)], start=2):
        now = track.step_state(start, (float(x), float(y), 0.0), 0.0, step, 0.0)
        assert track.changed == (now[k + 1 :] != before[k + 1 :]), step
        changes.append(track.changed)
        before = now
    assert any(changes)


def test_with_moving_lights_the_phased_grid_sent_is_the_gym_envs_marked_at_its_place():
    """Moving lights: the phased grid of what was sensed the node sends before each state (as
    agent_link builds it) is the one of the Gym env's own phased memory, the robot marked at
    the Gym env's (layer, cell) only."""
    grid = None
    compared = []

    def compare(env, track, state):
        nonlocal grid
        grid = grid or observed_grid(env.task, 'sensed', 'grid', env.model)
        sent = grid.with_robot(grid.phased_sensed(track.sensor.phased), state)
        gym = grid.phased_sensed(env.sensor.phased)
        np.testing.assert_array_equal(sent[..., 2:], gym[..., 2:])
        np.testing.assert_array_equal(sent[..., FREE], gym[..., FREE])
        sensing = grid.sensing
        layer, node = divmod(int(env.node), sensing.n)
        assert sent[layer, sensing.grid_row[node], sensing.grid_col[node], ROBOT] == 1.0
        assert sent[..., ROBOT].sum() == 1.0
        compared.append((sent[..., LIGHT] >= 0).sum())

    poses_and_states('map1-moving', compare)
    assert grid.layout().startswith('stealth-phased-v1/sensed/8phases-1perstep/')
    assert len(compared) == len(ACTIONS) + 1 and compared[-1] > compared[0]  # it grew


def test_the_description_gives_every_feature_a_range():
    env, track, _, _ = poses_and_states('map1')
    fields = track.task.description(stochastic=True)
    described = track.description(fields)
    low, high = described['min_state_range'], described['max_state_range']
    assert len(low) == len(high) == track.length
    k = len(fields['min_state_range'])
    assert low[:k] == fields['min_state_range'] and high[:k] == fields['max_state_range']
    assert (low[k], high[k]) == (0.0, 1.0)
    space = env.observation_space
    assert set(low[k + 1 :]) == {NO_PLACE} and set(high[k + 1 :]) == {space['light'].high.max()}
    assert described['num_states'] == fields['num_states']


def test_sensed_light_levels_are_unknown_or_a_share_of_the_threshold():
    env, track, _, _ = poses_and_states('map1')
    levels = track.levels()
    light = env.sensor.sensing.grid(env.sensor.memory.node_light)
    assert levels.shape == light.shape and levels.dtype == np.int8
    known = light >= 0
    assert known.any() and (levels[~known] == -1).all()
    assert levels[known].min() >= 0 and levels[known].max() <= 100
    expected = np.minimum(np.rint(light[known] / env.scenario.detection_threshold * 100), 100)
    np.testing.assert_array_equal(levels[known], expected)
    resolution, x, y = track.grid_geometry()
    lattice = env.task.lattice
    assert resolution == env.scenario.step_distance
    assert (x + resolution / 2, y + resolution / 2) == pytest.approx(
        lattice.node_to_point((lattice.i_min, lattice.j_min))
    )
