"""The generator's fast paths (issue 27: >= 20 proven scenarios/s) equal, bit for bit, the
references they replaced: the lattice model's step samples in one call, the lamps' sight memo,
value iteration in (directions, places) layout, vectorised states, the footprint test only near
walls, one move lattice per scenario, the generator's scenario read from its fields rather than
its text; and a generated scenario's files are what they were."""

import dataclasses
import hashlib
import math

import numpy as np
import pytest
from stealth_core import visibility
from stealth_core.lattice_model import LatticeModel
from stealth_core.lighting import point_visibility
from stealth_core.move_lattice import MoveLattice
from stealth_core.planners import step_terms, value_iteration
from stealth_core.scenario import load_scenario, scenario_from_fields, scenario_paths
from stealth_core.scenario_generator import Options, _draw_fields, generate, scenario_name
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion
from stealth_core.task import StealthTask
from stealth_core.yaml_fields import read_yaml_mapping

SHIPPED = [path.stem for path in scenario_paths()]
MIXED = Options(lights=5, moving='mixed')
# sha256 of each scenario's text and map files (name, bytes), from the generator before the
# fast paths: the files of a seed must not change. Where a change is meant to change them, raise
# scenario_generator.GENERATOR_VERSION (caches of generated scenarios record it) with GOLDEN.
GOLDEN = {
    (Options(), 0): '185845671574e70c',
    (Options(), 2): '17400467a03b2984',
    (MIXED, 0): 'cf84dd35c1dd38f2',
    (Options(40, 25, 6, 'sweeping', 'hard'), 4): '1e48b05814069d25',
}


def _digest(generated) -> str:
    digest = hashlib.sha256(generated.scenario_text.encode())
    for name in sorted(generated.map_files):
        digest.update(name.encode())
        digest.update(generated.map_files[name])
    return digest.hexdigest()[:16]


@pytest.fixture(scope='module')
def generated(tmp_path_factory):
    """Two generated scenarios, written and loaded back: a static one and a mixed one."""
    directory = tmp_path_factory.mktemp('generated')
    return [load_scenario(generate(seed, options).write(directory)) for options, seed in (
        (Options(), 2), (MIXED, 0)
    )]  # fmt: skip


def _scenarios(generated):
    return [load_scenario(name) for name in SHIPPED] + list(generated)


@pytest.fixture(scope='module')
def models(generated):
    """The lattice model of every shipped scenario and of the generated ones."""
    return [LatticeModel.build(StealthTask(scenario)) for scenario in _scenarios(generated)]


@pytest.mark.parametrize(('options', 'seed'), list(GOLDEN))
def test_generated_files_are_the_same_bytes_as_before(options, seed):
    assert _digest(generate(seed, options)) == GOLDEN[(options, seed)], (
        'the generated files changed: if meant, raise GENERATOR_VERSION and update GOLDEN'
    )


def _reference_step_peaks(task: StealthTask, model: LatticeModel) -> np.ndarray:
    """The step visibility of the first layer as it was computed: ``many`` per sample, on a
    PointVisibility without the sight memo (max_lamps=0)."""
    scenario = task.scenario
    see = visibility.scenario_point_visibility(scenario)
    see.max_lamps = 0
    n = len(model.nodes)
    points = model.points[:n]
    ends = points[model.successors[:n] % n]
    t1 = task.timing.step_seconds if task.timing is not None else 0.0
    xs, ys, ts = task.step_samples_of(
        points[:, None, 0], points[:, None, 1], 0.0, ends[..., 0], ends[..., 1], t1
    )
    return np.max([see.many(x, y, t) for x, y, t in zip(xs, ys, ts, strict=True)], 0)


