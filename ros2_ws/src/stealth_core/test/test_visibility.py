"""The vectorised visibility field equals the per-point reference on every cell; the cache."""

import dataclasses
import math
import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from stealth_core import sight_kernels, visibility, visibility_cache
from stealth_core.lighting import (
    GridFrame,
    line_of_sight,
    point_light_visibilities,
    point_visibility,
)
from stealth_core.occupancy_map import OccupancyMap
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion
from stealth_core.visibility import visibility_field
from stealth_core.visibility_cache import cache_key, cached_visibility_field, scenario_visibility

PI = math.pi


def random_case(seed: int):
    """A random map (walls, clutter and lamps in walls included) and 1-4 random lights."""
    rng = np.random.default_rng(seed)
    height, width = (int(n) for n in rng.integers(3, 36, 2))
    blocked = rng.random((height, width)) < rng.uniform(0.0, 0.45)
    resolution = float(rng.uniform(0.05, 0.5))
    origin = (float(rng.uniform(-5, 5)), float(rng.uniform(-5, 5)), 0.0)
    frame = GridFrame.of(blocked, resolution, origin)
    lights = []
    for i in range(int(rng.integers(1, 5))):
        col = rng.integers(0, width) + rng.uniform(0.01, 0.99) - 0.5
        row = rng.integers(0, height) + rng.uniform(0.01, 0.99) - 0.5
        x, y = (float(v) for v in frame.cell_centre(col, row))
        lights.append(
            Searchlight(
                f'L{i}',
                x,
                y,
                direction=float(rng.uniform(-2 * PI, 2 * PI)),
                fov=float(rng.choice([2 * PI, rng.uniform(0.05, 2 * PI)])),
                range=float(rng.uniform(0.2, 1.3) * resolution * max(height, width)),
                delta=float(rng.uniform(0.01, 0.99)),
                soft_edge=float(rng.choice([0.0, rng.uniform(0.0, 1.0)])),
            )
        )
    return blocked, resolution, origin, lights


def reference_field(blocked, resolution, origin, lights, t=0.0):
    frame = GridFrame.of(blocked, resolution, origin)
    per_light = np.zeros((len(lights), *blocked.shape))
    total = np.zeros(blocked.shape)
    for row in range(frame.height):
        for col in range(frame.width):
            x, y = (float(v) for v in frame.cell_centre(col, row))
            values = point_light_visibilities(blocked, resolution, origin, lights, x, y, t)
            per_light[:, row, col] = values
            total[row, col] = sum(values)
    return total, per_light


@pytest.mark.parametrize('seed', range(40))
def test_field_equals_the_reference_on_every_cell(seed):
    case = random_case(seed)
    total, per_light = visibility_field(*case)
    expected_total, expected_per_light = reference_field(*case)
    np.testing.assert_array_equal(per_light, expected_per_light)
    np.testing.assert_array_equal(total, expected_total)


def test_field_in_every_octant_around_a_walled_lamp():
    """A lamp in the middle of a maze of pillars: lines in all 8 octants, corners included."""
    blocked = np.zeros((41, 41), dtype=bool)
    blocked[::3, ::3] = True
    blocked[1::4, 2::4] = True  # diagonal pairs that touch at corners
    lights = [Searchlight('all-round', 2.05, 2.05, 0.0, 2 * PI, 3.0)]
    total, _ = visibility_field(blocked, 0.1, (0.0, 0.0), lights)
    expected, _ = reference_field(blocked, 0.1, (0.0, 0.0), lights)
    np.testing.assert_array_equal(total, expected)
    assert np.count_nonzero(total) > 100 and np.count_nonzero(total == 0.0) > 100


def test_per_light_fields_add_up_and_have_the_right_shape():
    blocked, resolution, origin, lights = random_case(3)
    total, per_light = visibility_field(blocked, resolution, origin, lights)
    assert total.shape == blocked.shape and per_light.shape == (len(lights), *blocked.shape)
    np.testing.assert_allclose(per_light.sum(axis=0), total)
    assert total.min() >= 0.0 and per_light.max() <= 1.0


def test_an_empty_light_list_is_dark():
    total, per_light = visibility_field(np.zeros((4, 5), dtype=bool), 0.1, (0, 0), [])
    assert per_light.shape == (0, 4, 5) and not total.any()


