"""Scenario files: the shipped four, the format, and one clear error per kind of bad input."""

import copy
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from stealth_core.occupancy_map import OccupancyMap, save_map
from stealth_core.reward import RewardWeights
from stealth_core.scenario import (
    Goal,
    NotMarkovWarning,
    ScenarioError,
    find_scenario,
    load_scenario,
    scenario_paths,
)
from stealth_core.searchlight import PatrolMotion, SweepMotion
from stealth_core.visibility import visibility_field
import yaml

REPO = Path(__file__).resolve().parents[4]
SHIPPED = ['floorplan', 'lgfloor', 'map1', 'simple-maze']
MOVING = [f'{name}-moving' for name in SHIPPED]
EXPOSURE = ['map1-exposure', 'simple-maze-exposure']
BOUNCE = ['lgfloor-bounce', 'map1-bounce']  # one-bounce light (test_bounce_scenarios.py)


# --- the shipped scenarios ----------------------------------------------------------------------


def test_the_four_scenarios_and_their_variants_are_found_by_name():
    assert [path.stem for path in scenario_paths()] == sorted(SHIPPED + MOVING + EXPOSURE + BOUNCE)
    assert find_scenario('lgfloor') == REPO / 'scenarios' / 'lgfloor.yaml'


@pytest.mark.parametrize('name', SHIPPED)
def test_shipped_scenario_loads_and_validates(name):
    scenario = load_scenario(name)
    assert scenario.name == name
    assert scenario.map_path.resolve() == REPO / 'maps' / f'{name}.yaml'
    assert list(scenario.goals) == ['easy', 'medium', 'hard']
    assert scenario.default_goal == 'hard' and scenario.goal is scenario.goals['hard']
    assert scenario.step_distance == 0.5 and scenario.state_cell == 0.5
    assert scenario.goal_radius == 0.5 and scenario.robot_radius == 0.2
    assert scenario.detection_threshold == 0.3 and scenario.detection_mode == 'threshold'
    assert 100 <= scenario.step_limit <= 1000
    assert scenario.lights


def lit_by(scenario) -> np.ndarray:
    """Per light, the cells it lights (occlusion included), (n_lights, height, width)."""
    occupancy = scenario.map
    _, per_light = visibility_field(
        occupancy.blocked, occupancy.resolution, occupancy.origin, scenario.lights
    )
    return per_light > 0


def test_lgfloor_has_four_lights_two_of_them_overlapping():
    scenario = load_scenario('lgfloor')
    assert len(scenario.lights) == 4
    overlap = lit_by(scenario).sum(axis=0) >= 2
    assert overlap.any()


def test_map1_has_three_lights_one_close_to_the_goal():
    scenario = load_scenario('map1')
    assert len(scenario.lights) == 3
    goal = scenario.goals['hard']
    assert min(math.dist((light.x, light.y), goal.point) for light in scenario.lights) < 3.0


def test_floorplan_lights_stand_in_different_rooms_on_the_way():
    scenario = load_scenario('floorplan')
    assert len(scenario.lights) >= 2
    xs = sorted(light.x for light in scenario.lights)
    start_x, goal_x = scenario.start[0], scenario.goals['hard'].x
    assert all(start_x < x < goal_x for x in xs)
    for light in scenario.lights:  # inside a room, not in the corridor y in [11, 14]
        assert not 11.0 <= light.y <= 14.0


def test_simple_maze_lights_have_very_wide_ranges():
    scenario = load_scenario('simple-maze')
    diagonal = math.hypot(scenario.map.width, scenario.map.height) * scenario.map.resolution
    assert all(light.range >= 0.9 * diagonal for light in scenario.lights)


# --- the format, on a small map of our own ------------------------------------------------------


def small_map() -> OccupancyMap:
    """10 x 8 m at 0.1 m: a wall x in [4, 5], y < 5; unknown x > 8, y > 6; a sealed room."""
    data = np.zeros((80, 100), np.int8)
    data[0:50, 40:50] = 100
    data[60:80, 80:100] = -1
    data[5:36, 65:96] = 100
    data[7:34, 67:94] = 0  # the sealed room's inside, x in [6.7, 9.4], y in [0.7, 3.4]
    return OccupancyMap(data, 0.1, (0.0, 0.0, 0.0))