def test_step_visibility_equals_the_per_sample_calls_and_the_task(models):
    rng = np.random.default_rng(5)
    for model in models:
        task = model.task
        n = len(model.nodes)
        if task.footprint is None:  # with exposure the first layer faces east: checked below
            expected = _reference_step_peaks(task, model)
            np.testing.assert_array_equal(model.step_visibility[:n], expected, task.title)
        fresh = StealthTask(task.scenario)  # the task's own judge, its memo empty
        bin_seconds = task.timing.bin_seconds if task.timing is not None else 0.0
        step_seconds = task.timing.step_seconds if task.timing is not None else 0.0
        for i in rng.choice(model.size, 40, replace=False):
            t0 = (i // n) % model.cycle_bins * bin_seconds
            for direction in range(model.num_actions):
                j = model.successors[i, direction]
                yaw0, yaw1 = (float(model.heading_of(k)) * (math.pi / 2) for k in (i, j))
                x0, y0 = model.points[i]
                x1, y1 = model.points[j]
                expected = fresh.step_visibility(x0, y0, t0, x1, y1, t0 + step_seconds, yaw0, yaw1)
                assert model.step_visibility[i, direction] == expected, (task.title, i, direction)


def test_states_are_the_task_state_of_every_place(models):
    for model in models:
        task = model.task
        n = len(model.nodes)
        bin_seconds = task.timing.bin_seconds if task.timing is not None else 0.0
        expected = [
            task.state_of(x, y, (i // n) % model.cycle_bins * bin_seconds,
                          float(model.heading_of(i)) * (math.pi / 2))
            for i, (x, y) in enumerate(model.points)
        ]  # fmt: skip
        np.testing.assert_array_equal(model.states, np.array(expected, dtype=np.float32))


def _reference_value_iteration(model: LatticeModel):
    """value_iteration without slip, gamma 1, as it was: (places, directions) rows."""
    p_detected, caught, safe = step_terms(model)
    continues = (1.0 - p_detected) * ~model.goal[model.successors]
    immediate = p_detected * caught + (1.0 - p_detected) * safe
    values = np.zeros(model.size)
    q = np.zeros((model.size, model.num_actions))
    for _ in range(model.task.step_limit):
        q = np.take(values, model.successors)
        q *= continues
        q += immediate
        values = q.max(axis=1)
    return values, q


def test_value_iteration_equals_the_row_layout_bit_for_bit(models):
    for model in models:
        result = value_iteration(model)
        values, q = _reference_value_iteration(model)
        assert result.values.tobytes() == values.tobytes(), model.task.title
        assert result.q.tobytes() == q.tobytes(), model.task.title
        assert result.q.flags.c_contiguous
        np.testing.assert_array_equal(result.policy, q.argmax(axis=1))


def _reference_footprints(lattice: MoveLattice) -> np.ndarray:
    """Every node's exact footprint test, none skipped (the test as it was)."""
    xs, ys = lattice._node_points()
    u, v = lattice._grid_coordinates(xs.ravel(), ys.ravel())
    radius = lattice.robot_radius / lattice.map.resolution
    reach = math.ceil(radius) + 1
    offsets = np.arange(-reach, reach + 1)
    d_col, d_row = (o.ravel() for o in np.meshgrid(offsets, offsets, indexing='ij'))
    cols = np.floor(u[:, None]).astype(np.int64) + d_col
    rows = np.floor(v[:, None]).astype(np.int64) + d_row
    gap_u = np.maximum(np.maximum(cols - u[:, None], u[:, None] - (cols + 1)), 0.0)
    gap_v = np.maximum(np.maximum(rows - v[:, None], v[:, None] - (rows + 1)), 0.0)
    distance_squared = gap_u * gap_u + gap_v * gap_v
    touched = (distance_squared < radius * radius) | (distance_squared == 0.0)
    return ~(touched & lattice._blocked[rows, cols]).any(axis=1).reshape(lattice.shape)


@pytest.mark.parametrize('radius', [0.0, 0.05, 0.2, 0.37])
def test_node_footprints_equal_the_exact_test_on_every_node(generated, radius):
    for scenario in _scenarios(generated):
        for step in (scenario.step_distance, 0.23):
            lattice = MoveLattice(scenario.map, scenario.start[:2], step, radius)
            np.testing.assert_array_equal(lattice.node_mask, _reference_footprints(lattice))


def test_a_scenario_builds_its_lattice_once_and_a_changed_copy_its_own(generated):
    scenario = generated[0]
    lattice = StealthTask(scenario).lattice
    assert StealthTask(scenario).lattice is lattice  # the one load_scenario built
    fresh = MoveLattice(scenario.map, scenario.start[:2], scenario.step_distance,
                        scenario.robot_radius)  # fmt: skip
    for name in ('node_mask', 'right_moves', 'up_moves'):
        np.testing.assert_array_equal(getattr(lattice, name), getattr(fresh, name))
    moved = dataclasses.replace(scenario, start=(scenario.start[0] + 0.5, *scenario.start[1:]))
    other = StealthTask(moved).lattice
    assert other is not lattice and other.anchor == (moved.start[0], moved.start[1])


def test_the_sight_memo_equals_the_reference_with_patrols_evicting_it():
    """Moving lights at many times (a patrol's lamp visits many cells), a memo of one lamp
    cell: many() still gives the per-point reference's totals to the last bit."""
    rng = np.random.default_rng(11)
    blocked = rng.random((40, 40)) < 0.15
    blocked[:, 20] = True
    blocked[10:14, 20] = False
    lights = [
        Searchlight('sweep', 1.05, 1.05, 0.3, 0.8, 3.0, motion=SweepMotion(0.0, 1.5, 0.7)),
        Searchlight(
            'patrol', 3.05, 0.55, 1.6, 1.2, 2.5,
            motion=PatrolMotion(((3.05, 0.55), (3.05, 3.55)), 0.4),
        ),
        Searchlight('still', 2.15, 2.15, 3.5, 2.0, 2.0),
    ]  # fmt: skip
    for max_lamps in (0, 1, 64):
        fast = visibility.PointVisibility(blocked, 0.1, (0.0, 0.0), lights, max_lamps=max_lamps)
        for t in rng.uniform(0.0, 20.0, 12):
            count = int(rng.choice([3, 200]))
            xs, ys = rng.uniform(0.0, 4.0 - 1e-9, (2, count))
            expected = [
                point_visibility(blocked, 0.1, (0.0, 0.0), lights, x, y, t)
                for x, y in zip(xs, ys, strict=True)
            ]
            np.testing.assert_array_equal(fast.many(xs, ys, t), expected)


def _same_scenario(one, other) -> None:
    """Every field of two scenarios equal (the map's cells, resolution and origin included)."""
    for field in dataclasses.fields(one):
        a, b = getattr(one, field.name), getattr(other, field.name)
        if field.name == 'map':
            np.testing.assert_array_equal(a.data, b.data)
            assert (a.resolution, a.origin, a.metadata) == (b.resolution, b.origin, b.metadata)
        else:
            assert a == b, field.name


@pytest.mark.parametrize(
    'options', [Options(), MIXED, Options(20, 20, 2, 'patrolling', 'easy'), Options(60, 40, 8)]
)
def test_the_fields_proven_are_what_the_written_file_loads_to(tmp_path, options):
    """The generator proves ``scenario_from_fields`` of the fields it writes the text from:
    YAML reads the written text back as exactly those fields, and the file loads to the same
    scenario, for several tries of several seeds (candidates that failed their proof too)."""
    for seed in range(3):
        rng = np.random.default_rng(seed)
        for _ in range(3):
            candidate, fields = _draw_fields(rng, seed, scenario_name(seed), options)
            path = candidate.write(tmp_path)
            read = read_yaml_mapping(path, ValueError, 'scenario')
            assert repr(read) == repr(fields)  # types too: 12 is not 12.0; and the order
            _same_scenario(scenario_from_fields(path, fields), load_scenario(path))