@pytest.mark.parametrize('t', [0.0, 0.7, 2.5, 11.0])
def test_moving_lights_at_given_times(t):
    blocked = np.zeros((30, 30), dtype=bool)
    blocked[10:12, 5:25] = True
    sweep = Searchlight('sweep', 1.55, 1.55, 0.3, 0.6, 2.5, motion=SweepMotion(0.0, PI / 2, 1.0))
    patrol = Searchlight(
        'patrol', 0.5, 2.5, -PI / 2, 1.0, 2.0, motion=PatrolMotion(((2.5, 2.5), (2.5, 0.5)), 0.8)
    )
    lights = [sweep, patrol]
    total, per_light = visibility_field(blocked, 0.1, (0.0, 0.0), lights, t=t)
    np.testing.assert_array_equal(total, reference_field(blocked, 0.1, (0, 0), lights, t)[0])
    static_total, _ = visibility_field(blocked, 0.1, (0.0, 0.0), [light.at(t) for light in lights])
    np.testing.assert_array_equal(total, static_total)


def test_a_sweeping_light_moves_its_bright_spot():
    blocked = np.zeros((50, 50), dtype=bool)
    sweep = Searchlight('s', 2.55, 2.55, 0.0, 0.3, 2.0, motion=SweepMotion(0.0, PI, PI / 2))
    east, west = (25, 45), (25, 5)  # (row, col) 2 m east and west of the lamp
    at_start, _ = visibility_field(blocked, 0.1, (0.0, 0.0), [sweep], t=0.0)
    at_end, _ = visibility_field(blocked, 0.1, (0.0, 0.0), [sweep], t=2.0)
    assert at_start[east] > 0.0 and at_start[west] == 0.0
    assert at_end[east] == 0.0 and at_end[west] > 0.0


def test_a_lamp_off_the_map_is_an_error():
    lights = [Searchlight('far', 50.0, 0.5, 0.0, 1.0, 2.0)]
    with pytest.raises(ValueError, match="searchlight 'far'.*outside the map"):
        visibility_field(np.zeros((10, 10), dtype=bool), 0.1, (0.0, 0.0), lights)


def test_a_patrol_leaving_the_map_is_an_error_at_that_time():
    patrol = Searchlight('p', 0.5, 0.5, 0.0, 1.0, 2.0, motion=PatrolMotion(((5.0, 0.5),), 1.0))
    visibility_field(np.zeros((10, 10), dtype=bool), 0.1, (0.0, 0.0), [patrol], t=0.2)
    with pytest.raises(ValueError, match="searchlight 'p'"):
        visibility_field(np.zeros((10, 10), dtype=bool), 0.1, (0.0, 0.0), [patrol], t=2.0)


# --- cache -------------------------------------------------------------------------------------


def small_case():
    blocked = np.zeros((20, 30), dtype=bool)
    blocked[5, 3:20] = True
    return blocked, 0.1, (0.0, 0.0, 0.0), [Searchlight('L', 1.0, 1.0, 0.5, 1.5, 1.5)]


def forbid_computing(monkeypatch):
    def fail(*args, **kwargs):
        raise AssertionError('recomputed instead of loading the cache')

    monkeypatch.setattr(visibility_cache, 'visibility_field', fail)


def test_a_second_load_comes_from_the_cache(tmp_path, monkeypatch):
    case = small_case()
    first = cached_visibility_field(*case, cache_dir=tmp_path)
    assert len(list(tmp_path.glob('*.npz'))) == 1
    forbid_computing(monkeypatch)
    second = cached_visibility_field(*case, cache_dir=tmp_path)
    np.testing.assert_array_equal(first[0], second[0])
    np.testing.assert_array_equal(first[1], second[1])
    assert not list(tmp_path.glob('*.tmp'))  # atomic write leaves nothing behind


def test_the_cache_directory_comes_from_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv('STEALTH_NAV_CACHE', str(tmp_path / 'env-cache'))
    cached_visibility_field(*small_case())
    assert len(list((tmp_path / 'env-cache').glob('*.npz'))) == 1
    assert visibility_cache.cache_directory(tmp_path / 'arg') == tmp_path / 'arg'
    monkeypatch.delenv('STEALTH_NAV_CACHE')
    assert (
        visibility_cache.cache_directory() == Path('~/.cache/stealth_nav/visibility').expanduser()
    )


