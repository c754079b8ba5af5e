"""The sensed track: what the robot senses (walls, range), what it remembers, and the Gym
observation that carries it."""

import math
import warnings

import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import numpy as np
import pytest
from stealth_core.gym_env import ENV_ID, StealthNavEnv, lattice_model
from stealth_core.lighting import line_of_sight
from stealth_core.planners import astar
from stealth_core.sensing import NO_PLACE, UNKNOWN, Sensing, Sensor, flat_observation

SCENARIO = 'map1'


@pytest.fixture(scope='module')
def model():
    return lattice_model(SCENARIO)


@pytest.fixture(scope='module')
def sensing(model):
    return Sensing(model)


def cell(sensing, point):
    return sensing.frame.cell_of(*point)


def reference_nodes(sensing, node, reach):
    """The nodes in range and in sight of ``node``, one reference line at a time."""
    robot = cell(sensing, sensing.points[node])
    found = []
    for k, point in enumerate(sensing.points):
        if math.dist(point, sensing.points[node]) > reach:
            continue
        if line_of_sight(sensing.blocked, robot, cell(sensing, point)):
            found.append(k)
    return found


@pytest.mark.parametrize('node', [0, 150, 400, 777])
def test_sensed_nodes_are_those_in_range_and_in_sight(sensing, node):
    nodes, _ = sensing.trace(node)
    assert nodes.tolist() == reference_nodes(sensing, node, sensing.range)


def test_a_sensed_move_has_every_sample_in_range_and_in_sight(model, sensing):
    node = model.start
    _, moves = sensing.trace(node)
    robot = cell(sensing, sensing.points[node])
    samples = model.task.step_samples
    for e in range(sensing.moves):
        a, b = sensing.points[sensing.move_from[e]], sensing.points[sensing.move_to[e]]
        points = [a + (b - a) * f for f in np.linspace(0, 1, samples + 1)]
        near = all(math.dist(p, sensing.points[node]) <= sensing.range for p in points)
        seen = near and all(
            line_of_sight(sensing.blocked, robot, cell(sensing, p)) for p in points
        )
        assert (e in moves) == seen, e


def test_a_lit_node_behind_a_wall_is_not_sensed(model):
    sensor = Sensor(model)
    nodes, _ = sensor.sense(model.start, 0)
    sensing = sensor.sensing
    near = np.hypot(*(sensing.points - sensing.points[model.start]).T) <= sensing.range
    hidden_lit = np.flatnonzero(near & (model.visibility[: sensing.n] > 0))
    hidden_lit = np.setdiff1d(hidden_lit, nodes)
    assert hidden_lit.size > 0  # map1's start has lit nodes within range behind walls
    robot = cell(sensing, sensing.points[model.start])
    for k in hidden_lit:
        assert not line_of_sight(sensing.blocked, robot, cell(sensing, sensing.points[k]))
    assert np.all(sensor.memory.node_light[hidden_lit] == UNKNOWN)
    assert np.all(sensor.memory.node_step[hidden_lit] == -1)
    seen_lit = np.intersect1d(nodes, np.flatnonzero(model.visibility[: sensing.n] > 0))
    assert seen_lit.size > 0  # and lit nodes in sight, sensed with their light
    assert np.array_equal(sensor.memory.node_light[seen_lit], model.visibility[seen_lit])


def test_the_range_bounds_what_is_sensed(model):
    short, default = Sensing(model, 2.0), Sensing(model, None)
    assert default.range == 8.0  # the scenario's default
    near, _ = short.trace(model.start)
    far, _ = default.trace(model.start)
    assert set(near) < set(far)
    start = short.points[model.start]
    assert max(math.dist(short.points[k], start) for k in near) <= 2.0
    assert near.tolist() == reference_nodes(short, model.start, 2.0)