BASE = {
    'name': 'small',
    'map': '../maps/small.yaml',
    'start': {'x': 1.0, 'y': 1.0, 'yaw': 90},
    'goals': {
        'easy': {'x': 2.0, 'y': 6.0},
        'medium': {'x': 6.0, 'y': 6.0},
        'hard': {'x': 6.0, 'y': 1.0},
    },
    'robot_radius': 0.2,
    'step_distance': 0.5,
    'goal_radius': 0.5,
    'detection_threshold': 0.3,
    'step_limit': 200,
    'lights': [
        {'name': 'a', 'x': 3.0, 'y': 3.0, 'direction': 90, 'fov': 60, 'range': 4.0},
        {'x': 6.0, 'y': 7.0, 'direction': 180, 'fov': 360, 'range': 2.0, 'delta': 0.2},
    ],
    'rewards': {},
}


@pytest.fixture
def write(tmp_path):
    """Write the scenario BASE changed by ``change`` and return its path."""
    (tmp_path / 'maps').mkdir()
    (tmp_path / 'scenarios').mkdir()
    save_map(small_map(), tmp_path / 'maps' / 'small')

    def writer(change=lambda values: None, text: str | None = None) -> Path:
        values = copy.deepcopy(BASE)
        change(values)
        path = tmp_path / 'scenarios' / 'small.yaml'
        path.write_text(yaml.safe_dump(values, sort_keys=False) if text is None else text)
        return path

    return writer


def test_a_valid_scenario(write):
    scenario = load_scenario(write())
    assert scenario.start == (1.0, 1.0, math.pi / 2)
    assert scenario.goals['medium'] == Goal('medium', 6.0, 6.0, 0.5)
    assert scenario.default_goal == 'hard'
    first, second = scenario.lights
    assert first.direction == pytest.approx(math.pi / 2) and first.fov == pytest.approx(
        math.pi / 3
    )
    assert first.delta == 0.1 and first.soft_edge == 0.0 and first.motion is None
    assert second.name == 'L2' and second.fov == pytest.approx(2 * math.pi)
    assert scenario.state_cell == 0.5 and scenario.detection_mode == 'threshold'
    assert scenario.rewards == RewardWeights()


def test_optional_fields(write):
    def change(values):
        values['goals'] = {'easy': {'x': 2.0, 'y': 6.0, 'radius': 0.8}}
        values['robot_radius'] = 0.1
        values['state_cell'] = 0.25
        values['detection_mode'] = 'probabilistic'
        values['rewards'] = {'goal_reward': 500, 'detection_penalty': 5000}
        values['lights'][0]['soft_edge'] = 0.25
        values['lights'][0]['motion'] = {
            'type': 'sweep',
            'min_direction': 60,
            'max_direction': 120,
            'angular_speed': 30,
        }
        values['lights'][1]['motion'] = {
            'type': 'patrol',
            'waypoints': [[6, 5], [2, 7]],
            'speed': 1,
        }

    scenario = load_scenario(write(change))
    assert list(scenario.goals) == ['easy'] and scenario.goal.radius == 0.8
    assert (scenario.robot_radius, scenario.state_cell) == (0.1, 0.25)
    assert scenario.rewards.goal_reward == 500 and scenario.rewards.time_cost == 0.0
    sweep, patrol = scenario.lights[0].motion, scenario.lights[1].motion
    assert sweep == SweepMotion(math.radians(60), math.radians(120), math.radians(30))
    assert patrol == PatrolMotion(((6.0, 5.0), (2.0, 7.0)), 1.0)
    assert scenario.lights[0].soft_edge == 0.25


def test_find_scenario_on_the_search_path(write, monkeypatch):
    path = write()
    monkeypatch.setenv('STEALTH_NAV_SCENARIOS', str(path.parent))
    assert find_scenario('small') == path
    assert load_scenario('small').name == 'small'


# --- bad input ----------------------------------------------------------------------------------


def assert_scenario_error(path: Path, *parts: str) -> None:
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    message = str(raised.value)
    assert message.startswith(str(path)), message
    for part in parts:
        assert part in message, message
    assert '\n' not in message


def setter(key_path: str, value):
    """A change to BASE setting the field at a dotted path (numbers index lists)."""

    def change(values):
        *parents, last = key_path.split('.')
        node = values
        for key in parents:
            node = node[int(key)] if key.isdigit() else node[key]
        if value is DELETE:
            del node[int(last) if last.isdigit() else last]
        else:
            node[int(last) if last.isdigit() else last] = value

    return change


DELETE = object()


def test_unknown_scenario_name():
    with pytest.raises(ScenarioError, match="scenario 'nowhere': not found .*lgfloor"):
        find_scenario('nowhere')


