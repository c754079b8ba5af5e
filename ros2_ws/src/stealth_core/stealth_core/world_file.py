"""The world file: a scenario as the light model may know it, written for the agent node. No
rclpy.

Through ROS the agent node must never receive the lights. A ``stealth train --learner
light-model`` run writes the scenario's own fields with ``lights: []``, the map's absolute path
and the run's goal as ``default_goal`` into the run directory (``world.yaml``), and the agent
reads that file (parameter ``world_file``) into a ``LightWorld``. A file that still holds lights
is refused, so handing the agent the scenario itself is an error, not a leak.

Where lights move, the phase the agent's states carry needs its meaning: the file keeps
``phase_bins`` and ``step_seconds`` and adds ``cycle_seconds`` (the lights' joint cycle, which a
robot reads off how its phase advances, not off the lights). A scenario file refuses
``phase_bins`` without moving lights, so these three are read here, beside the scenario.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import yaml

from stealth_core.light_cycle import TimingError, timing_of
from stealth_core.light_world import LightWorld, check_modelled
from stealth_core.scenario import Scenario, ScenarioError, load_scenario, scenario_from_fields
from stealth_core.yaml_fields import read_yaml_mapping

WORLD_FILE = 'world.yaml'  # its name in a run directory
TIMING_FIELDS = ('phase_bins', 'step_seconds', 'cycle_seconds')  # read here, not by scenario
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
    if scenario.timing is not None:
        fields['cycle_seconds'] = scenario.timing.cycle
        fields['step_seconds'] = scenario.timing.step_seconds
    return fields


def write_world_file(scenario: Scenario, goal: str, path: Path) -> Path:
    """Write the world file of ``scenario`` and ``goal`` at ``path``, checked to load as a
    scenario (ScenarioError otherwise); OSError where it cannot be written."""
    fields = world_fields(scenario, goal)
    _world_scenario(Path(path), fields)  # what the agent will read must load
    text = HEADER.format(name=scenario.name, goal=goal) + yaml.safe_dump(fields, sort_keys=False)
    Path(path).write_text(text, encoding='utf-8')
    return Path(path)


def load_world(path: str | Path) -> LightWorld:
    """The LightWorld of a world file, for its ``default_goal``. WorldFileError (one line) for a
    file that cannot be read as a scenario or that holds lights; UnmodelledLawError for a
    scenario whose law the light model does not model."""
    try:
        path = Path(path)
        if not path.is_file():
            load_scenario(path)  # its own error: no such file
        scenario = _world_scenario(path, read_yaml_mapping(path, ScenarioError, 'scenario'))
    except (ScenarioError, OSError) as error:
        raise WorldFileError(f'world_file: {error}') from None
    if scenario.lights:
        raise WorldFileError(
            f'world_file {path}: it has {len(scenario.lights)} lights, which the agent must not '
            'be told; give it the scenario without them (lights: [], as stealth train writes '
            f'runs/<name>/{WORLD_FILE})'
        )
    return LightWorld(scenario, scenario.default_goal)


def _world_scenario(path: Path, fields: dict) -> Scenario:
    """The scenario of a world file's fields, its timing (``TIMING_FIELDS``) read here;
    ScenarioError naming the file and the field."""
    fields = dict(fields)
    if 'cycle_seconds' not in fields:
        return scenario_from_fields(path, fields)
    bins, step, cycle = (fields.pop(name, None) for name in TIMING_FIELDS)
    scenario = scenario_from_fields(path, fields)
    if (
        isinstance(cycle, bool)
        or not isinstance(cycle, int | float)
        or not (math.isfinite(cycle) and cycle > 0)
    ):
        raise ScenarioError(
            f"{path}: field 'cycle_seconds': expected a time > 0 (s), got {cycle!r}"
        )
    if scenario.lights:
        return scenario  # load_world refuses it, naming the lights
    try:
        timing = timing_of(float(cycle), bins, step)
    except TimingError as error:
        raise ScenarioError(f'{path}: {error}') from None
    return dataclasses.replace(scenario, timing=timing)
