"""Exposure by orientation (issue 18.1): the factor, the scenario field, the heading in the state,
turn actions, the planners over (node, heading), and the variants whose optimum it changes."""

import dataclasses
import math
from pathlib import Path

import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import numpy as np
import pytest
from stealth_core import exposure
from stealth_core.exposure import Footprint
from stealth_core.gym_env import StealthNavEnv
from stealth_core.lattice_model import LatticeModel
from stealth_core.lighting import point_light_visibilities
from stealth_core.planners import dark_path, follow, value_iteration, walk
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import ScenarioError, load_scenario
from stealth_core.task import StealthTask
from stealth_core.visibility import PointVisibility

VARIANTS = ('map1-exposure', 'simple-maze-exposure')
FOOTPRINT = Footprint(0.6, 0.15)


def test_the_factor_is_the_projected_width_over_the_diagonal():
    diagonal = math.hypot(0.6, 0.15)
    # Driving straight away from (or towards) the lamp shows the narrow end ...
    assert exposure.factor(FOOTPRINT, 0.0, 2.0, 0.0) == pytest.approx(0.15 / diagonal)
    assert exposure.factor(FOOTPRINT, math.pi, 2.0, 0.0) == pytest.approx(0.15 / diagonal)
    # ... crossing the beam the long side, and a corner towards the lamp all of the robot.
    assert exposure.factor(FOOTPRINT, math.pi / 2, 2.0, 0.0) == pytest.approx(0.6 / diagonal)
    corner = math.atan2(0.6, 0.15)
    assert exposure.factor(FOOTPRINT, corner, 3.0, 0.0) == pytest.approx(1.0)
    angles = np.linspace(-math.pi, math.pi, 721)
    values = exposure.factor(FOOTPRINT, angles, 1.0, 0.0)
    assert values.max() <= 1.0 + 1e-12 and values.min() == pytest.approx(0.15 / diagonal)
    # A square (the default footprint of the simulator's disc) still prefers a face to a corner.
    square = Footprint(0.4, 0.4)
    assert exposure.factor(square, 0.0, 1.0, 0.0) == pytest.approx(1 / math.sqrt(2))


def test_headings_are_quarter_turns_from_east():
    assert [exposure.heading_of(k * math.pi / 2 + 0.3) for k in range(4)] == [0, 1, 2, 3]
    assert exposure.heading_of(-math.pi / 2) == 3
    assert [exposure.heading_angle(k) for k in range(4)] == [
        0,
        math.pi / 2,
        math.pi,
        1.5 * math.pi,
    ]


def test_point_visibility_weighs_each_light_by_the_reference_and_the_factor():
    scenario = load_scenario('map1-exposure')
    occupancy = scenario.map
    see = PointVisibility(
        occupancy.blocked,
        occupancy.resolution,
        occupancy.origin,
        scenario.lights,
        footprint=scenario.exposure,
    )
    rng = np.random.default_rng(3)
    xs, ys = rng.uniform(8.0, 18.0, 60), rng.uniform(1.0, 16.0, 60)
    headings = rng.uniform(-math.pi, math.pi, 60)
    many = see.many(xs, ys, 0.0, headings)
    checked = 0
    for x, y, heading, value in zip(xs, ys, headings, many, strict=True):
        reference = point_light_visibilities(
            occupancy.blocked, occupancy.resolution, occupancy.origin, scenario.lights, x, y
        )
        weighed = [
            v * exposure.factor(scenario.exposure, heading, x - light.x, y - light.y)
            for v, light in zip(reference, scenario.lights, strict=True)
        ]
        assert see(x, y, 0.0, heading) == pytest.approx(sum(weighed), abs=1e-12)
        assert value == pytest.approx(sum(weighed), abs=1e-12)
        assert see(x, y) == pytest.approx(sum(reference), abs=1e-12)  # no heading: unweighed
        checked += sum(weighed) > 0
    assert checked >= 5  # the points include lit ones


def _write(tmp_path: Path, exposure_text: str) -> Path:
    text = Path(load_scenario('map1-exposure').path).read_text()
    text = text[: text.index('\nexposure:') + 1] + exposure_text
    text = text.replace('../maps/', f'{Path(load_scenario("map1").map_path).parent}/')
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ('text', 'field', 'got'),
    [
        ('exposure: {length: 0, width: 0.2}\n', 'exposure.length', 'got 0'),
        ('exposure: {length: 0.5, width: -0.2}\n', 'exposure.width', 'got -0.2'),
        ('exposure: {length: .nan, width: 0.2}\n', 'exposure.length', 'got nan'),
        ('exposure: {length: 0.5, width: wide}\n', 'exposure.width', "got 'wide'"),
        ('exposure: {length: 0.5, turn_actions: 1}\n', 'exposure.turn_actions', 'got 1'),
        ('exposure: {length: 0.5, height: 1}\n', 'exposure.height', 'length, width'),
        ('exposure: 3\n', 'exposure', 'got 3'),
        ('robot_radius: 0\nexposure: {}\n', 'exposure.length', 'the default'),
    ],
)
def test_a_bad_footprint_is_one_error_naming_the_field_and_the_range(tmp_path, text, field, got):
    if text.startswith('robot_radius'):
        path = _write(tmp_path, text.split('\n', 1)[1])
        path.write_text(path.read_text().replace('robot_radius: 0.2', 'robot_radius: 0'))
    else:
        path = _write(tmp_path, text)
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    message = str(caught.value)
    assert '\n' not in message and str(path) in message
    assert f"field '{field}'" in message and got in message
    if field not in ('exposure', 'exposure.height'):
        assert 'expected' in message and ('> 0 (m)' in message or 'true or false' in message)