def test_memory_keeps_old_values_and_replaces_what_is_sensed_again(model):
    sensor = Sensor(model)
    first_nodes, first_moves = sensor.sense(model.start, 0)
    far = int(np.argmax(np.hypot(*(sensor.sensing.points - model.points[model.start]).T)))
    second_nodes, second_moves = sensor.sense(far, 7)
    memory = sensor.memory
    only_first = np.setdiff1d(first_nodes, second_nodes)
    assert only_first.size > 0 and second_nodes.size > 0
    assert np.all(memory.node_step[only_first] == 0)
    assert np.all(memory.node_step[second_nodes] == 7)
    assert np.array_equal(memory.node_light[second_nodes], model.visibility[second_nodes])
    assert np.all(memory.move_step[np.setdiff1d(first_moves, second_moves)] == 0)
    never = np.setdiff1d(np.arange(sensor.sensing.n), np.union1d(first_nodes, second_nodes))
    assert np.all(memory.node_light[never] == UNKNOWN)
    sensor.reset()
    assert not memory.node_known.any() or sensor.memory is not memory
    assert not sensor.memory.node_known.any()


def test_memory_takes_the_new_value_of_a_moving_light():
    model = lattice_model('map1-moving')
    sensor = Sensor(model)
    n = sensor.sensing.n

    def changes(node):  # a node from which a moving light is seen to change
        nodes, _ = sensor.sensing.visible(node)
        return np.any(model.visibility[nodes] != model.visibility[n + nodes])

    node = next(k for k in range(0, n, 7) if changes(k))
    nodes, _ = sensor.sense(node, 0)
    assert np.array_equal(sensor.memory.node_light[nodes], model.visibility[nodes])
    for layer in range(1, model.cycle_bins):
        sensor.sense(layer * n + node, layer)
        assert np.array_equal(sensor.memory.node_light[nodes], model.visibility[layer * n + nodes])
        assert np.all(sensor.memory.node_step[nodes] == layer)


def test_the_phased_memory_keeps_each_layers_value_apart():
    model = lattice_model('map1-moving')
    sensor = Sensor(model)
    n = sensor.sensing.n
    node = 150
    nodes, moves = sensor.sense(2 * n + node, 0)  # at bin 2
    phased = sensor.phased
    assert phased.layers == model.layers == model.cycle_bins
    truth_nodes, truth_moves = sensor.sensing.truth(2 * n + node, nodes, moves)
    assert np.array_equal(phased.node_light[2, nodes], truth_nodes)
    assert np.array_equal(phased.move_light[2, moves], truth_moves)
    # a wait from each node in sight: its light over the step (the beam may cross between bins)
    wait = model.step_visibility[2 * n + nodes, 4]
    assert np.array_equal(phased.wait_light[2, nodes], wait)
    assert (wait >= np.maximum(truth_nodes, model.visibility[3 * n + nodes]) - 1e-12).all()
    others = np.delete(np.arange(model.layers), 2)
    assert np.all(phased.node_light[others] == UNKNOWN)
    assert np.all(phased.move_light[others] == UNKNOWN)
    sensor.sense(5 * n + node, 1)  # the same place at bin 5: bin 2's values are kept
    assert np.array_equal(phased.node_light[2, nodes], truth_nodes)
    assert np.array_equal(phased.node_light[5, nodes], model.visibility[5 * n + nodes])
    sensor.reset()
    assert np.all(sensor.phased.node_light == UNKNOWN)
    assert np.all(sensor.phased.wait_light == UNKNOWN)


# --- the Gym observation ------------------------------------------------------------------------


@pytest.fixture
def env():
    environment = gym.make(ENV_ID, scenario=SCENARIO, track='sensed')
    yield environment
    environment.close()


def test_check_env_passes_on_the_sensed_track_without_any_warning():
    environment = gym.make(ENV_ID, scenario=SCENARIO, track='sensed', render_mode='ansi')
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        check_env(environment.unwrapped)


def test_the_full_track_stays_the_default():
    environment = StealthNavEnv(SCENARIO)
    observation, _ = environment.reset(seed=0)
    assert environment.track == 'full' and environment.sensor is None
    assert isinstance(observation, np.ndarray) and observation.shape == (2,)


def test_an_unknown_track_is_refused():
    with pytest.raises(ValueError, match="track: expected one of full, sensed, got 'blind'"):
        StealthNavEnv(SCENARIO, track='blind')