@pytest.mark.parametrize('damage', ['garbage', 'truncate', 'wrong-shape'])
def test_a_corrupt_cache_file_is_recomputed(tmp_path, damage):
    case = small_case()
    expected = visibility_field(*case)
    cached_visibility_field(*case, cache_dir=tmp_path)
    (path,) = tmp_path.glob('*.npz')
    if damage == 'garbage':
        path.write_bytes(b'not an npz at all')
    elif damage == 'truncate':
        path.write_bytes(path.read_bytes()[:100])
    else:
        np.savez(path, total=np.zeros((2, 2)), per_light=np.zeros((1, 2, 2)))
    total, per_light = cached_visibility_field(*case, cache_dir=tmp_path)
    np.testing.assert_array_equal(total, expected[0])
    np.testing.assert_array_equal(per_light, expected[1])
    with np.load(path) as repaired:  # and the file is good again
        np.testing.assert_array_equal(repaired['total'], expected[0])


def test_the_key_changes_with_everything_the_field_depends_on():
    blocked, resolution, origin, lights = small_case()
    base = cache_key(blocked, resolution, origin, lights)
    other_map = blocked.copy()
    other_map[0, 0] = True
    moved = [Searchlight('L', 1.0, 1.0, 0.5, 1.5, 1.5, soft_edge=0.1)]
    variants = [
        cache_key(other_map, resolution, origin, lights),
        cache_key(blocked.reshape(30, 20), resolution, origin, lights),
        cache_key(blocked, 0.2, origin, lights),
        cache_key(blocked, resolution, (0.1, 0.0, 0.0), lights),
        cache_key(blocked, resolution, origin, moved),
        cache_key(blocked, resolution, origin, lights, t=1.0),
    ]
    assert len({base, *variants}) == len(variants) + 1
    assert cache_key(blocked.copy(), resolution, origin, list(lights)) == base


def test_an_unwritable_cache_warns_but_still_answers(tmp_path):
    blocker = tmp_path / 'file'
    blocker.write_text('a file where the cache directory should be')
    with pytest.warns(UserWarning, match='not written'):
        total, _ = cached_visibility_field(*small_case(), cache_dir=blocker / 'cache')
    np.testing.assert_array_equal(total, visibility_field(*small_case())[0])


def test_scenario_visibility_uses_the_scenario_map_and_lights(tmp_path):
    data = np.zeros((20, 30), dtype=np.int8)
    data[5, 3:20] = 100
    data[15, 3:20] = -1
    grid = OccupancyMap(data, 0.1, (0.0, 0.0, 0.0))
    lights = [Searchlight('L', 1.0, 1.0, 0.5, 1.5, 1.5)]
    scenario = SimpleNamespace(map=grid, lights=lights)
    total, per_light = scenario_visibility(scenario, cache_dir=tmp_path)
    expected = visibility_field(grid.blocked, 0.1, grid.origin, lights)
    np.testing.assert_array_equal(total, expected[0])
    assert os.listdir(tmp_path)


# --- PointVisibility: the per-point fast path ---------------------------------------------------


def corner_case_points(frame: GridFrame, blocked: np.ndarray, rng) -> list[tuple[float, float]]:
    """Cell corners and edges (at and just inside), points in and beside blocking cells."""
    res = frame.resolution
    points = []
    rows, cols = np.nonzero(blocked)
    pick = rng.permutation(len(rows))[:40]
    for col, row in [*zip(cols[pick], rows[pick], strict=True), (0, 0)]:
        for d_col, d_row in ((-1, 0), (1, 0), (0, -1), (0, 1), (1, 1), (0, 0)):
            c, r = int(col) + d_col, int(row) + d_row
            if 0 <= c < frame.width and 0 <= r < frame.height:
                x0, y0 = frame.origin_x + c * res, frame.origin_y + r * res
                for fx, fy in ((0.0, 0.0), (0.5, 0.5), (1e-9, 0.999999), (0.999999, 0.0)):
                    points.append((x0 + fx * res, y0 + fy * res))
    return points


def evicting_case(seed: int, rng: np.random.Generator, max_tiles: int):
    """random_case(seed) and a PointVisibility on it whose blocks (of a random TILE) straddle
    the map and whose tiny cache evicts often: (case, frame, fast, (x0, y0, x1, y1) in m)."""
    blocked, resolution, origin, lights = case = random_case(seed)
    frame = GridFrame.of(blocked, resolution, origin)
    fast = visibility.PointVisibility(blocked, resolution, origin, lights, max_tiles=max_tiles)
    fast.TILE = int(rng.integers(1, 9))
    x0, y0 = frame.origin_x, frame.origin_y
    bounds = (x0, y0, x0 + frame.width * resolution, y0 + frame.height * resolution)
    return case, frame, fast, bounds


