"""Marker geometry and Searchlight fields of the environment node, without ROS."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from stealth_core.lighting import intensity, point_visibility
from stealth_core.scenario import load_scenario
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion
from stealth_env.markers import (
    KINDS,
    MOTION_PATROL,
    MOTION_STATIC,
    MOTION_SWEEP,
    MarkerSpec,
    WallMap,
    cone_mesh,
    detection_distance,
    intensity_colour,
    ray_reach,
    ring_radii,
    scene_markers,
    searchlight_fields,
    visibility_levels,
)

MSG_DIR = Path(__file__).resolve().parents[2] / 'stealth_interfaces' / 'msg'
RESOLUTION = 0.05


def msg_fields(name: str) -> list[str]:
    names = []
    for line in (MSG_DIR / f'{name}.msg').read_text().splitlines():
        words = line.split('#', 1)[0].split()
        if len(words) == 2 and '=' not in words[1] and words[1] != 'header':
            names.append(words[1])
    return names


def room(wall_x: float | None = 3.0, size=(100, 120)) -> WallMap:
    """An open 6 x 5 m map at 0.05 m (origin 0, 0), with a wall across at x = wall_x."""
    blocked = np.zeros(size, dtype=bool)
    if wall_x is not None:
        blocked[:, int(wall_x / RESOLUTION)] = True
    return WallMap(blocked, RESOLUTION, 0.0, 0.0)


@pytest.fixture(scope='module')
def map1():
    return load_scenario('map1')


def test_intensity_colours_run_from_pale_yellow_to_dark_red_and_more_opaque():
    dark, bright = intensity_colour(0.0), intensity_colour(1.0)
    assert dark == pytest.approx((1.0, 1.0, 0.8, 0.3))
    assert bright == pytest.approx((0.502, 0.0, 0.149, 0.8))
    assert intensity_colour(-1.0) == dark and intensity_colour(7.0) == bright
    greens = [intensity_colour(v)[1] for v in np.linspace(0, 1, 11)]
    assert greens == sorted(greens, reverse=True)


def test_rays_stop_at_the_first_wall_and_at_the_map_edge():
    walls = room(wall_x=3.0)  # wall cells x in [3.0, 3.05)
    east, west, north = ray_reach(walls, 1.0, 2.5, [0.0, math.pi, math.pi / 2], 10.0)
    assert 2.0 <= east <= 2.0 + RESOLUTION  # into the wall by at most half a cell
    assert west == pytest.approx(1.0, abs=RESOLUTION)  # the map's edge
    assert north == pytest.approx(2.5, abs=RESOLUTION)
    assert ray_reach(walls, 1.0, 2.5, [0.0], 1.5)[0] == 1.5  # short of the wall: the range


def test_a_lamp_in_a_wall_shines_out_of_it():
    walls = room(wall_x=3.0)
    # The lamp's own cell is ignored; the next wall cell is not.
    assert ray_reach(walls, 3.02, 2.5, [0.0], 2.0)[0] == 2.0
    thick = room(wall_x=None)
    thick.blocked[:, 60:62] = True  # x in [3.0, 3.1)
    assert ray_reach(thick, 3.02, 2.5, [0.0], 2.0)[0] <= 0.1


def test_rings_are_evenly_spaced_in_intensity():
    light = Searchlight('a', 1.0, 1.0, 0.0, math.radians(50), 10.0, delta=0.1)
    radii = ring_radii(light)
    assert radii[0] == 0.0 and radii[-1] == 10.0
    levels = intensity(radii, light.beta)
    assert np.diff(levels) == pytest.approx(np.full(len(radii) - 1, (0.1 - 1.0) / 6))


def test_the_cone_is_filled_up_to_the_wall_and_coloured_by_intensity():
    walls = room(wall_x=3.0)
    light = Searchlight('a', 1.0, 2.5, 0.0, math.radians(60), 4.0)
    points, colors = cone_mesh(light, walls)
    assert len(points) % 3 == 0 and len(colors) == len(points) > 0
    xy = np.array(points)[:, :2]
    offsets = xy - (1.0, 2.5)
    distances = np.hypot(*offsets.T)
    assert distances.max() <= 4.0 + 1e-9
    angles = np.arctan2(offsets[:, 1], offsets[:, 0])
    assert np.all(np.abs(angles[distances > 1e-9]) <= math.radians(30) + 1e-9)
    assert xy[:, 0].max() <= 3.05  # never past the wall
    # The apex is the brightest vertex, every colour that of the intensity at its vertex.
    for point, colour in zip(points, colors, strict=True):
        d = math.hypot(point[0] - 1.0, point[1] - 2.5)
        assert colour == pytest.approx(intensity_colour(float(intensity(d, light.beta))))
    apex = [c for p, c in zip(points, colors, strict=True) if p[:2] == (1.0, 2.5)]
    assert apex and all(c == intensity_colour(1.0) for c in apex)


def test_a_soft_edge_darkens_the_rim():
    walls = room(wall_x=None)
    light = Searchlight('a', 1.0, 2.5, 0.0, math.radians(60), 2.0, soft_edge=1.0)
    points, colors = cone_mesh(light, walls)
    rim = [
        c
        for p, c in zip(points, colors, strict=True)
        if abs(abs(math.atan2(p[1] - 2.5, p[0] - 1.0)) - math.radians(30)) < 1e-6
    ]
    assert rim and all(c == pytest.approx(intensity_colour(0.0)) for c in rim)


def test_the_detection_arc_is_where_one_light_reaches_the_threshold():
    light = Searchlight('a', 1.0, 1.0, 0.0, 1.0, 10.0, delta=0.1)
    distance = detection_distance(light, 0.3)
    assert float(intensity(distance, light.beta)) == pytest.approx(0.3)
    assert detection_distance(light, 0.05) == 10.0  # the whole range
    assert detection_distance(light, 1.5) is None  # one light never reaches it


def test_the_scene_has_every_light_goal_and_the_start(map1):
    markers = scene_markers(map1, 'easy')
    assert all(isinstance(m, MarkerSpec) and m.kind in KINDS for m in markers)
    keys = [(m.namespace, m.id) for m in markers]
    assert len(keys) == len(set(keys)), 'namespace and id must be unique'
    by_namespace = {}
    for marker in markers:
        by_namespace.setdefault(marker.namespace, []).append(marker)
    lights = len(map1.lights)
    for namespace in ('cones', 'ranges', 'detection', 'lamps', 'names'):
        assert len(by_namespace[namespace]) == lights, namespace
    assert 'motion' not in by_namespace  # map1's lights stand still
    assert [m.text for m in by_namespace['names']] == [light.name for light in map1.lights]
    assert [m.text for m in by_namespace['labels']] == ['start', 'goal: easy', 'medium', 'hard']
    goals = by_namespace['goals']
    assert [m.color[3] for m in goals] == [0.7, 0.25, 0.25]
    assert goals[0].position[:2] == (15.0, 9.5) and goals[0].scale[:2] == (1.0, 1.0)
    assert by_namespace['start'][0].position[:2] == (2.5, 2.5)
    for cone in by_namespace['cones']:
        assert cone.kind == 'triangle_list' and len(cone.colors) == len(cone.points) > 0


def test_cone_vertices_in_the_open_are_lit_by_the_model(map1):
    """Display and model agree: the cone's outer vertices that are not at a wall are lit."""
    occupancy = map1.map
    light = map1.lights[0]
    points, _ = cone_mesh(light, WallMap.of(occupancy))
    far = {
        p[:2]
        for p in points
        if 0.5 < math.hypot(p[0] - light.x, p[1] - light.y) < light.range - 1e-6
    }
    lit = 0
    for x, y in far:
        lit += point_visibility(occupancy.blocked, occupancy.resolution, occupancy.origin,
                                [light], x, y) > 0  # fmt: skip
    assert lit >= 0.9 * len(far)


