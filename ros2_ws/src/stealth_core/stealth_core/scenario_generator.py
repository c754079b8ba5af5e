"""Generated scenarios: a building, guards' lights, a start and a goal, proven and written.

``generate(seed, options)`` lays out a building (``stealth_core.floor_plan``), starts the robot
in the hall, sets the goal in the room farthest from it (most doors away, then farthest in
metres), posts the lights (``stealth_core.guard_lights``) and writes the nav2 map (PGM + YAML,
``stealth_core.occupancy_map.save_map``) and the scenario YAML that ``load_scenario`` reads. The
scenario is read back as written (``scenario.scenario_from_fields``: the written map, and the
fields the text is written from, which is what YAML reads from it, so the text is not parsed
again) and *proven* on its move lattice
(``stealth_core.planners``): the value-iteration optimum reaches the goal unseen within the step
limit (a covert route exists), and the shortest route ignoring the lights (A*) is seen (the
scenario is not trivial), and the difficulty's measure holds (``DIFFICULTY_RULES``). Otherwise
the building and lights are drawn again, at most ``MAX_TRIES`` times; then GenerationError.

Decisions:

- **Determinism**: all randomness comes from one ``np.random.default_rng(seed)``; the files of
  a seed and options are the same byte for byte on every run (the YAML is written by hand with
  fixed number formats). ``GENERATOR_VERSION`` names that output: it is raised whenever a seed
  and options give other files, so a cache of generated scenarios that records it (`stealth
  benchmark`'s) knows its files are outdated (``test_fast_paths`` holds the files' digests).
- **Seeds** (``SEED_RANGES``): a scenario is named by its seed; train, validation and test
  scenarios come from disjoint ranges, and the test range is never used for tuning anything.
  Its seeds from ``FINAL_TEST_SEED`` on are the final test range: development measures below
  it, and the final range is evaluated once, at an issue's end (`stealth benchmark` and
  `stealth generalist` refuse it unless asked for by name).
- **Difficulty**, measured on the proven scenario: ``lit``, the fraction of the valid lattice
  nodes seen at some phase of the lights, and ``detour``, the covert route's steps over the
  shortest route's. Each difficulty sets the lights' size (``guard_lights.LIGHT_SIZES``: easy
  4-6 m and 30-50 degrees, medium 5-8 m and 40-60, hard 7-10 m and 50-80), which lights guard
  the goal's approach (all: the corridor beside the goal's way in; medium: also one door of
  the goal's room and a corridor end; hard: all but one of its doors and both corridor ends),
  and requires ``DIFFICULTY_RULES``: a band of ``lit`` and a least ``detour`` (hard: the covert
  route at least 1.1 x the shortest). Both measures go into the file's header. (Measured at
  30 x 30 m, 4 lights: lit about 1 % easy, 2-3 % medium, 4-5 % hard.)
- **Step limit**: ``STEPS_PER_METRE`` x (width + height): twice the walk from one corner to the
  opposite one along the walls at 0.5 m a step.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
import tempfile

import numpy as np

from stealth_core.floor_plan import DEFAULT_RESOLUTION, UNIT, FloorPlan, generate_floor_plan
from stealth_core.guard_lights import MOVING, PHASE_BINS, STEP_SECONDS, place_lights
from stealth_core.lattice_model import LatticeModel
from stealth_core.occupancy_map import save_map
from stealth_core.planners import astar, follow, value_iteration, walk
from stealth_core.reward import (
    EpisodeOutcome,
    RewardError,
    RewardWeights,
    check_well_posed,
    undetected_visibility_bound,
)
from stealth_core.scenario import DIFFICULTIES, Scenario, scenario_from_fields
from stealth_core.task import StealthTask

# The generator's output: raised whenever a seed and options give other files than before.
GENERATOR_VERSION = 1
SEED_RANGES = {  # inclusive; None: no upper end
    'train': (0, 99_999),
    'validation': (100_000, 109_999),
    'test': (1_000_000, None),
}
FINAL_TEST_SEED = 2_000_000  # the test range's final part (module docstring)
WIDTH_RANGE = (20, 60)  # m, whole metres
HEIGHT_RANGE = (20, 40)
LIGHTS_RANGE = (2, 8)
MAX_TRIES = 40
STEPS_PER_METRE = 4
ROBOT_RADIUS = 0.2
GOAL_RADIUS = 0.5
THRESHOLD = 0.3
# Per difficulty: (lit low, lit high, least detour): see "Difficulty" above.
DIFFICULTY_RULES = {
    'easy': (0.0, 1.0, 1.0),
    'medium': (0.0, 1.0, 1.0),
    'hard': (0.0, 1.0, 1.1),
}
REWARDS = (  # map1's weights; detection_penalty raised where the building needs (_penalty)
    ('goal_reward', 1000.0),
    ('goal_distance_weight', 100.0),
    ('detection_penalty', 1000.0),
    ('detection_distance_weight', 10.0),
    ('visibility_weight', 1.0),
    ('distance_weight', 0.05),
    ('time_cost', 0.0),
)
PENALTY_STEP = 500.0  # detection_penalty rises by this until the rewards are well posed


class GenerationError(ValueError):
    """Options out of range, or a seed that gave no proven scenario within MAX_TRIES."""


@dataclasses.dataclass(frozen=True)
class Options:
    """What the scenarios of a batch look like (besides their seeds)."""

    width: int = 30
    height: int = 30
    lights: int = 4
    moving: str = 'none'
    difficulty: str = 'medium'

    def check(self) -> None:
        """GenerationError naming the first option out of range, and the range."""
        for name, (low, high) in (
            ('width', WIDTH_RANGE),
            ('height', HEIGHT_RANGE),
            ('lights', LIGHTS_RANGE),
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise GenerationError(
                    f'--{name}: expected a whole number in [{low}, {high}], got {value!r}'
                )
        for name, choices in (('moving', MOVING), ('difficulty', DIFFICULTIES)):
            if getattr(self, name) not in choices:
                raise GenerationError(
                    f'--{name}: expected one of {", ".join(choices)}, got {getattr(self, name)!r}'
                )


@dataclasses.dataclass(frozen=True)
class Proof:
    """What was proven of a scenario, and its difficulty's measures."""

    lit: float  # fraction of valid lattice nodes seen at some phase
    shortest_steps: int  # A*'s path, ignoring the lights (seen)
    covert_steps: int  # the value-iteration optimum's path (unseen, reaches the goal)
    covert_return: float
    tries: int

    @property
    def detour(self) -> float:
        return self.covert_steps / self.shortest_steps