def test_missing_scenario_file(tmp_path):
    assert_scenario_error(tmp_path / 'absent.yaml', 'cannot read scenario', 'No such file')


def test_unreadable_scenario_file(tmp_path):
    (tmp_path / 'folder.yaml').mkdir()
    assert_scenario_error(tmp_path / 'folder.yaml', 'cannot read scenario')


def test_yaml_syntax_error(write):
    assert_scenario_error(write(text='name: x\nstart: {x: 1, y: 2\n'), 'YAML syntax error at line')


def test_a_key_given_twice_is_an_error_not_the_last_value(write):
    text = 'name: x\nstep_limit: 100\nstart: {x: 1, y: 2}\nstep_limit: 300\n'
    assert_scenario_error(
        write(text=text), "at line 4, column 1: duplicate key 'step_limit' (first at line 2)"
    )
    nested = 'name: x\nstart: {x: 1, y: 2, x: 3}\n'
    assert_scenario_error(write(text=nested), "duplicate key 'x' (first at line 2)")


def test_scenario_that_is_not_a_mapping(write):
    assert_scenario_error(write(text='[1, 2]\n'), 'expected a YAML mapping of scenario fields')


@pytest.mark.parametrize(
    'field',
    [
        'map',
        'start',
        'goals',
        'step_distance',
        'goal_radius',
        'detection_threshold',
        'step_limit',
        'lights',
    ],
)
def test_missing_field(write, field):
    assert_scenario_error(write(setter(field, DELETE)), f"field '{field}'", 'missing')


@pytest.mark.parametrize(
    ('field', 'value'),
    [
        ('step_distance', 'far'),
        ('step_limit', 2.5),
        ('step_limit', True),
        ('robot_radius', True),
        ('start', 'home'),
        ('start.yaw', 'north'),
        ('goals', ['easy']),
        ('goals.easy.x', None),
        ('lights', {'a': 1}),
        ('lights.0', 'lamp'),
        ('lights.0.direction', 'up'),
        ('name', 7),
        ('map', 3),
        ('detection_mode', 'sometimes'),
        ('rewards', [1, 2]),
        ('rewards.goal_reward', 'lots'),
        ('default_goal', 'impossible'),
    ],
)
def test_wrongly_typed_field(write, field, value):
    name = field.replace('.0', '[0]').replace('s[0].', 's[0].')
    assert_scenario_error(write(setter(field, value)), f"field '{name}'", 'expected')


@pytest.mark.parametrize(
    'field', ['stepdistance', 'start.z', 'goals.extreme', 'goals.easy.yaw', 'lights.0.colour']
)
def test_unknown_field(write, field):
    name = field.replace('.0.', '[0].')
    assert_scenario_error(write(setter(field, 1)), f"field '{name}'", 'unknown field')


@pytest.mark.parametrize(
    ('field', 'value'), [('step_distance', 0), ('goal_radius', -1), ('detection_threshold', 0)]
)
def test_numbers_out_of_range(write, field, value):
    assert_scenario_error(write(setter(field, value)), f"field '{field}'", 'expected a number > 0')


def test_missing_map_file(write):
    assert_scenario_error(
        write(setter('map', '../maps/absent.yaml')), "field 'map'", 'cannot read map YAML'
    )


def test_bad_map(write, tmp_path):
    path = write()
    map_yaml = tmp_path / 'maps' / 'small.yaml'
    map_yaml.write_text(map_yaml.read_text().replace('resolution: 0.100', 'resolution: -1'))
    assert_scenario_error(path, "field 'map'", "field 'resolution'", 'expected a number > 0')


@pytest.mark.parametrize(
    ('field', 'value', 'named'),
    [('start.x', -1.0, 'start.x'), ('start.y', 8.0, 'start.y'), ('start.x', 10.0, 'start.x')],
)
def test_start_outside_the_map(write, field, value, named):
    assert_scenario_error(write(setter(field, value)), f"field '{named}'", 'inside the map')


def test_start_in_an_occupied_cell(write):
    assert_scenario_error(
        write(setter('start.x', 4.5)), "field 'start'", 'free cell', 'occupied cell'
    )


def test_start_in_an_unknown_cell(write):
    def change(values):
        values['start'] = {'x': 9.0, 'y': 7.0}

    assert_scenario_error(write(change), "field 'start'", 'free cell', 'unknown cell')


def test_start_without_clearance(write):
    assert_scenario_error(
        write(setter('start.x', 3.85)), "field 'start'", 'robot_radius 0.2 m of clearance'
    )