def test_moving_lights_are_drawn_where_they_are_at_the_time(map1):
    kitchen, study = map1.lights[:2]
    sweep = dataclasses.replace(
        kitchen, motion=SweepMotion(math.radians(150), math.radians(210), math.radians(10))
    )
    patrol = dataclasses.replace(study, motion=PatrolMotion(((13.0, 5.0),), 0.5))
    scenario = dataclasses.replace(map1, lights=(sweep, patrol))
    at_0, at_2 = scene_markers(scenario, 'hard', 0.0), scene_markers(scenario, 'hard', 2.0)

    def find(markers, namespace, index):
        return next(m for m in markers if (m.namespace, m.id) == (namespace, index))

    assert find(at_0, 'cones', 0).points != find(at_2, 'cones', 0).points
    assert find(at_2, 'lamps', 1).position[:2] == pytest.approx((13.0, 4.5))
    route = find(at_2, 'motion', 1).points
    assert [p[:2] for p in route] == [(13.0, 3.5), (13.0, 5.0), (13.0, 3.5)]
    assert len(find(at_2, 'motion', 0).points) > 3  # the sweep's whole sector


def test_searchlight_fields_follow_the_message(map1):
    static = searchlight_fields(map1.lights[0])
    assert list(static) == msg_fields('Searchlight')
    assert static['motion'] == MOTION_STATIC and static['waypoints'] == ()
    assert static['position'] == (13.0, 8.5) and static['direction'] == pytest.approx(math.pi)

    sweep = dataclasses.replace(map1.lights[0], motion=SweepMotion(2.6, 3.6, 0.1))
    fields = searchlight_fields(sweep, 1.0)
    assert fields['motion'] == MOTION_SWEEP
    assert (fields['sweep_min'], fields['sweep_max'], fields['angular_speed']) == (2.6, 3.6, 0.1)
    assert fields['direction'] == pytest.approx(math.pi + 0.1)

    patrol = dataclasses.replace(
        map1.lights[1], motion=PatrolMotion(((13.0, 3.5), (13.0, 5.0)), 0.5)
    )
    fields = searchlight_fields(patrol, 1.0)
    assert fields['motion'] == MOTION_PATROL and fields['linear_speed'] == 0.5
    assert fields['waypoints'] == ((13.0, 3.5), (13.0, 5.0))  # no repeat of the start
    assert fields['position'] == pytest.approx((13.0, 4.0))