def test_the_observation_layout(env):
    observation, _ = env.reset(seed=0)
    unwrapped = env.unwrapped
    sensing, memory = unwrapped.sensor.sensing, unwrapped.sensor.memory
    columns, rows = unwrapped.task.lattice.shape
    assert set(observation) == {'state', 'lit', 'light', 'moves'}
    assert observation['light'].shape == (rows, columns)
    assert observation['moves'].shape == (2, rows, columns)
    assert observation in env.observation_space
    assert observation['state'].tolist() == unwrapped.model.states[unwrapped.node].tolist()
    light = observation['light']
    for k, (i, j) in enumerate(unwrapped.model.nodes):  # node (i, j) at [j - j_min, i - i_min]
        value = light[j - unwrapped.task.lattice.j_min, i - unwrapped.task.lattice.i_min]
        assert value == np.float32(memory.node_light[k])
    valid = np.zeros((rows, columns), dtype=bool)
    valid[sensing.grid_row, sensing.grid_col] = True
    assert np.all(light[~valid] == NO_PLACE)
    assert np.any(light[valid] == UNKNOWN) and np.any(light[valid] >= 0)
    # the move right from a node whose right neighbour is a node, and the move up
    e = int(np.flatnonzero(sensing.move_direction == 3)[0])
    start = sensing.move_from[e]
    channel = observation['moves'][1]
    assert channel[sensing.grid_row[start], sensing.grid_col[start]] == np.float32(
        memory.move_light[e]
    )
    flat = flat_observation(observation)
    assert flat.dtype == np.float32 and flat.size == 2 + 1 + 3 * rows * columns
    assert flat[3 : 3 + light.size].tolist() == light.ravel().tolist()


def test_the_lit_flag_is_the_judged_light_against_the_threshold(env):
    unwrapped = env.unwrapped
    model, task = unwrapped.model, unwrapped.task
    threshold = task.scenario.detection_threshold
    observation, info = env.reset(seed=0)
    start = model.points[model.start]
    assert observation['lit'][0] == int(task.visibility(*start) >= threshold)
    path = astar(model)  # the shortest way is seen: the flag goes up when it is
    flags = []
    for before, after in zip(path, path[1:], strict=False):
        observation, _, terminated, truncated, info = env.step(model.direction(before, after))
        judged = model.step_visibility[before, model.direction(before, after)]
        assert info['visibility'] == judged
        assert observation['lit'][0] == int(judged >= threshold)
        flags.append(int(observation['lit'][0]))
        if terminated or truncated:
            break
    assert info['detected'] and flags[-1] == 1 and set(flags[:-1]) == {0}


def test_the_sensed_track_judges_as_the_full_track():
    actions = np.random.default_rng(3).integers(4, size=300).tolist()
    full, sensed = StealthNavEnv(SCENARIO), StealthNavEnv(SCENARIO, track='sensed')
    for environment in (full, sensed):
        environment.reset(seed=4)
    for action in actions:
        a, b = full.step(action), sensed.step(action)
        assert a[0].tolist() == b[0]['state'].tolist()
        assert a[1:] == b[1:]
        if a[2] or a[3]:
            full.reset()
            sensed.reset()


def test_each_episode_starts_knowing_no_light(env):
    unwrapped = env.unwrapped
    first, _ = env.reset(seed=0)
    for action in np.random.default_rng(2).integers(4, size=40).tolist():
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    assert np.count_nonzero(unwrapped.sensor.memory.node_step > 0) > 0
    again, _ = env.reset(seed=0)
    assert np.all(unwrapped.sensor.memory.node_step <= 0)
    assert np.array_equal(again['light'], first['light'])
    assert np.array_equal(again['moves'], first['moves'])


@pytest.mark.parametrize('scenario', ['map1', 'map1-moving', 'map1-exposure'])
def test_the_place_of_a_pose_is_the_gym_envs_place(scenario):
    env = StealthNavEnv(scenario, track='sensed')
    sensor, task = env.sensor, env.task
    env.reset(seed=0)
    yaw = task.scenario.start[2]
    for action in np.random.default_rng(6).integers(4, size=60).tolist():
        _, _, terminated, truncated, info = env.step(action)
        t = info['steps'] * task.step_seconds
        if task.footprint is not None:
            yaw = float(env.model.heading_of(env.node)) * math.pi / 2
        assert sensor.place_of(*info['pose'], t, yaw) == env.node
        if terminated or truncated:
            break