def test_goal_outside_the_map(write):
    assert_scenario_error(
        write(setter('goals.hard.x', 12.0)), "field 'goals.hard.x'", 'inside the map'
    )


def test_goal_in_an_occupied_cell(write):
    assert_scenario_error(write(setter('goals.hard.x', 4.2)), "field 'goals.hard'", 'occupied')


def test_goal_in_an_unknown_cell(write):
    def change(values):
        values['goals']['medium'] = {'x': 9.5, 'y': 7.5}

    assert_scenario_error(write(change), "field 'goals.medium'", 'unknown cell')


def test_unreachable_goal(write):
    def change(values):
        values['goals']['hard'] = {'x': 8.0, 'y': 2.0}  # inside the sealed room

    assert_scenario_error(write(change), "field 'goals.hard'", 'reachable from the start')


@pytest.mark.parametrize(
    ('field', 'value', 'named'),
    [
        ('lights.1.x', 10.5, 'lights[1].x'),
        ('lights.0.y', -0.5, 'lights[0].y'),
        ('lights.1.y', 8.0, 'lights[1].y'),
    ],
)
def test_light_outside_the_map(write, field, value, named):
    assert_scenario_error(
        write(setter(field, value)), f"field '{named}'", 'a light position inside the map'
    )


@pytest.mark.parametrize('value', [0, -2.0])
def test_light_range_not_positive(write, value):
    assert_scenario_error(
        write(setter('lights.0.range', value)), "field 'lights[0].range'", 'a number > 0 (m)'
    )


@pytest.mark.parametrize('value', [0, -10, 360.5, 400])
def test_light_field_of_view_outside_0_360(write, value):
    assert_scenario_error(
        write(setter('lights.1.fov', value)), "field 'lights[1].fov'", 'in (0, 360] degrees'
    )


@pytest.mark.parametrize('value', [0, 1, 1.5, -0.1])
def test_light_delta_outside_0_1(write, value):
    assert_scenario_error(
        write(setter('lights.0.delta', value)), "field 'lights[0].delta'", 'a number in (0, 1)'
    )


def test_light_soft_edge_outside_0_1(write):
    assert_scenario_error(
        write(setter('lights.0.soft_edge', 2)), "'lights[0].soft_edge'", '[0, 1]'
    )


def test_duplicate_light_names(write):
    assert_scenario_error(
        write(setter('lights.1.name', 'a')), "field 'lights[1].name'", 'a name no other light has'
    )


def test_unknown_motion_type(write):
    assert_scenario_error(
        write(setter('lights.0.motion', {'type': 'dance'})),
        "field 'lights[0].motion.type'",
        'sweep or patrol',
    )


def test_sweep_ends_out_of_order(write):
    motion = {'type': 'sweep', 'min_direction': 90, 'max_direction': 30, 'angular_speed': 5}
    assert_scenario_error(
        write(setter('lights.0.motion', motion)), "'lights[0].motion.max_direction'", '[90, 450]'
    )


def test_sweep_that_does_not_hold_the_direction(write):
    motion = {'type': 'sweep', 'min_direction': 120, 'max_direction': 150, 'angular_speed': 5}
    assert_scenario_error(
        write(setter('lights.0.motion', motion)),
        "field 'lights[0].direction'",
        'an angle inside the sweep [120, 150], got 90',
    )


def test_sweep_direction_is_taken_modulo_360(write):
    motion = {'type': 'sweep', 'min_direction': 420, 'max_direction': 460, 'angular_speed': 5}
    assert load_scenario(write(setter('lights.0.motion', motion))).lights[0].motion is not None


def test_patrol_waypoint_outside_the_map(write):
    motion = {'type': 'patrol', 'waypoints': [[1, 1], [1, 9]], 'speed': 0.5}
    assert_scenario_error(
        write(setter('lights.1.motion', motion)),
        "field 'lights[1].motion.waypoints[1]'",
        'a waypoint inside the map',
    )


@pytest.mark.parametrize(
    ('light', 'motion', 'field'),
    [
        (0, {'type': 'sweep', 'min_direction': 60, 'max_direction': 120, 'angular_speed': 0},
         'angular_speed'),
        (1, {'type': 'patrol', 'waypoints': [[1, 1]], 'speed': 0}, 'speed'),
    ],
)  # fmt: skip
def test_motion_with_zero_speed(write, light, motion, field):
    assert_scenario_error(
        write(setter(f'lights.{light}.motion', motion)),
        f"field 'lights[{light}].motion.{field}'",
        'a number > 0',
        'got 0',
    )


