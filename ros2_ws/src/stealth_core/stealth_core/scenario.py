"""Scenarios: a map, a start, goals by difficulty, searchlights and the task's numbers.

A scenario is one YAML file (``scenarios/<name>.yaml``), validated completely on load: every
problem is one :class:`ScenarioError` naming the file, the field and what was expected, and no
Scenario is built until everything checked out. Angles are degrees in the file (counter-clockwise
from +x) and radians in the :class:`Scenario`. Example, every field::

    name: map1                      # default: the file's stem
    map: ../maps/map1.yaml          # nav2 map YAML, relative to this file
    start: {x: 2.5, y: 2.5, yaw: 90}
    goals:                          # any of easy, medium, hard; radius defaults to goal_radius
      easy: {x: 15.0, y: 9.5}
      hard: {x: 18.0, y: 14.5, radius: 0.5}
    default_goal: hard              # default: the hardest goal given
    robot_radius: 0.2               # m
    step_distance: 0.5              # m per move (up, down, left, right)
    state_cell: 0.5                 # m, the agent's state grid; default: step_distance
    goal_radius: 0.5                # m
    detection_threshold: 0.3        # total visibility at which the robot is seen
    detection_mode: threshold       # or probabilistic
    step_limit: 300                 # moves per episode
    phase_bins: 8                   # moving lights only: bins of the lights' joint cycle, the
                                    # phase is then a state feature (stealth_core.light_cycle)
    step_seconds: 3.0               # moving lights only: simulated s per move or wait, a whole
                                    # number of bins (default: one bin)
    lights:
      - name: kitchen               # default: L<number>
        x: 13.0
        y: 8.5
        direction: 180              # degrees
        fov: 40                     # full opening angle, degrees, in (0, 360]
        range: 6.0                  # m
        delta: 0.1                  # intensity at the range, in (0, 1)
        soft_edge: 0.0              # optional, in [0, 1]
        motion: {type: sweep, min_direction: 150, max_direction: 210, angular_speed: 10}
        # or {type: patrol, waypoints: [[13, 8.5], [13, 10]], speed: 0.3}
    rewards: {goal_reward: 1000.0}  # any RewardWeights field; the rest keep their defaults
    exposure:                       # optional: each light weighed by how much of the robot it
      length: 0.6                   # sees (stealth_core.exposure); footprint in m, > 0, default
      width: 0.3                    # 2 * robot_radius (the simulator's robot is a disc)
      turn_actions: true            # add turn left / turn right in place (default false)
    bounce: {albedo: 0.3, range: 3.0}  # one-bounce light off the walls (stealth_core.bounce):
                                    # albedo in [0, 1) (default 0: none), range m (default 3);
                                    # static lights only
    sensing_range: 8.0              # m, how far the robot that does not know the lights senses
                                    # them (stealth_core.sensing), > 0 and at most the map's
                                    # diagonal; default 8 (or the diagonal, if shorter)

Validation checks the fields' types and ranges, that the start and goals lie in free cells of
the map, that the start has ``robot_radius`` of clearance, that every goal is reachable from the
start on the robot's move lattice (:mod:`stealth_core.move_lattice`) and that every light and
patrol waypoint lies inside the map, that every light stands in a free cell (a lamp in a wall
cell, which ``stealth_core.lighting`` would accept, lights at most the far side of the wall: put
there by mistake, it would light nothing without a word; patrol waypoints may still cross
walls), and that moving lights' periods and the step fit the phase bins
(:mod:`stealth_core.light_cycle`), and that an ``exposure`` footprint has a length and a width
> 0 (m) (:mod:`stealth_core.exposure`). A scenario whose lights move without ``phase_bins``
loads with a warning: the state does not say where the lights are, so the task is not Markov.
Whether the goals can be reached unseen is a property of the shipped scenarios, proved
by their tests, not a load-time check.
"""

import dataclasses
import hashlib
import json
import math
import os
from pathlib import Path
from typing import Any, NamedTuple
import warnings