def test_the_footprint_defaults_to_the_simulators_disc(tmp_path):
    scenario = load_scenario(_write(tmp_path, 'exposure: {}\n'))
    assert scenario.exposure == Footprint(0.4, 0.4, False)
    task = StealthTask(scenario)
    assert task.num_actions == 4 and task.state_features == ('x', 'y', 'heading')


def test_the_shipped_scenarios_have_exposure_off_and_the_variants_on():
    for name in ('simple-maze', 'map1', 'lgfloor', 'floorplan', 'map1-moving'):
        assert load_scenario(name).exposure is None
    for name in VARIANTS:
        scenario = load_scenario(name)
        assert scenario.exposure == Footprint(0.6, 0.15, True)
        task = StealthTask(scenario)
        assert task.action_names == ('up', 'down', 'left', 'right', 'turn_left', 'turn_right')
        assert task.state_features == ('x', 'y', 'heading')
        low, high = task.state_bounds()
        assert (low[2], high[2]) == (0.0, 3.0)
        plain = StealthTask(dataclasses.replace(scenario, exposure=None))
        assert task.description()['num_states'] == 4 * plain.description()['num_states']


@pytest.fixture(scope='module', params=VARIANTS)
def models(request):
    scenario = load_scenario(request.param)
    with_exposure = LatticeModel.build(StealthTask(scenario))
    without = LatticeModel.build(StealthTask(dataclasses.replace(scenario, exposure=None)))
    return with_exposure, without


def _optimal(model):
    optimum = value_iteration(model)
    path = follow(model, lambda i: int(optimum.policy[i]))
    return optimum, path, walk(model, path)


def test_the_option_changes_the_optimal_route(models):
    """The proof the issue asks for: value iteration's optimal path with exposure is not the one
    without, and it is better (exposure only ever takes light away)."""
    with_exposure, without = models
    best, path, result = _optimal(with_exposure)
    best_plain, path_plain, result_plain = _optimal(without)
    assert (
        result.outcome is EpisodeOutcome.SUCCESS and result_plain.outcome is EpisodeOutcome.SUCCESS
    )
    assert best.optimal_return > best_plain.optimal_return
    assert result.steps < result_plain.steps
    nodes = [with_exposure.nodes[with_exposure.node_of(i)] for i in path]
    assert nodes != [without.nodes[i] for i in path_plain]
    assert result.total_reward == pytest.approx(best.optimal_return)


def test_the_optimal_path_turns_its_narrow_side_to_a_light(models):
    """Somewhere on the optimum the light at the robot's point would see it unweighed, and the
    robot gets by because it drives straight towards or away from the lamp."""
    model, _ = models
    _, path, _ = _optimal(model)
    task = model.task
    threshold = task.scenario.detection_threshold
    narrow = 0
    for after in path[1:]:
        x, y = model.points[after]
        whole = task.visibility(x, y)
        heading = exposure.heading_angle(int(model.heading_of(after)))
        weighed = task.visibility(x, y, 0.0, heading)
        assert weighed < threshold
        if whole >= threshold:
            values = task._point_visibility.light_visibilities(x, y)
            lamp = task.scenario.lights[int(np.argmax(values))]
            ray = math.atan2(y - lamp.y, x - lamp.x)
            assert abs(math.sin(heading - ray)) < 0.3  # end on to the lamp
            narrow += 1
    assert narrow >= 3


def test_the_model_is_exact_on_node_and_heading(models):
    """Every step of the model (a sample of places and every action) is judged as the task
    judges it from the place's pose and heading, turn included; moves set the heading, turns
    turn it, blocked moves keep it."""
    model, _ = models
    task = model.task
    n = len(model.nodes)
    assert model.headings == 4 and model.size == 4 * n
    start_heading = exposure.heading_of(task.scenario.start[2])
    assert model.heading_of(model.start) == start_heading
    rng = np.random.default_rng(0)
    for i in rng.choice(model.size, 40, replace=False):
        heading = int(model.heading_of(i))
        x0, y0 = model.points[i]
        for action, name in enumerate(task.action_names):
            j = int(model.successors[i, action])
            moved = model.node_of(j) != model.node_of(i)
            assert model.heading_of(j) == task.heading_after(heading, action, moved)
            if name.startswith('turn'):
                assert not moved
                assert model.heading_of(j) == (heading + task.turn_of(action)) % 4
            x1, y1 = model.points[j]
            expected = task.step_visibility(
                x0, y0, 0.0, x1, y1, 0.0, exposure.heading_angle(heading),
                exposure.heading_angle(int(model.heading_of(j))),
            )  # fmt: skip
            assert model.step_visibility[i, action] == pytest.approx(expected, abs=1e-12)
            assert tuple(model.states[j]) == pytest.approx(
                task.state_of(x1, y1, 0.0, exposure.heading_angle(int(model.heading_of(j))))
            )