SWEEP_12S = {'type': 'sweep', 'min_direction': 60, 'max_direction': 120, 'angular_speed': 10}


def moving(phase_bins=None, step_seconds=None, motion=SWEEP_12S):
    def change(values):
        values['lights'][0]['motion'] = motion
        if phase_bins is not None:
            values['phase_bins'] = phase_bins
        if step_seconds is not None:
            values['step_seconds'] = step_seconds

    return change


def test_phase_bins_and_step_seconds(write):
    scenario = load_scenario(write(moving(phase_bins=6, step_seconds=4.0)))
    timing = scenario.timing
    assert (timing.cycle, timing.cycle_bins, timing.step_seconds) == (12.0, 6, 4.0)
    assert timing.bins_per_step == 2
    assert load_scenario(write(moving(phase_bins=4))).timing.step_seconds == 3.0  # one bin
    assert load_scenario(write()).timing is None


def test_phase_bins_of_zero(write):
    assert_scenario_error(
        write(moving(phase_bins=0)), "field 'phase_bins'", 'an integer >= 1, got 0'
    )


def test_a_period_that_does_not_divide_into_the_bins(write):
    patrol = {'type': 'patrol', 'waypoints': [[3, 5]], 'speed': 1}  # 2 m there, 2 back: 4 s

    def change(values):
        moving(phase_bins=4)(values)  # the cycle, lcm(12, 4) = 12 s, in bins of 3 s
        values['lights'][1]['motion'] = patrol
        values['lights'][1]['x'], values['lights'][1]['y'] = 3.0, 3.0

    assert_scenario_error(
        write(change),
        "searchlight 'L2': field 'motion.speed'",
        'its period 4 s is 1.33333 phase bins of 3 s',
        'expected a whole number',
    )


def test_a_step_that_is_not_a_whole_number_of_bins(write):
    assert_scenario_error(
        write(moving(phase_bins=4, step_seconds=4.5)),
        "field 'step_seconds'",
        'a whole number (>= 1) of phase bins of 3 s',
    )


def test_phase_bins_without_moving_lights(write):
    assert_scenario_error(
        write(setter('phase_bins', 4)),
        "field 'phase_bins'",
        'only in a scenario whose lights move',
    )


def test_moving_lights_without_phase_bins_warn_that_the_task_is_not_markov(write):
    with pytest.warns(NotMarkovWarning, match=r'lights a move .* the task is not Markov'):
        scenario = load_scenario(write(moving()))
    assert scenario.timing is None and scenario.has_moving_lights


def test_patrol_waypoint_not_a_point(write):
    motion = {'type': 'patrol', 'waypoints': [[1, 1, 1]], 'speed': 0.5}
    assert_scenario_error(
        write(setter('lights.1.motion', motion)), "'lights[1].motion.waypoints[0]'", '[x, y]'
    )


def test_unknown_reward_weight(write):
    assert_scenario_error(
        write(setter('rewards', {'bonus': 1})), "field 'rewards.bonus'", 'goal_reward'
    )


def test_negative_reward_weight(write):
    assert_scenario_error(
        write(setter('rewards', {'time_cost': -1})), "field 'rewards.time_cost'", '>= 0'
    )


def test_ill_posed_rewards(write):
    def change(values):
        values['rewards'] = {'detection_penalty': 10.0}
        values['step_limit'] = 1000

    assert_scenario_error(write(change), "field 'rewards'", 'ill-posed')


# --- one-bounce light ---------------------------------------------------------------------------


def test_bounce_is_off_by_default_and_in_the_shipped_scenarios(write):
    assert load_scenario(write()).bounce is None
    for name in SHIPPED + MOVING:
        assert load_scenario(name).bounce is None
    assert load_scenario(write(setter('bounce', {'albedo': 0}))).bounce is None


def test_a_bounce_loads_with_its_default_range(write):
    scenario = load_scenario(write(setter('bounce', {'albedo': 0.25})))
    assert (scenario.bounce.albedo, scenario.bounce.range) == (0.25, 3.0)
    scenario = load_scenario(write(setter('bounce', {'albedo': 0.5, 'range': 2})))
    assert (scenario.bounce.albedo, scenario.bounce.range) == (0.5, 2.0)


@pytest.mark.parametrize('value', [math.nan, 1, 1.5, -0.1, math.inf, 'bright', None])
def test_bounce_albedo_outside_0_1(write, value):
    assert_scenario_error(
        write(setter('bounce', {'albedo': value})),
        "field 'bounce.albedo'",
        'expected a number in [0, 1)',
    )


