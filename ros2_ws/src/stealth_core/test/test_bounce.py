"""One-bounce light: the model by hand, the fast paths equal to the per-point reference on every
cell of random maps, the cache, and what is refused."""

import dataclasses
import math

import numpy as np
import pytest
from stealth_core import bounce_kernels, sight_kernels, visibility
from stealth_core.bounce import (
    Bounce,
    bounce_bound,
    point_bounce,
    point_total_visibility,
    received_light,
    wall_emitters,
)
from stealth_core.lighting import GridFrame, point_visibility
from stealth_core.searchlight import Searchlight, SweepMotion
from stealth_core.visibility import PointVisibility, visibility_field
from stealth_core.visibility_cache import cache_key, cached_visibility_field
from test_visibility import corner_case_points, random_case

PI = math.pi


def reference(blocked, resolution, origin, lights, bounce):
    """The per-point reference of a map, emitters and their received light found once."""
    emitters = wall_emitters(blocked)
    received = received_light(blocked, resolution, origin, lights, emitters)

    def total(x, y):
        direct = point_visibility(blocked, resolution, origin, lights, x, y)
        return direct + point_bounce(blocked, resolution, origin, emitters, received, bounce, x, y)

    return total


def random_bounce(seed: int, resolution: float, blocked) -> Bounce:
    rng = np.random.default_rng(500 + seed)
    reach = float(rng.uniform(0.1, 1.0) * resolution * max(blocked.shape))
    return Bounce(float(rng.uniform(0.05, 0.99)), reach)


# --- the model by hand --------------------------------------------------------------------------


def test_emitters_are_blocking_cells_open_to_free_space_with_their_normals():
    blocked = np.zeros((7, 9), dtype=bool)
    blocked[2:5, 2:5] = True  # a 3 x 3 block: 8 emitters around its hidden centre
    blocked[1:6, 7] = True  # a wall one cell thick: open east and west, no normal but its ends
    emitters = wall_emitters(blocked)
    found = {
        (int(c), int(r)): (round(float(nx), 6), round(float(ny), 6))
        for c, r, nx, ny in zip(*emitters, strict=True)
    }
    diagonal = round(math.sqrt(0.5), 6)
    assert found[(2, 2)] == (-diagonal, -diagonal)  # a corner: the sum of west and south
    assert found[(3, 2)] == (0.0, -1.0)
    assert found[(4, 3)] == (1.0, 0.0)
    assert found[(4, 4)] == (diagonal, diagonal)
    assert (3, 3) not in found
    assert found[(7, 5)] == (0.0, 1.0) and found[(7, 1)] == (0.0, -1.0)  # the thin wall's ends
    assert not any((7, row) in found for row in range(2, 5))
    assert list(emitters.rows) == sorted(emitters.rows)  # row-major: the order of the sums


def test_contribution_by_hand_lambertian_falloff_range_and_weight():
    blocked = np.zeros((20, 40), dtype=bool)
    blocked[:, 0] = True  # the west wall's cells face east
    bounce = Bounce(0.5, 1.0)
    resolution = 0.1
    emitters = wall_emitters(blocked)
    received = [0.0] * len(emitters.cols)
    index = [int(r) for r in emitters.rows].index(5)
    received[index] = 0.8
    beta = (1 - 0.1) / (0.1 * 1.0**2)

    def at(x, y):
        return point_bounce(blocked, resolution, (0, 0), emitters, received, bounce, x, y)

    expected = 0.5 * 0.1 * 0.8 / (1 + beta * 0.5**2)  # straight ahead, 0.5 m: cos = 1
    assert at(0.55, 0.55) == pytest.approx(expected)
    d = 0.5 / math.cos(math.radians(60))  # 60 degrees off the normal: half of it
    x, y = 0.05 + 0.5, 0.55 + 0.5 * math.tan(math.radians(60))
    assert at(x, y) == pytest.approx(0.5 * 0.1 * 0.8 * 0.5 / (1 + beta * d * d))
    assert at(1.06, 0.55) == 0.0  # beyond the bounce range (1.01 m)
    assert at(0.95, 0.55) == pytest.approx(0.5 * 0.1 * 0.8 / (1 + beta * 0.9**2))
    blocked[5, 3] = True
    assert at(0.55, 0.55) == 0.0  # occluded by a wall cell on the line


