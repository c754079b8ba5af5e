"""The world file: a scenario as the light model may know it, written for the agent node. No
rclpy.

Through ROS the agent node must never receive the lights. A ``stealth train --learner
light-model`` run writes the scenario's own fields with ``lights: []``, the map's absolute path
and the run's goal as ``default_goal`` into the run directory (``world.yaml``), and the agent
reads that file (parameter ``world_file``) into a ``LightWorld``. A file that still holds lights
is refused, so handing the agent the scenario itself is an error, not a leak.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from stealth_core.light_world import LightWorld, check_modelled
from stealth_core.scenario import Scenario, ScenarioError, load_scenario, scenario_from_fields
from stealth_core.yaml_fields import read_yaml_mapping

WORLD_FILE = 'world.yaml'  # its name in a run directory
HEADER = (
    '# The world the light-model agent may know: {name} ({goal}) with every light removed\n'
    '# (stealth_core.world_file). Written by the run; the agent reads it (world_file).\n'
)


class WorldFileError(ValueError):
    """A world file the agent cannot use; one line naming the file and what to do."""


def world_fields(scenario: Scenario, goal: str) -> dict:
    """The scenario file's fields without its lights, the map's path absolute and ``goal`` the
    default. UnmodelledLawError for a scenario the light model cannot model."""
    check_modelled(scenario)
    fields = dict(read_yaml_mapping(scenario.path, ScenarioError, 'scenario'))
    fields['map'] = str(Path(scenario.map_path).resolve())
    fields['default_goal'] = goal
    fields['lights'] = []
    return fields


def write_world_file(scenario: Scenario, goal: str, path: Path) -> Path:
    """Write the world file of ``scenario`` and ``goal`` at ``path``, checked to load as a
    scenario (ScenarioError otherwise); OSError where it cannot be written."""
    fields = world_fields(scenario, goal)
    scenario_from_fields(Path(path), fields)  # what the agent will read must load
    text = HEADER.format(name=scenario.name, goal=goal) + yaml.safe_dump(fields, sort_keys=False)
    Path(path).write_text(text, encoding='utf-8')
    return Path(path)


def load_world(path: str | Path) -> LightWorld:
    """The LightWorld of a world file, for its ``default_goal``. WorldFileError (one line) for a
    file that cannot be read as a scenario or that holds lights; UnmodelledLawError for a
    scenario whose law the light model does not model."""
    try:
        scenario = load_scenario(Path(path))
    except (ScenarioError, OSError) as error:
        raise WorldFileError(f'world_file: {error}') from None
    if scenario.lights:
        raise WorldFileError(
            f'world_file {path}: it has {len(scenario.lights)} lights, which the agent must not '
            'be told; give it the scenario without them (lights: [], as stealth train writes '
            f'runs/<name>/{WORLD_FILE})'
        )
    return LightWorld(scenario, scenario.default_goal)