from stealth_core.bounce import DEFAULT_RANGE, Bounce, bounce_bound
from stealth_core.exposure import Footprint, valid_length
from stealth_core.light_cycle import Timing, TimingError, check_timing
from stealth_core.move_lattice import MoveLattice
from stealth_core.occupancy_map import MapError, OccupancyMap, load_map
from stealth_core.reward import (
    DETECTION_MODES,
    RewardError,
    RewardWeights,
    check_well_posed,
    undetected_visibility_bound,
)
from stealth_core.scenario_fields import (
    POSITIVE,
    ScenarioError,
    point_in_free_space,
    read_lights,
)
from stealth_core.searchlight import Searchlight
from stealth_core.yaml_fields import FieldReader, read_yaml_mapping

DIFFICULTIES = ('easy', 'medium', 'hard')
SCENARIOS_ENV = 'STEALTH_NAV_SCENARIOS'
FIELDS = (
    'name',
    'map',
    'start',
    'goals',
    'default_goal',
    'robot_radius',
    'step_distance',
    'state_cell',
    'goal_radius',
    'detection_threshold',
    'detection_mode',
    'step_limit',
    'phase_bins',
    'step_seconds',
    'lights',
    'rewards',
    'exposure',
    'bounce',
    'sensing_range',
)
DEFAULT_SENSING_RANGE = 8.0  # m: the sensed track's camera (stealth_core.sensing)


class Goal(NamedTuple):
    """A goal point (m, map frame) and the distance within which it counts as reached."""

    name: str
    x: float
    y: float
    radius: float

    @property
    def point(self) -> tuple[float, float]:
        return (self.x, self.y)


@dataclasses.dataclass(frozen=True, eq=False)
class Scenario:
    """One validated scenario; lengths in metres, angles in radians."""

    name: str
    path: Path
    map_path: Path
    map: OccupancyMap
    start: tuple[float, float, float]  # x, y, yaw
    goals: dict[str, Goal]  # easy / medium / hard, in that order
    default_goal: str
    lights: tuple[Searchlight, ...]
    robot_radius: float
    step_distance: float
    state_cell: float
    goal_radius: float
    detection_threshold: float
    detection_mode: str
    step_limit: int
    rewards: RewardWeights
    timing: Timing | None = None  # moving lights with phase_bins: the phase state feature
    exposure: Footprint | None = None  # exposure by orientation: the heading state feature
    bounce: Bounce | None = None  # one-bounce light; None: direct light only (albedo 0)
    sensing_range: float = DEFAULT_SENSING_RANGE  # m, the sensed track's (stealth_core.sensing)

    @property
    def has_moving_lights(self) -> bool:
        return any(light.is_moving for light in self.lights)

    @property
    def goal(self) -> Goal:
        """The goal pursued unless another is asked for."""
        return self.goals[self.default_goal]


def content_identity(scenario: Scenario) -> dict[str, str]:
    """What a policy is learned on, by content, not by name (a scenario file may keep its name
    and get another map or other lights): SHA-256 of the occupancy grid (cells, resolution,
    origin) and of the lights (every field, motions included)."""
    grid = scenario.map
    shape = json.dumps([list(grid.data.shape), grid.resolution, list(grid.origin)])
    lights = json.dumps(
        [[type(light.motion).__name__, dataclasses.asdict(light)] for light in scenario.lights],
        sort_keys=True,
    )
    return {
        'grid_sha256': hashlib.sha256(shape.encode() + grid.data.tobytes()).hexdigest(),
        'lights_sha256': hashlib.sha256(lights.encode()).hexdigest(),
    }


# --- finding scenarios --------------------------------------------------------------------------


def scenario_search_path() -> list[Path]:
    """Where bare scenario names are looked up: $STEALTH_NAV_SCENARIOS (a ':'-separated list),
    then the repository's scenarios/ directory, or where this package was installed with pip
    (no repository beside it), the copy of the shipped scenarios its wheel holds."""
    extra = [Path(p) for p in os.environ.get(SCENARIOS_ENV, '').split(os.pathsep) if p]
    here = Path(__file__).resolve()
    repository = here.parents[4] / 'scenarios' if len(here.parents) > 4 else None
    shipped = repository if repository is not None and repository.is_dir() else None
    return [*extra, shipped or here.parent / 'data' / 'scenarios']