@pytest.mark.parametrize('seed', range(40))
def test_point_visibility_equals_the_reference_on_random_and_corner_points(seed):
    rng = np.random.default_rng(1000 + seed)
    case, frame, fast, (x0, y0, x1, y1) = evicting_case(seed, rng, max_tiles=5)
    blocked, resolution, origin, lights = case
    points = [(float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1))) for _ in range(300)]
    points += corner_case_points(frame, blocked, rng)
    points += [(light.x, light.y) for light in lights]
    for x, y in points:
        if not (x0 <= x < x1 and y0 <= y < y1):
            continue
        expected = point_light_visibilities(blocked, resolution, origin, lights, x, y)
        assert fast.light_visibilities(x, y) == expected, (x, y)
        assert fast(x, y) == point_visibility(blocked, resolution, origin, lights, x, y)


@pytest.mark.parametrize('seed', range(20))
def test_many_equals_the_reference_through_the_cache_and_in_one_trace(seed):
    """A few points (a move's samples: the block cache, cell by cell) and many points (one
    vectorised trace per light) both give the per-point reference's totals to the last bit."""
    rng = np.random.default_rng(2000 + seed)
    case, _, fast, (x0, y0, x1, y1) = evicting_case(seed, rng, max_tiles=3)
    blocked, resolution, origin, lights = case
    for count in (1, 10, fast.FEW_CELLS, 400):
        xs = rng.uniform(x0, x1 - 1e-9, count)
        ys = rng.uniform(y0, y1 - 1e-9, count)
        expected = [
            point_visibility(blocked, resolution, origin, lights, x, y)
            for x, y in zip(xs, ys, strict=True)
        ]
        np.testing.assert_array_equal(fast.many(xs, ys), expected)