def test_the_bounce_does_not_depend_much_on_the_map_resolution():
    """albedo is per metre of wall: halving the cells keeps a lit wall's bounce (to the
    discretisation's few per cent)."""
    values = []
    for resolution in (0.1, 0.05, 0.025):
        size = round(4.0 / resolution)
        blocked = np.zeros((size, size), dtype=bool)
        wall = round(0.2 / resolution)
        blocked[:, :wall] = True
        lamp = Searchlight('L', 2.0, 2.0, PI, PI / 2, 3.0)
        point = (1.0, 0.9)  # outside the cone: bounce only
        lights = [lamp]
        field = reference(blocked, resolution, (0, 0), lights, Bounce(0.5, 2.0))
        assert point_visibility(blocked, resolution, (0, 0), lights, *point) == 0.0
        values.append(field(*point))
    assert values[0] > 0.02
    assert max(values) / min(values) < 1.06, values  # measured: 0.0510, 0.0528, 0.0535


def test_no_bounce_is_the_direct_light():
    blocked, resolution, origin, lights = random_case(3)
    frame = GridFrame.of(blocked, resolution, origin)
    x, y = (float(v) for v in frame.cell_centre(1, 1))
    direct = point_visibility(blocked, resolution, origin, lights, x, y)
    assert point_total_visibility(blocked, resolution, origin, lights, x, y) == direct
    zero = Bounce(0.0)
    assert point_total_visibility(blocked, resolution, origin, lights, x, y, 0.0, zero) == direct
    for bounce in (None, zero):
        total, _ = visibility_field(blocked, resolution, origin, lights, bounce=bounce)
        np.testing.assert_array_equal(total, visibility_field(*random_case(3))[0])
        assert cache_key(blocked, resolution, origin, lights, 0.0, bounce) == cache_key(
            blocked, resolution, origin, lights
        )


# --- the fast paths equal the reference ---------------------------------------------------------


@pytest.mark.parametrize('seed', range(25))
def test_bounce_field_equals_the_reference_on_every_cell_of_random_maps(seed):
    blocked, resolution, origin, lights = random_case(seed)
    bounce = random_bounce(seed, resolution, blocked)
    total, per_light = visibility_field(blocked, resolution, origin, lights, bounce=bounce)
    expected = reference(blocked, resolution, origin, lights, bounce)
    frame = GridFrame.of(blocked, resolution, origin)
    for row in range(frame.height):
        for col in range(frame.width):
            x, y = (float(v) for v in frame.cell_centre(col, row))
            assert total[row, col] == expected(x, y), (col, row)  # to the last bit
    direct = per_light.sum(axis=0)
    assert np.all(total >= direct - 1e-12)


@pytest.mark.parametrize('seed', range(25))
def test_point_visibility_with_bounce_equals_the_reference_on_random_and_corner_points(seed):
    blocked, resolution, origin, lights = random_case(seed)
    bounce = random_bounce(seed, resolution, blocked)
    rng = np.random.default_rng(2000 + seed)
    frame = GridFrame.of(blocked, resolution, origin)
    fast = PointVisibility(blocked, resolution, origin, lights, bounce=bounce)
    expected = reference(blocked, resolution, origin, lights, bounce)
    x0, y0 = frame.origin_x, frame.origin_y
    x1, y1 = x0 + frame.width * resolution, y0 + frame.height * resolution
    points = [(float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1))) for _ in range(150)]
    points += corner_case_points(frame, blocked, rng)
    points = [(x, y) for x, y in points if x0 <= x < x1 and y0 <= y < y1]
    for x, y in points:
        assert fast(x, y) == expected(x, y), (x, y)
    xs, ys = np.array(points).T
    np.testing.assert_array_equal(fast.many(xs, ys), [expected(x, y) for x, y in points])