def test_a_turn_in_the_light_is_judged_on_the_headings_it_sweeps():
    task = StealthTask(load_scenario('simple-maze-exposure'))
    # In the west column's beam, facing the lamp (south) the robot passes; turning a quarter
    # in place it shows a corner on the way and is seen.
    x, y = 1.5, 6.0
    south, west = -math.pi / 2, math.pi
    facing = task.step_visibility(x, y, 0.0, x, y, 0.0, south, south)
    turning = task.step_visibility(x, y, 0.0, x, y, 0.0, south, west)
    assert facing < task.scenario.detection_threshold <= turning
    assert turning >= task.visibility(x, y, 0.0, west)


def test_dark_path_and_astar_run_on_headings(models):
    model, _ = models
    path = dark_path(model)
    assert path is not None and walk(model, path).outcome is EpisodeOutcome.SUCCESS


def test_the_gym_env_has_the_heading_and_the_turns():
    env = StealthNavEnv('simple-maze-exposure')
    assert env.action_space.n == 6 and env.observation_space.shape == (3,)
    observation, _ = env.reset(seed=0)
    assert observation[2] == 2.0  # the start faces west (yaw 180)
    observation, *_ = env.step(4)  # turn left: south
    assert tuple(observation) == (3.0, 1.5, 3.0)
    observation, *_ = env.step(1)  # down
    assert tuple(observation) == (3.0, 1.0, 3.0)
    observation, *_ = env.step(3)  # right: faces east
    assert tuple(observation) == (3.5, 1.0, 0.0)
    observation, *_ = env.step(1)  # down is blocked by the outer wall: the heading stays
    assert tuple(observation) == (3.5, 1.0, 0.0)
    check_env(
        gym.make('StealthNav-v0', scenario='map1-exposure').unwrapped, skip_render_check=True
    )


def test_exposure_combines_with_moving_lights():
    """places = node x phase x heading: a turn or a move takes a step's slot, and every step of
    the model is the task's, judged in space, time and heading."""
    moving = load_scenario('simple-maze-moving')
    scenario = dataclasses.replace(moving, exposure=Footprint(0.6, 0.15, True))
    task = StealthTask(scenario)
    assert task.action_names[4:] == ('wait', 'turn_left', 'turn_right')
    assert task.state_features == ('x', 'y', 'phase', 'heading')
    model = LatticeModel.build(task)
    timing = scenario.timing
    n = len(model.nodes)
    assert model.size == n * timing.cycle_bins * 4
    rng = np.random.default_rng(1)
    for i in rng.choice(model.size, 12, replace=False):
        cycle_bin = (i // n) % timing.cycle_bins
        heading = int(model.heading_of(i))
        t0 = cycle_bin * timing.bin_seconds
        for action in range(task.num_actions):
            j = int(model.successors[i, action])
            assert (j // n) % timing.cycle_bins == (
                cycle_bin + timing.bins_per_step
            ) % timing.cycle_bins
            expected = task.step_visibility(
                *model.points[i], t0, *model.points[j], t0 + timing.step_seconds,
                exposure.heading_angle(heading), exposure.heading_angle(int(model.heading_of(j))),
            )  # fmt: skip
            assert model.step_visibility[i, action] == pytest.approx(expected, abs=1e-12)
    best = value_iteration(model)
    result = walk(model, follow(model, lambda i: int(best.policy[i])))
    assert result.outcome is EpisodeOutcome.SUCCESS


def test_the_episode_flow_states_the_heading_and_judges_with_the_judged_yaw():
    """EpisodeFlow (the ROS environment's core): the state's heading is the estimate's yaw, a
    step is judged turning from the last judged yaw to the true pose's, turns are actions."""
    from stealth_env.episode_flow import EpisodeFlow, PlanarPose

    task = StealthTask(load_scenario('simple-maze-exposure'))
    flow = EpisodeFlow(task)
    token, _ = flow.begin_reset()
    assert flow.reset_done(token) == (3.0, 1.5, 2.0)
    assert 'turn_right' in flow.accept_action(6) and flow.accept_action(5) is None  # 5: right
    # In the beam facing the lamp, the truth turned from west to south on the spot: the turn
    # is judged, and the state's heading follows the estimate.
    truth = PlanarPose(1.5, 6.0, -math.pi / 2)
    flow._judged_at = (1.5, 6.0, 0.0, math.pi)
    report = flow.finish_move(flow.token, PlanarPose(1.52, 6.01, -1.5), truth, 3.0)
    assert report.state == (1.5, 6.0, 3.0)
    expected = task.step_visibility(1.5, 6.0, 0.0, 1.5, 6.0, 3.0, math.pi, -math.pi / 2)
    assert report.judgement.visibility == pytest.approx(expected)
    assert report.judgement.detected  # a quarter turn in the beam shows a corner