@dataclasses.dataclass(frozen=True)
class Generated:
    """One proven scenario: its name, files' contents and proof."""

    seed: int
    name: str
    scenario_text: str
    map_files: dict[str, bytes]  # file name (in maps/) -> bytes
    proof: Proof

    def files(self) -> dict[str, bytes]:
        """Every file as ``write`` lays it out: its path in the directory -> its bytes."""
        return {
            **{f'maps/{file_name}': data for file_name, data in self.map_files.items()},
            f'{self.name}.yaml': self.scenario_text.encode('utf-8'),
        }

    def write(self, directory: str | Path) -> Path:
        """Write ``<name>.yaml`` and ``maps/<name>.pgm + .yaml`` into directory; the
        scenario's path."""
        directory = Path(directory)
        (directory / 'maps').mkdir(parents=True, exist_ok=True)
        for relative, data in self.files().items():
            (directory / relative).write_bytes(data)
        return directory / f'{self.name}.yaml'


def seed_range_of(seed: int) -> str | None:
    """'train', 'validation' or 'test' for a seed in one of SEED_RANGES, else None."""
    for name, (low, high) in SEED_RANGES.items():
        if low <= seed and (high is None or seed <= high):
            return name
    return None


def scenario_name(seed: int) -> str:
    return f'gen-{seed:07d}'


def generate(seed: int, options: Options = Options()) -> Generated:
    """The proven scenario of this seed and these options (GenerationError after MAX_TRIES)."""
    options.check()
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise GenerationError(f'--seed: expected a whole number >= 0, got {seed!r}')
    rng = np.random.default_rng(seed)
    name = scenario_name(seed)
    failures: dict[str, int] = {}
    with tempfile.TemporaryDirectory(prefix='stealth-generate-') as work:
        for tries in range(1, MAX_TRIES + 1):
            candidate, fields = _draw_fields(rng, seed, name, options)
            path = candidate.write(work)  # proven as written: its map, and its fields unparsed
            proof, failure = prove(scenario_from_fields(path, fields), options.difficulty, tries)
            if proof is not None:
                return dataclasses.replace(candidate, proof=proof, scenario_text=_with_header(
                    candidate.scenario_text, seed, options, proof
                ))  # fmt: skip
            failures[failure] = failures.get(failure, 0) + 1
    reasons = ', '.join(f'{reason} {count}x' for reason, count in sorted(failures.items()))
    raise GenerationError(
        f'seed {seed}: no proven scenario in {MAX_TRIES} tries ({reasons}) with --width '
        f'{options.width} --height {options.height} --lights {options.lights} --moving '
        f'{options.moving} --difficulty {options.difficulty}; try other options or seeds'
    )


