"""The world file the light-model agent reads: the scenario without its lights (no ROS)."""

import dataclasses

import numpy as np
import pytest
from stealth_core.light_world import LightWorld, UnmodelledLawError
from stealth_core.scenario import load_scenario
from stealth_core.world_file import WorldFileError, load_world, write_world_file


@pytest.mark.parametrize('name, goal', [('simple-maze', 'easy'), ('map1-bounce', 'hard')])
def test_the_world_file_is_the_scenario_without_its_lights(tmp_path, monkeypatch, name, goal):
    scenario = load_scenario(name)
    path = write_world_file(scenario, goal, tmp_path / 'world.yaml')
    text = path.read_text()
    assert 'lights: []' in text
    for light in scenario.lights:  # not a name, not a place
        assert light.name not in text
    monkeypatch.chdir(tmp_path.parent)  # the map's path does not depend on where one stands
    world = load_world(path)
    assert world.scenario.lights == () and world.task.goal.name == goal
    known = LightWorld(scenario, goal)  # what the harness builds from the scenario itself
    assert np.array_equal(world.model.states, known.model.states)
    assert np.array_equal(world.model.successors, known.model.successors)
    assert world.task.description(False) == known.task.description(False)
    assert world.scenario.rewards == scenario.rewards
    assert (world.scenario.bounce is None) == (scenario.bounce is None)


def test_a_file_with_lights_is_refused_in_one_line():
    scenario = load_scenario('simple-maze')
    with pytest.raises(WorldFileError) as error:
        load_world(scenario.path)
    line = str(error.value)
    assert 'world_file' in line and '2 lights' in line and 'lights: []' in line
    assert '\n' not in line


def test_an_unreadable_world_file_is_one_line(tmp_path):
    with pytest.raises(WorldFileError) as missing:
        load_world(tmp_path / 'nowhere.yaml')
    (tmp_path / 'bad.yaml').write_text('name: [unclosed\n')
    with pytest.raises(WorldFileError) as bad:
        load_world(tmp_path / 'bad.yaml')
    for error, part in ((missing, 'nowhere.yaml'), (bad, 'bad.yaml')):
        line = str(error.value)
        assert line.startswith('world_file: ') and part in line and '\n' not in line


def test_a_moving_world_file_carries_the_phase_and_no_light(tmp_path):
    scenario = load_scenario('map1-moving')
    path = write_world_file(scenario, 'easy', tmp_path / 'world.yaml')
    text = path.read_text()
    assert 'lights: []' in text and 'cycle_seconds: 24.0' in text and 'kitchen' not in text
    world = load_world(path)
    assert world.scenario.lights == () and world.timing == scenario.timing
    known = LightWorld(scenario, 'easy')
    assert np.array_equal(world.model.states, known.model.states)
    assert np.array_equal(world.model.successors, known.model.successors)


@pytest.mark.parametrize(
    ('line', 'field'),
    [('cycle_seconds: -1', 'cycle_seconds'), ('step_seconds: 4.0', 'step_seconds')],
)
def test_a_world_file_with_timing_that_does_not_fit_is_one_line(tmp_path, line, field):
    scenario = load_scenario('map1-moving')
    path = write_world_file(scenario, 'easy', tmp_path / 'world.yaml')
    key = line.split(':')[0]
    kept = [row for row in path.read_text().splitlines() if not row.startswith(key + ':')]
    path.write_text('\n'.join([*kept, line]) + '\n')
    with pytest.raises(WorldFileError) as error:
        load_world(path)
    message = str(error.value)
    assert message.startswith('world_file: ') and field in message and '\n' not in message


def test_a_law_it_does_not_model_is_refused_before_any_file(tmp_path):
    scenario = dataclasses.replace(load_scenario('map1'), detection_mode='probabilistic')
    with pytest.raises(UnmodelledLawError) as error:
        write_world_file(scenario, scenario.default_goal, tmp_path / 'world.yaml')
    line = str(error.value)
    assert 'detection_mode' in line and 'light-model' in line and '\n' not in line
    assert not (tmp_path / 'world.yaml').exists()