@pytest.mark.parametrize('seed', range(10))
def test_point_visibility_line_of_sight_equals_bresenham_on_every_cell(seed):
    blocked, resolution, origin, lights = random_case(seed)
    fast = visibility.PointVisibility(blocked, resolution, origin, lights)
    height, width = blocked.shape
    lamps = [(0, 0), (width - 1, height - 1), (width // 2, height // 2)]
    for lamp in lamps:
        for row in range(height):
            for col in range(width):
                expected = line_of_sight(blocked, lamp, (col, row))
                assert fast.line_of_sight(lamp, (col, row)) == expected, (lamp, col, row)


@pytest.mark.parametrize('seed', range(20))
def test_the_compiled_and_the_lockstep_trace_agree_on_every_cell(seed):
    """Every cell of a random map from a random lamp cell (every octant, the lamp's own cell,
    squeezed corners): the compiled lines, the same code run as Python and the lockstep numpy
    trace give the same answers, and they are the reference's on a sample."""
    rng = np.random.default_rng(3000 + seed)
    height, width = (int(n) for n in rng.integers(2, 90, 2))
    blocked = rng.random((height, width)) < rng.uniform(0.0, 0.5)
    lamp = (int(rng.integers(width)), int(rng.integers(height)))
    rows, cols = (a.ravel() for a in np.indices((height, width)))
    corners = visibility.corner_maps(blocked)
    lockstep = visibility._occluded_in_lockstep(blocked, corners, lamp, cols, rows)
    traced = visibility._occluded(blocked, corners, lamp, cols, rows)
    np.testing.assert_array_equal(traced, lockstep)
    compiled = sight_kernels.occluded
    plain = getattr(compiled, 'py_func', compiled)
    np.testing.assert_array_equal(plain(blocked, *lamp, cols[:200], rows[:200]), lockstep[:200])
    for k in rng.choice(cols.size, min(60, cols.size), replace=False):
        assert lockstep[k] == (not line_of_sight(blocked, lamp, (cols[k], rows[k])))


@pytest.mark.parametrize('seed', range(12))
def test_the_lockstep_trace_where_numba_is_missing_equals_the_reference(seed, monkeypatch):
    """Without numba the lines run in lockstep (a few cells through the block cache): the same
    field and the same points, to the last bit."""
    monkeypatch.setattr(visibility, '_compiled_sight', lambda: None)
    case = random_case(seed)
    for got, expected in zip(visibility_field(*case), reference_field(*case), strict=True):
        np.testing.assert_array_equal(got, expected)
    rng = np.random.default_rng(4000 + seed)
    _, _, fast, (x0, y0, x1, y1) = evicting_case(seed, rng, max_tiles=3)
    for count in (1, fast.FEW_CELLS, 400):
        xs, ys = rng.uniform(x0, x1 - 1e-9, count), rng.uniform(y0, y1 - 1e-9, count)
        expected = [point_visibility(*case, x, y) for x, y in zip(xs, ys, strict=True)]
        np.testing.assert_array_equal(fast.many(xs, ys), expected)


def test_point_visibility_of_moving_lights_equals_the_reference():
    blocked = np.zeros((30, 30), dtype=bool)
    blocked[10:20, 14] = True
    blocked[5, 3:25] = True
    sweep = Searchlight('sweep', 1.55, 1.55, 0.3, 0.6, 2.5, motion=SweepMotion(0.0, PI / 2, 1.0))
    patrol = Searchlight(
        'patrol', 0.5, 2.5, -PI / 2, 1.0, 2.0, motion=PatrolMotion(((2.5, 2.5), (2.5, 0.5)), 0.8)
    )
    lights = [sweep, patrol]
    fast = visibility.PointVisibility(blocked, 0.1, (0.0, 0.0), lights, max_tiles=20)
    rng = np.random.default_rng(3)
    for _ in range(600):
        x, y, t = (float(v) for v in rng.uniform((0.0, 0.0, 0.0), (3.0, 3.0, 20.0)))
        expected = point_light_visibilities(blocked, 0.1, (0.0, 0.0), lights, x, y, t)
        assert fast.light_visibilities(x, y, t) == expected


@pytest.mark.parametrize('seed', range(6))
def test_many_at_times_is_each_point_at_its_own_time(seed):
    """One call over points at many times (a moving light over a lattice's samples) equals the
    point-by-point reference at each point's time, static lights and soft edges included."""
    blocked, resolution, origin, lights = random_case(seed)
    blocked[:] = False  # a free map, so that patrols may go anywhere on it
    frame = GridFrame.of(blocked, resolution, origin)
    span_x, span_y = frame.width * resolution, frame.height * resolution
    low, high = (origin[0], origin[1]), (origin[0] + span_x, origin[1] + span_y)
    moving = [
        dataclasses.replace(
            lights[0], motion=SweepMotion(lights[0].direction, lights[0].direction + 2.0, 0.7)
        ),
        dataclasses.replace(
            lights[-1],
            x=low[0] + 0.1 * span_x,
            y=low[1] + 0.1 * span_y,
            motion=PatrolMotion(((low[0] + 0.9 * span_x, low[1] + 0.6 * span_y),), 0.3 * span_x),
        ),
    ]
    lights = [*moving, *lights[1:-1]]
    fast = visibility.PointVisibility(blocked, resolution, origin, lights, max_tiles=20)
    rng = np.random.default_rng(seed)
    xs, ys = rng.uniform(low, high, (300, 2)).T
    ts = rng.uniform(0.0, 30.0, 300)
    expected = [fast(x, y, t) for x, y, t in zip(xs, ys, ts, strict=True)]
    np.testing.assert_allclose(fast.many_at_times(xs, ys, ts), expected, rtol=0, atol=1e-12)
    # A few shared times given once and indexed: the same to the last bit as each its own.
    times = rng.uniform(0.0, 30.0, 7)
    index = rng.integers(0, 7, 300)
    indexed = fast.many_at_times(xs, ys, times, time_index=index)
    assert np.array_equal(indexed, fast.many_at_times(xs, ys, times[index]))


def test_point_visibility_refuses_what_the_reference_refuses():
    blocked = np.zeros((10, 10), dtype=bool)
    light = Searchlight('L', 0.5, 0.5, 0.0, PI, 2.0)
    fast = visibility.PointVisibility(blocked, 0.1, (0.0, 0.0), [light])
    for x, y in ((1.0, 0.5), (-0.01, 0.5), (math.nan, 0.5), (0.5, math.inf)):
        with pytest.raises(ValueError, match='outside the map|finite'):
            fast(x, y)
    with pytest.raises(ValueError, match='time t'):
        fast(0.5, 0.5, math.nan)


def test_task_visibility_is_the_reference_on_every_scenario_lattice():
    from stealth_core.scenario import load_scenario, scenario_paths
    from stealth_core.task import StealthTask

    for path in scenario_paths():
        scenario = load_scenario(path)
        if scenario.bounce is not None:
            continue  # test_bounce_scenarios: the same check with the bounce's reference
        task, occupancy = StealthTask(scenario), scenario.map
        lattice = task.lattice
        for node in list(lattice.valid_nodes())[::7]:
            x, y = lattice.node_to_point(node)
            for t in (0.0, 3.0):
                expected = point_visibility(
                    occupancy.blocked, occupancy.resolution, occupancy.origin,
                    scenario.lights, x + 0.013, y - 0.021, t,
                )  # fmt: skip
                assert task.visibility(x + 0.013, y - 0.021, t) == expected