# --- the visibility grid ----------------------------------------------------------------------


def test_visibility_levels_scale_to_the_detection_threshold_and_cap_at_100():
    total = np.array([[0.0, 0.03, 0.15], [0.2999, 0.3, 2.0]])
    levels = visibility_levels(total, 0.3)
    assert levels.dtype == np.int8
    assert levels.tolist() == [[0, 10, 50], [100, 100, 100]]


def test_visibility_levels_of_a_scenario_match_the_model_at_cell_centres():
    from stealth_core.visibility_cache import scenario_visibility

    scenario = load_scenario('simple-maze')
    total, _ = scenario_visibility(scenario)
    levels = visibility_levels(total, scenario.detection_threshold)
    assert levels.shape == (scenario.map.height, scenario.map.width)
    assert levels.min() == 0 and levels.max() == 100  # dark cells, and cells where one is seen
    lit = np.argwhere(total > 0)
    row, col = lit[len(lit) // 2]
    res, (x0, y0, _) = scenario.map.resolution, scenario.map.origin
    x, y = x0 + (col + 0.5) * res, y0 + (row + 0.5) * res  # row 0 is the bottom row
    expected = point_visibility(
        scenario.map.blocked, res, scenario.map.origin, scenario.lights, x, y
    )
    assert levels[row, col] == min(100, round(expected / scenario.detection_threshold * 100))


@pytest.mark.parametrize('threshold', [0.0, -1.0, math.nan])
def test_visibility_levels_refuse_a_threshold_that_is_not_positive(threshold):
    with pytest.raises(ValueError, match='detection threshold'):
        visibility_levels(np.zeros((2, 2)), threshold)


def test_visibility_levels_refuse_a_field_that_is_not_finite():
    with pytest.raises(ValueError, match='finite'):
        visibility_levels(np.array([[0.0, math.inf]]), 0.3)