def prove(scenario: Scenario, difficulty: str, tries: int = 1) -> tuple[Proof | None, str]:
    """(Proof, '') when a covert route exists, A*'s route is seen and the difficulty's
    measures hold; else (None, why)."""
    model = LatticeModel.build(StealthTask(scenario))
    shortest = astar(model)
    if shortest is None:
        return None, 'goal unreachable'
    if walk(model, shortest).outcome is not EpisodeOutcome.DETECTED:
        return None, 'shortest route unseen'
    optimum = value_iteration(model)
    route = follow(model, lambda i: int(optimum.policy[i]))
    result = walk(model, route)
    if result.outcome is not EpisodeOutcome.SUCCESS:
        return None, 'no covert route'
    seen = model.seen.reshape(model.layers, len(model.nodes)).any(axis=0)
    proof = Proof(
        lit=float(seen.mean()),
        shortest_steps=len(shortest) - 1,
        covert_steps=result.steps,
        covert_return=round(float(result.total_reward), 6),
        tries=tries,
    )
    lit_low, lit_high, detour = DIFFICULTY_RULES[difficulty]
    if not lit_low <= proof.lit < lit_high:
        return None, f'lit outside [{lit_low:g}, {lit_high:g})'
    if proof.detour < detour:
        return None, f'detour below {detour:g}'
    return proof, ''


def _draw(rng: np.random.Generator, seed: int, name: str, options: Options) -> Generated:
    """One candidate: building, start, goal and lights (not yet proven)."""
    return _draw_fields(rng, seed, name, options)[0]


def _draw_fields(rng, seed: int, name: str, options: Options) -> tuple[Generated, dict]:
    """``_draw``, and the scenario file's fields as YAML reads them (``_scenario_fields``)."""
    plan = generate_floor_plan(rng, options.width, options.height, DEFAULT_RESOLUTION)
    start = plan.rooms[plan.hall].centre
    goal_room = _farthest_room(plan, start)
    goal = plan.rooms[goal_room].centre
    lights = place_lights(rng, plan, goal_room, options.lights, options.moving, options.difficulty)
    with tempfile.TemporaryDirectory(prefix='stealth-map-') as work:
        yaml_path = save_map(plan.occupancy_map(), Path(work) / name)
        map_files = {p.name: p.read_bytes() for p in sorted(Path(work).iterdir())}
    fields = _scenario_fields(name, yaml_path.name, start, goal, lights, options)
    return Generated(
        seed, name, _scenario_text(fields), map_files, Proof(0.0, 1, 1, 0.0, 0)
    ), fields


def _farthest_room(plan: FloorPlan, start: tuple[float, float]) -> int:
    """The room most doors from the hall, the farthest in metres among those."""
    doors = plan.door_distances(plan.hall)

    def key(index: int):
        x, y = plan.rooms[index].centre
        return (doors[index], abs(x - start[0]) + abs(y - start[1]))

    rooms = [i for i, room in enumerate(plan.rooms) if room.kind == 'room']
    return max(rooms, key=key)


def _value(value: float):
    """A number as the scenario file writes it and YAML reads it back: whole numbers as ints,
    others to 6 significant digits (``:g``; a float where that has a decimal point, which YAML
    needs, else the text, as YAML reads it). ``str`` of such a float is the same text for every
    number below 1e6, far beyond a building's metres, degrees and speeds."""
    if float(value) == int(value):
        return int(value)
    text = f'{value:g}'
    return float(text) if '.' in text else text