def scenario_paths() -> list[Path]:
    """Every scenario file on the search path, one per name (earlier directories win)."""
    found: dict[str, Path] = {}
    for directory in scenario_search_path():
        for path in sorted(directory.glob('*.yaml')):
            found.setdefault(path.stem, path)
    return sorted(found.values(), key=lambda p: p.stem)


def find_scenario(name_or_path: str | os.PathLike) -> Path:
    """A scenario file from a path, or from a bare name such as ``lgfloor``."""
    candidate = Path(name_or_path)
    if candidate.suffix in ('.yaml', '.yml') or candidate.exists() or len(candidate.parts) > 1:
        return candidate
    for directory in scenario_search_path():
        path = directory / f'{candidate}.yaml'
        if path.is_file():
            return path
    names = ', '.join(p.stem for p in scenario_paths()) or 'none'
    raise ScenarioError(f'scenario {str(name_or_path)!r}: not found (known scenarios: {names})')


# --- loading ------------------------------------------------------------------------------------


def load_scenario(name_or_path: str | os.PathLike) -> Scenario:
    """Load and validate a scenario by name or path; ScenarioError on any problem."""
    path = find_scenario(name_or_path)
    return scenario_from_fields(path, read_yaml_mapping(path, ScenarioError, 'scenario'))


def scenario_from_fields(path: Path, values: dict) -> Scenario:
    """``load_scenario`` of the file at ``path`` whose YAML reads as ``values`` (its map is
    read from disk, relative to path): for a caller that holds the mapping already, such as
    the generator proving the scenario it writes without parsing the text back."""
    fields = FieldReader(path, values, ScenarioError)
    fields.reject_unknown(FIELDS)
    name = fields.string('name', 'a non-empty string', default=path.stem)
    map_path, occupancy = _load_map(fields, path)
    numbers = _task_numbers(fields)
    start_fields = fields.mapping('start', 'a mapping {x, y, yaw} (m, m, degrees)')
    start_fields.reject_unknown(('x', 'y', 'yaw'))
    start = (
        *point_in_free_space(start_fields, occupancy),
        math.radians(start_fields.number('yaw', 'an angle in degrees', default=0.0)),
    )
    lattice = MoveLattice(occupancy, start[:2], numbers['step_distance'], numbers['robot_radius'])
    if not lattice.is_valid((0, 0)):
        fields.fail(
            'start',
            f'a pose with robot_radius {numbers["robot_radius"]:g} m of clearance from walls, '
            'unknown space and the map edge',
            list(start[:2]),
        )
    goals = _goals(fields, occupancy, lattice, numbers)
    default_goal = fields.string('default_goal', f'one of {", ".join(goals)}', list(goals)[-1])
    if default_goal not in goals:
        fields.fail('default_goal', f'one of the goals given ({", ".join(goals)})', default_goal)
    lights = read_lights(fields, occupancy)
    timing = _timing(fields, lights, path)
    bounce = _bounce(fields, lights)
    if bounce is not None and fields.has('exposure'):
        fields.fail_with(
            'bounce',
            'no bounce together with exposure (the bounced light comes from many walls, and '
            'exposure weighs one direction per light; remove one of the two)',
            'an exposure field too',
        )
    rewards = _rewards(fields, occupancy, numbers, len(lights), bounce)
    scenario = Scenario(
        name=name,
        path=path,
        map_path=map_path,
        map=occupancy,
        start=start,
        goals=goals,
        default_goal=default_goal,
        lights=lights,
        rewards=rewards,
        timing=timing,
        exposure=_exposure(fields, numbers['robot_radius']),
        bounce=bounce,
        sensing_range=_sensing_range(fields, occupancy),
        **numbers,
    )
    lattice.share_with(scenario)  # its tasks need not build it again
    return scenario