@pytest.mark.parametrize('value', [0, -1, math.nan])
def test_bounce_range_not_positive(write, value):
    assert_scenario_error(
        write(setter('bounce', {'albedo': 0.3, 'range': value})),
        "field 'bounce.range'",
        'a number > 0 (m)',
    )


def test_bounce_fields_are_checked(write):
    assert_scenario_error(write(setter('bounce', 0.3)), "field 'bounce'", 'a mapping {albedo')
    assert_scenario_error(
        write(setter('bounce', {'albedo': 0.3, 'colour': 'white'})),
        "field 'bounce.colour'",
        'unknown field',
    )
    assert_scenario_error(write(setter('bounce', {'range': 2.0})), "'bounce.albedo'", 'missing')


def test_bounce_with_moving_lights_is_refused(write):
    def change(values):
        moving(phase_bins=4)(values)
        values['bounce'] = {'albedo': 0.3}

    assert_scenario_error(
        write(change),
        "field 'bounce'",
        'no bounce in a scenario whose lights move',
        'lights[0] (',
    )


def test_bounce_with_exposure_is_refused(write):
    def change(values):
        values['bounce'] = {'albedo': 0.3}
        values['exposure'] = {'length': 0.6, 'width': 0.3}

    assert_scenario_error(
        write(change), "field 'bounce'", 'no bounce together with exposure', 'an exposure field'
    )


def test_probabilistic_mode_counts_the_bounce_in_the_reward_check(write):
    """Undetected steps may be brighter by the bounce's bound (bounce.bounce_bound)."""

    def change(penalty):
        def apply(values):
            values['detection_mode'] = 'probabilistic'
            values['bounce'] = {'albedo': 0.9, 'range': 3.0}
            values['rewards'] = {'detection_penalty': penalty}

        return apply

    assert_scenario_error(write(change(1000)), "field 'rewards'", 'Raise detection_penalty')
    assert load_scenario(write(change(30000))).bounce.albedo == 0.9


def free_cells_lit(scenario, light) -> int:
    """How many free cells within the light's range it lights (the lighting reference)."""
    from stealth_core.lighting import point_visibility

    grid = scenario.map
    lit = 0
    for row, col in zip(*np.nonzero(~grid.blocked), strict=True):
        x, y = grid.origin[0] + (col + 0.5) * 0.1, grid.origin[1] + (row + 0.5) * 0.1
        if math.dist((x, y), (light.x, light.y)) <= light.range:
            lit += point_visibility(grid.blocked, 0.1, grid.origin, [light], x, y) > 0
    return lit


@pytest.mark.parametrize(
    ('x', 'y', 'direction', 'kind'),
    [
        (4.55, 2.05, 90, 'occupied'),  # deep in the wall
        (4.05, 2.05, 0, 'occupied'),  # in its westmost column, facing into it
        (9.05, 7.05, 180, 'unknown'),
    ],
)
def test_a_light_in_a_wall_is_refused_with_its_name_and_position(write, x, y, direction, kind):
    def change(values):
        values['lights'][1].update(name='buried', x=x, y=y, direction=direction, fov=60)

    path = write(change)
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    assert str(raised.value) == (
        f"{path}: field 'lights[1]': expected a light in a free cell of the map, got 'buried' at "
        f'({x:g}, {y:g}) in an {kind} cell; move it to a free cell or remove it'
    )
    # and indeed it lights nothing: the same light, loaded in the open, then put there
    scenario = load_scenario(write())
    buried = dataclasses.replace(
        scenario.lights[1], x=x, y=y, direction=math.radians(direction), fov=math.radians(60)
    )
    assert free_cells_lit(scenario, buried) == 0


# --- sensing_range (the sensed track) -----------------------------------------------------------


def test_sensing_range_defaults_to_8_m_and_takes_a_value(write):
    assert load_scenario(write()).sensing_range == 8.0
    assert load_scenario(write(setter('sensing_range', 3.5))).sensing_range == 3.5


@pytest.mark.parametrize('value', [0, -2.0, 13.0, 'far'])
def test_sensing_range_zero_negative_or_beyond_the_map_is_named(write, value):
    # the small map is 10 x 8 m: its diagonal is 12.8062 m
    assert_scenario_error(
        write(setter('sensing_range', value)),
        "field 'sensing_range'",
        "expected a number > 0 (m) and at most the map's diagonal, 12.8062 m",
    )
