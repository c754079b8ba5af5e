"""The scene from a scenario file and from the map and lights messages (plain pytest)."""

import math

from nav_msgs.msg import OccupancyGrid
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from stealth_core.occupancy_map import to_occupancy_grid_data
from stealth_core.scenario import content_identity, load_scenario
from stealth_env.env_messages import searchlight_array_msg
from stealth_nav2.scene_source import (
    SceneError,
    SceneMissingError,
    SceneSource,
    lights_from_message,
    map_from_message,
    scene_from_messages,
    scene_from_scenario,
)
from stealth_node_kit.conversions import yaw_quaternion


def grid_message(occupancy, frame='map', yaw=0.0) -> OccupancyGrid:
    grid = OccupancyGrid()
    grid.header.frame_id = frame
    grid.info.width, grid.info.height = occupancy.width, occupancy.height
    grid.info.resolution = occupancy.resolution
    grid.info.origin.position.x, grid.info.origin.position.y = occupancy.origin[:2]
    grid.info.origin.orientation = yaw_quaternion(yaw)
    grid.data = to_occupancy_grid_data(occupancy)
    return grid


def test_scenario_scene_is_the_scenario():
    scene = scene_from_scenario('lgfloor')
    scenario = load_scenario('lgfloor')
    assert scene.identity() == content_identity(scenario)
    assert scene.lights == scenario.lights
    assert scene.blocked.shape == scenario.map.data.shape
    assert scene.scenario.name == 'lgfloor' and scene.frame_id == 'map'


def test_a_missing_scenario_is_one_line():
    with pytest.raises(SceneError) as caught:
        scene_from_scenario('/nonexistent/nowhere.yaml')
    assert 'nowhere.yaml' in str(caught.value) and '\n' not in str(caught.value)


@pytest.mark.parametrize('name', ['lgfloor', 'lgfloor-moving', 'simple-maze-moving'])
@pytest.mark.parametrize('stamp', [0.0, 2.5, 7.0, 13.0, 31.5])
def test_lights_messages_rebuild_the_lights(name, stamp):
    """A SearchlightArray at any stamp gives back the scenario's lights at t = 0: the same
    lights at every later time (sweeps turning either way at the stamp, patrols mid-route)."""
    scenario = load_scenario(name)
    lights, frame = lights_from_message(searchlight_array_msg(scenario.lights, stamp))
    assert frame == 'map'
    for rebuilt, light in zip(lights, scenario.lights, strict=True):
        for t in (0.0, 1.0, 5.0, stamp, stamp + 4.0):
            mine, theirs = rebuilt.at(t), light.at(t)
            assert math.isclose(mine.x, theirs.x, abs_tol=1e-9)
            assert math.isclose(mine.y, theirs.y, abs_tol=1e-9)
            assert math.isclose(mine.direction, theirs.direction, abs_tol=1e-9)


def test_map_message_gives_the_map():
    occupancy = load_scenario('simple-maze').map
    rebuilt, frame = map_from_message(grid_message(occupancy))
    assert frame == 'map'
    assert np.array_equal(rebuilt.data, occupancy.data)
    assert rebuilt.resolution == occupancy.resolution and rebuilt.origin == occupancy.origin


def test_map_message_keeps_the_resolution_the_float32_meant():
    """0.05 m travels as a float32 (0.05000000075): the scene must use 0.05, the scenario's."""
    occupancy = load_scenario('simple-maze').map
    wire = deserialize_message(serialize_message(grid_message(occupancy)), OccupancyGrid)
    assert wire.info.resolution != occupancy.resolution  # what arrives is the float32
    rebuilt, _ = map_from_message(wire)
    assert rebuilt.resolution == occupancy.resolution


def test_a_rotated_map_is_refused_by_field():
    occupancy = load_scenario('simple-maze').map
    with pytest.raises(SceneError, match="field 'info.origin.orientation'"):
        map_from_message(grid_message(occupancy, yaw=0.5))


def test_a_short_map_message_is_refused():
    grid = grid_message(load_scenario('simple-maze').map)
    grid.data = grid.data[:-1]
    with pytest.raises(SceneError, match="field 'data'"):
        map_from_message(grid)


def test_lights_in_another_frame_are_refused():
    scenario = load_scenario('simple-maze')
    lights = searchlight_array_msg(scenario.lights, 0.0)
    lights.header.frame_id = 'odom'
    with pytest.raises(SceneError, match="expected the map's frame 'map', got 'odom'"):
        scene_from_messages(grid_message(scenario.map), lights)


def test_a_bad_light_is_named():
    lights = searchlight_array_msg(load_scenario('simple-maze').lights, 0.0)
    lights.lights[1].field_of_view = 0.0
    with pytest.raises(SceneError, match=r'lights\[1\].*fov'):
        lights_from_message(lights)


def test_source_names_what_is_missing_then_gives_the_scene():
    scenario = load_scenario('simple-maze')
    source = SceneSource(map_topic='/map', lights_topic='searchlights')
    with pytest.raises(SceneMissingError) as caught:
        source.current()
    assert caught.value.missing == ('map', 'lights')
    assert '/map' in str(caught.value) and 'searchlights' in str(caught.value)
    source.update_map(grid_message(scenario.map))
    with pytest.raises(SceneMissingError) as caught:
        source.current()
    assert caught.value.missing == ('lights',)
    source.update_lights(searchlight_array_msg(scenario.lights, 0.0))
    scene = source.current()
    assert scene.identity() == content_identity(scenario)
    source.update_lights(searchlight_array_msg(scenario.lights, 0.0))  # the same lights again
    assert source.current() is scene


def test_a_fixed_source_ignores_nothing_missing():
    scene = scene_from_scenario('simple-maze')
    assert SceneSource(scene).current() is scene


def test_moving_lights_at_later_stamps_keep_the_scene():
    """The environment republishes moving lights at every stamp: the same lights at t = 0, so
    the same scene (nothing to rebuild, the planner's cache holds)."""
    scenario = load_scenario('lgfloor-moving')
    source = SceneSource()
    source.update_map(grid_message(scenario.map))
    source.update_lights(searchlight_array_msg(scenario.lights, 0.0))
    scene = source.current()
    for stamp in (3.0, 7.7, 31.5, 1234.25):
        source.update_lights(searchlight_array_msg(scenario.lights, stamp))
        assert source.current() is scene