@pytest.mark.parametrize('seed', range(6))
def test_the_kernels_as_plain_python_equal_the_compiled_ones(seed, monkeypatch):
    """Without numba the kernels run as Python: the same numbers."""
    kernels = ('field', 'at_points', '_line_blocked', '_contribution')
    if not hasattr(bounce_kernels.field, 'py_func'):
        pytest.skip('numba is not installed: the kernels already run as Python')
    blocked, resolution, origin, lights = random_case(seed)
    bounce = random_bounce(seed, resolution, blocked)
    compiled, _ = visibility_field(blocked, resolution, origin, lights, bounce=bounce)
    for name in kernels:  # the Python functions call each other through the module
        monkeypatch.setattr(bounce_kernels, name, getattr(bounce_kernels, name).py_func)
    plain, _ = visibility_field(blocked, resolution, origin, lights, bounce=bounce)
    np.testing.assert_array_equal(plain, compiled)
    frame = GridFrame.of(blocked, resolution, origin)
    xs, ys = frame.cell_centre(*np.meshgrid(range(frame.width), range(frame.height)))
    points = PointVisibility(blocked, resolution, origin, lights, bounce=bounce)
    np.testing.assert_array_equal(points.many(xs, ys), plain)


# --- cache and refusals -------------------------------------------------------------------------


def test_cached_field_with_bounce_has_its_own_key_and_equals_the_computed(tmp_path):
    case = random_case(7)
    bounce = random_bounce(7, case[1], case[0])
    with_bounce = cache_key(*case, 0.0, bounce)
    assert with_bounce != cache_key(*case)
    assert with_bounce != cache_key(*case, 0.0, dataclasses.replace(bounce, albedo=0.5))
    assert with_bounce != cache_key(*case, 0.0, dataclasses.replace(bounce, range=9.0))
    first, _ = cached_visibility_field(*case, cache_dir=tmp_path, bounce=bounce)
    assert (tmp_path / f'{with_bounce}.npz').is_file()
    again, _ = cached_visibility_field(*case, cache_dir=tmp_path, bounce=bounce)
    np.testing.assert_array_equal(first, visibility_field(*case, bounce=bounce)[0])
    np.testing.assert_array_equal(again, first)


def test_moving_lights_with_a_bounce_are_refused():
    blocked = np.zeros((10, 10), dtype=bool)
    sweep = Searchlight('sweeper', 0.5, 0.5, 0.0, 1.0, 2.0, motion=SweepMotion(0.0, 1.0, 0.5))
    for make in (
        lambda: visibility_field(blocked, 0.1, (0, 0), [sweep], bounce=Bounce(0.3)),
        lambda: PointVisibility(blocked, 0.1, (0, 0), [sweep], bounce=Bounce(0.3)),
    ):
        with pytest.raises(ValueError, match='static lights only; sweeper move'):
            make()
    visibility_field(blocked, 0.1, (0, 0), [sweep], bounce=Bounce(0.0))  # no bounce: fine


@pytest.mark.parametrize(
    ('albedo', 'reach'), [(math.nan, 1.0), (1.0, 1.0), (-0.1, 1.0), (0.3, 0.0), (0.3, math.inf)]
)
def test_bounce_values_are_checked(albedo, reach):
    with pytest.raises(ValueError, match=r'albedo: expected a number in \[0, 1\)|range: expected'):
        Bounce(albedo, reach)


def test_the_bound_holds_for_a_wall_lit_all_round():
    """bounce_bound (for the reward's check) is above the bounce of the brightest case."""
    blocked = np.ones((41, 41), dtype=bool)
    blocked[1:-1, 1:-1] = False  # a room; lamps everywhere light its walls at about 1
    lights = [Searchlight(f'L{i}', 0.1 + i * 0.5, 2.05, 0.0, 2 * PI, 0.3) for i in range(4)]
    lights += [Searchlight('C', 2.05, 2.05, 0.0, 2 * PI, 50.0, delta=0.99)]
    bounce = Bounce(0.99, 3.0)
    total, per_light = visibility_field(blocked, 0.1, (0, 0), lights, bounce=bounce)
    bounced = total - per_light.sum(axis=0)
    assert bounced.max() > 0.1
    assert bounced.max() <= bounce_bound(bounce, 0.1, len(lights))
    assert bounce_bound(None, 0.1, 3) == bounce_bound(Bounce(0.0), 0.1, 3) == 0.0


def test_warm_up_compiles_the_kernels():
    seconds = visibility.warm_up_kernels()
    if not hasattr(bounce_kernels.field, 'signatures'):
        assert seconds is None  # no numba: nothing to compile
        return
    assert seconds >= 0.0
    assert bounce_kernels.field.signatures and bounce_kernels.at_points.signatures
    assert sight_kernels.occluded.signatures