def _exposure(fields: FieldReader, robot_radius: float) -> Footprint | None:
    """The robot's footprint where lights are weighed by exposure (stealth_core.exposure)."""
    if not fields.has('exposure'):
        return None
    expected = 'a mapping {length, width (m), turn_actions (true or false)}'
    exposure = fields.mapping('exposure', expected)
    exposure.reject_unknown(('length', 'width', 'turn_actions'))
    size = {}
    for key in ('length', 'width'):
        size[key] = exposure.raw(key, 'a number > 0 (m)', 2.0 * robot_radius)
        if not valid_length(size[key]):
            default = '' if exposure.has(key) else ' (the default, 2 * robot_radius)'
            exposure.fail(key, f'a number > 0 (m){default}', size[key])
    turns = exposure.raw('turn_actions', 'true or false', False)
    if not isinstance(turns, bool):
        exposure.fail('turn_actions', 'true or false', turns)
    return Footprint(float(size['length']), float(size['width']), turns)


class NotMarkovWarning(UserWarning):
    """Moving lights without the phase in the state: the same state is safe or deadly
    depending on the time."""


def _timing(fields: FieldReader, lights, path: Path) -> Timing | None:
    moving = [light.name for light in lights if light.is_moving]
    if not fields.has('phase_bins'):
        if fields.has('step_seconds'):
            fields.fail('step_seconds', 'no step_seconds without phase_bins', 'a value')
        if moving:
            warnings.warn(
                f'{path}: lights {", ".join(moving)} move but the scenario has no phase_bins: '
                'the state is the position only, so the task is not Markov (the same cell is '
                'safe or seen depending on the time); add phase_bins',
                NotMarkovWarning,
                stacklevel=3,
            )
        return None
    bins = fields.integer('phase_bins', 'an integer >= 1', lambda v: v >= 1)
    step = None
    if fields.has('step_seconds'):
        step = fields.number('step_seconds', f'{POSITIVE} (s)', lambda v: v > 0)
    try:
        timing = check_timing(lights, bins, step)
    except TimingError as error:
        raise ScenarioError(f'{path}: {error}') from None
    if timing is None:
        fields.fail('phase_bins', 'phase_bins only in a scenario whose lights move', bins)
    return timing


def _bounce(fields: FieldReader, lights) -> Bounce | None:
    """The one-bounce light, or None when there is none (no field, or albedo 0)."""
    if not fields.has('bounce'):
        return None
    bounce = fields.mapping('bounce', 'a mapping {albedo, range}')
    bounce.reject_unknown(('albedo', 'range'))
    albedo = bounce.number('albedo', 'a number in [0, 1)', lambda v: 0 <= v < 1)
    reach = bounce.number('range', f'{POSITIVE} (m)', lambda v: v > 0, DEFAULT_RANGE)
    if albedo == 0.0:
        return None
    moving = [f'lights[{i}] ({light.name})' for i, light in enumerate(lights) if light.is_moving]
    if moving:
        fields.fail_with(
            'bounce',
            'no bounce in a scenario whose lights move (the bounce is computed for static '
            'lights only; remove bounce or the motion)',
            f'{", ".join(moving)} moving',
        )
    return Bounce(albedo, reach)


def _sensing_range(fields: FieldReader, occupancy: OccupancyMap) -> float:
    """How far the robot senses the lights on the sensed track: > 0, at most the diagonal."""
    x_min, y_min, x_max, y_max = occupancy.bounds
    diagonal = math.hypot(x_max - x_min, y_max - y_min)
    expected = f"a number > 0 (m) and at most the map's diagonal, {diagonal:g} m"
    return fields.number(
        'sensing_range',
        expected,
        lambda v: 0 < v <= diagonal,
        min(DEFAULT_SENSING_RANGE, diagonal),
    )