def _scenario_fields(name, map_file, start, goal, lights, options: Options) -> dict:
    """The scenario file's fields, as ``load_scenario`` reads them from the file's YAML (the
    text is written from them: ``_scenario_text``), in the shipped scenarios' order."""
    fields = {
        'name': name,
        'map': f'maps/{map_file}',
        'start': {'x': _value(start[0]), 'y': _value(start[1]), 'yaw': 0},
        'goals': {options.difficulty: {'x': _value(goal[0]), 'y': _value(goal[1])}},
        'default_goal': options.difficulty,
        'robot_radius': ROBOT_RADIUS,
        'step_distance': UNIT,
        'state_cell': UNIT,
        'goal_radius': GOAL_RADIUS,
        'detection_threshold': THRESHOLD,
        'detection_mode': 'threshold',
        'step_limit': STEPS_PER_METRE * (options.width + options.height),
    }
    if any('motion' in light for light in lights):
        fields.update(phase_bins=PHASE_BINS, step_seconds=STEP_SECONDS)
    fields['lights'] = []
    for light in lights:
        entry = {'name': light['name']}
        entry.update(
            (key, _value(light[key])) for key in ('x', 'y', 'direction', 'fov', 'range', 'delta')
        )
        motion = light.get('motion')
        if motion is not None and motion['type'] == 'sweep':
            entry['motion'] = {'type': 'sweep'} | {
                key: _value(motion[key])
                for key in ('min_direction', 'max_direction', 'angular_speed')
            }
        elif motion is not None:
            (x, y), = motion['waypoints']  # fmt: skip
            entry['motion'] = {
                'type': motion['type'],
                'waypoints': [[_value(x), _value(y)]],
                'speed': _value(motion['speed']),
            }
        fields['lights'].append(entry)
    penalty = _penalty(options)
    fields['rewards'] = {
        key: penalty if key == 'detection_penalty' else value for key, value in REWARDS
    }
    return fields


def _scenario_text(fields: dict) -> str:
    """The scenario YAML of ``_scenario_fields``: goals and rewards as block mappings, lights
    as a block sequence, everything within them in flow style."""
    lines = []
    for key, value in fields.items():
        if key in ('goals', 'rewards'):
            lines += [f'{key}:', *(f'  {k}: {_flow(v)}' for k, v in value.items())]
        elif key == 'lights':
            lines += ['lights:', *(f'  - {_flow(light)}' for light in value)]
        else:
            lines.append(f'{key}: {_flow(value)}')
    return '\n'.join(lines) + '\n'


def _flow(value) -> str:
    """A value in YAML flow style: mappings in braces, lists in brackets, numbers and names
    as ``str`` writes them."""
    if isinstance(value, dict):
        return '{' + ', '.join(f'{key}: {_flow(item)}' for key, item in value.items()) + '}'
    if isinstance(value, list):
        return '[' + ', '.join(_flow(item) for item in value) + ']'
    return str(value)


def _penalty(options: Options) -> float:
    """The least detection_penalty, from REWARDS' up in PENALTY_STEPs, that makes getting
    caught never pay in this building (``reward.check_well_posed``, as load_scenario checks):
    a long undetected episode in a big building with many lights may cost more than 1000."""
    weights = dict(REWARDS)
    while True:
        try:
            check_well_posed(
                RewardWeights(**weights),
                max_distance=math.hypot(options.width, options.height),
                max_visibility=undetected_visibility_bound('threshold', THRESHOLD, options.lights),
                max_steps=STEPS_PER_METRE * (options.width + options.height),
            )
            return weights['detection_penalty']
        except RewardError:
            weights['detection_penalty'] += PENALTY_STEP


def _with_header(text: str, seed: int, options: Options, proof: Proof) -> str:
    """The scenario text under a comment saying how it was made and what was proven."""
    header = (
        f'# {scenario_name(seed)}: generated by `stealth scenarios generate --seed {seed} '
        f'--width {options.width} --height {options.height} --lights {options.lights} '
        f'--moving {options.moving} --difficulty {options.difficulty}` '
        f'({seed_range_of(seed) or "no"} seed range).\n'
        f'# Proven: the shortest route ignoring the lights ({proof.shortest_steps} steps, A*) is '
        f'seen; a covert route of {proof.covert_steps} steps (value iteration, return '
        f'{proof.covert_return:.1f}) reaches the goal unseen.\n'
        f'# Difficulty {options.difficulty}: {100 * proof.lit:.1f} % of the lattice nodes lit, '
        f'detour {proof.detour:.2f}x the shortest route; try {proof.tries}.\n'
    )
    return header + text
