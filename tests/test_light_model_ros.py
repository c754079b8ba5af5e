"""`stealth train --learner light-model` through ROS: the agent learns on the scenario without
its lights (its world file), publishes its belief as OccupancyGrids the recording holds, and the
run draws it beside the true field; where lights move it is told their timing only."""

import csv
import json

from stealth_core.scenario import load_scenario
from test_system import read_bag
from test_system import system as system  # noqa: F401, PLC0414 - the fixture, used by name
import yaml

BELIEF_TOPICS = ('/agent/light_belief', '/agent/light_belief_uncertain')


def test_light_model_trains_through_ros_without_being_told_the_lights(system):
    result = system.run(
        'train', '--scenario', 'simple-maze', '--learner', 'light-model', '--episodes', '4',
        '--eval-every', '2', '--success-streak', '0', '--seed', '1', '--name', 'lm',
        '--runs-dir', str(system.runs),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr + result.stdout
    assert 'Traceback' not in result.stderr
    run = system.runs / 'lm'
    rows = list(csv.DictReader((run / 'episodes.csv').open()))
    assert [int(row['episode']) for row in rows] == [0, 1, 2, 3]
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['policy']['learner'] == 'light-model'

    # The agent's parameters and its world file hold no light (the lights' SHA-256 only).
    agent = yaml.safe_load((run / 'params' / 'agent.yaml').read_text())['agent']['ros__parameters']
    assert agent['agent'] == 'light-model'
    world_text = (run / 'world.yaml').read_text()
    assert agent['world_file'] == str((run / 'world.yaml').resolve())
    assert load_scenario(run / 'world.yaml').lights == ()
    told = yaml.safe_dump(agent) + world_text
    for light in load_scenario('simple-maze').lights:
        assert light.name not in told
        assert f'x: {light.x}' not in world_text

    # The belief is in the recording, on the map's frame, after each learning episode.
    _, messages, types = read_bag(run / 'recording.mcap')
    occupancy = load_scenario('simple-maze').map
    for topic in BELIEF_TOPICS:
        assert types[topic] == 'nav_msgs/msg/OccupancyGrid', sorted(types)
        assert 1 <= len(messages[topic]) <= 3, len(messages[topic])  # 2 learning episodes (+ 1)
        grid = messages[topic][-1]
        assert grid.header.frame_id == 'map'
        assert grid.info.resolution == occupancy.resolution * 5
        assert (grid.info.width, grid.info.height) == (occupancy.width // 5, occupancy.height // 5)
        values = set(grid.data)
        assert -1 in values and values <= set(range(-1, 101))
    assert (run / 'light_belief.png').stat().st_size > 10_000
    assert 'light_belief.png' in result.stdout


def test_light_model_trains_on_moving_lights_told_only_their_timing(system):
    """simple-maze-moving: the agent's world has the phase's meaning (phase bins, cycle, step)
    and the wait action, never the sweeping light; its belief holds moving lights."""
    result = system.run(
        'train', '--scenario', 'simple-maze-moving', '--learner', 'light-model',
        '--episodes', '2', '--eval-every', '2', '--success-streak', '0', '--seed', '1',
        '--name', 'lmm', '--runs-dir', str(system.runs),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr + result.stdout
    assert 'Traceback' not in result.stderr
    run = system.runs / 'lmm'
    rows = list(csv.DictReader((run / 'episodes.csv').open()))
    assert [int(row['episode']) for row in rows] == [0, 1]
    world = yaml.safe_load((run / 'world.yaml').read_text())
    assert world['lights'] == [] and world['cycle_seconds'] == 24.0 and world['phase_bins'] == 8
    assert 'goal-guard' not in (run / 'world.yaml').read_text()
    _, messages, _ = read_bag(run / 'recording.mcap')
    assert messages['/agent/light_belief'], 'no belief was published'