def _load_map(fields: FieldReader, path: Path) -> tuple[Path, OccupancyMap]:
    relative = fields.string('map', 'the path of a nav2 map YAML, relative to this file')
    map_path = path.parent / Path(relative).expanduser()
    try:
        return map_path, load_map(map_path)
    except MapError as error:
        raise ScenarioError(f'{fields.where("map")}: {error}') from None


def _task_numbers(fields: FieldReader) -> dict[str, Any]:
    step = fields.number('step_distance', f'{POSITIVE} (m)', lambda v: v > 0)
    mode = fields.string('detection_mode', f'one of {", ".join(DETECTION_MODES)}', 'threshold')
    if mode not in DETECTION_MODES:
        fields.fail('detection_mode', f'one of {", ".join(DETECTION_MODES)}', mode)
    return {
        'robot_radius': fields.number('robot_radius', 'a number >= 0 (m)', lambda v: v >= 0, 0.2),
        'step_distance': step,
        'state_cell': fields.number('state_cell', f'{POSITIVE} (m)', lambda v: v > 0, step),
        'goal_radius': fields.number('goal_radius', f'{POSITIVE} (m)', lambda v: v > 0),
        'detection_threshold': fields.number('detection_threshold', POSITIVE, lambda v: v > 0),
        'detection_mode': mode,
        'step_limit': fields.integer('step_limit', 'an integer >= 1', lambda v: v >= 1),
    }


def _goals(fields, occupancy, lattice: MoveLattice, numbers) -> dict[str, Goal]:
    expected = f'a mapping of goals by difficulty ({", ".join(DIFFICULTIES)})'
    goal_fields = fields.mapping('goals', expected)
    goal_fields.reject_unknown(DIFFICULTIES)
    if not goal_fields.values:
        fields.fail('goals', expected, {})
    goals = {}
    reachable = None  # the lattice nodes reachable from the start, found once when needed
    for difficulty in (d for d in DIFFICULTIES if goal_fields.has(d)):
        one = goal_fields.mapping(difficulty, 'a mapping {x, y} (m), optionally radius (m)')
        one.reject_unknown(('x', 'y', 'radius'))
        x, y = point_in_free_space(one, occupancy)
        radius = one.number('radius', f'{POSITIVE} (m)', lambda v: v > 0, numbers['goal_radius'])
        targets = lattice.nodes_within(x, y, radius)
        if reachable is None:
            reachable = lattice.reachable((0, 0))
        if not any(reachable[i - lattice.i_min, j - lattice.j_min] for i, j in targets):
            where = f"{fields.source}: field 'goals.{difficulty}'"
            raise ScenarioError(
                f'{where}: expected a goal reachable from the start by moves of '
                f'{numbers["step_distance"]:g} m up, down, left and right with robot_radius '
                f'{numbers["robot_radius"]:g} m, got ({x:g}, {y:g}): no lattice node within '
                f'{radius:g} m of it can be reached'
            )
        goals[difficulty] = Goal(difficulty, x, y, radius)
    return goals


def _rewards(fields: FieldReader, occupancy, numbers, n_lights: int, bounce) -> RewardWeights:
    """The weights, checked to make getting caught never pay (reward.check_well_posed)."""
    known = tuple(f.name for f in dataclasses.fields(RewardWeights))
    rewards = fields.mapping('rewards', 'a mapping of reward weights', default={})
    rewards.reject_unknown(known)
    given = {key: rewards.number(key, 'a number >= 0', lambda v: v >= 0) for key in rewards.values}
    x_min, y_min, x_max, y_max = occupancy.bounds
    try:
        weights = RewardWeights(**given)
        check_well_posed(
            weights,
            max_distance=math.hypot(x_max - x_min, y_max - y_min),
            max_visibility=undetected_visibility_bound(
                numbers['detection_mode'],
                numbers['detection_threshold'],
                n_lights,
                bounce_bound(bounce, occupancy.resolution, n_lights),
            ),
            max_steps=numbers['step_limit'],
        )
    except RewardError as error:
        raise ScenarioError(f'{fields.where("rewards")}: {error}') from None
    return weights
