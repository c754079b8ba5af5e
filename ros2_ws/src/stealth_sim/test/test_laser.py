"""Laser ranges against hand-computed distances to known walls."""

import math

import numpy as np
import pytest
from sim_test_maps import PROJECT_MAPS, as_map, maze_map, project_map_and_start, room
from stealth_core.occupancy_map import OCCUPIED, UNKNOWN
from stealth_sim.kernels import laser as laser_kernel
from stealth_sim.laser import LaserConfig, RayCaster, noisy_ranges, ray_entry

# room(100, 60): walls are the outer ring of cells, so the free interior is
# x in [0.05, 4.95], y in [0.05, 2.95].
ROOM = as_map(room(100, 60))


def test_ranges_to_the_walls_of_a_room():
    caster = RayCaster(ROOM, range_max=10.0)
    bearings = np.array([0.0, math.pi / 2, math.pi, -math.pi / 2, math.pi / 4, -3 * math.pi / 4])
    ranges = caster.cast(1.0, 1.0, 0.0, bearings)
    expected = [3.95, 1.95, 0.95, 0.95, 1.95 * math.sqrt(2), 0.95 * math.sqrt(2)]
    assert ranges == pytest.approx(expected, abs=1e-9)


def test_bearings_are_relative_to_the_robots_heading():
    caster = RayCaster(ROOM, range_max=10.0)
    turned = caster.cast(1.0, 1.0, math.pi / 2, np.array([0.0, -math.pi / 2]))
    assert turned == pytest.approx([1.95, 3.95], abs=1e-9)


def test_a_shallow_ray_hits_the_far_wall_where_trigonometry_says():
    caster = RayCaster(ROOM, range_max=10.0)
    angle = math.atan2(1.0, 3.0)  # from (1, 1): reaches x = 4.95 at y = 1 + 3.95 / 3
    (reading,) = caster.cast(1.0, 1.0, 0.0, np.array([angle]))
    assert reading == pytest.approx(3.95 / math.cos(angle), abs=1e-9)


def test_nothing_within_range_reads_infinity():
    caster = RayCaster(ROOM, range_max=1.0)
    ranges = caster.cast(1.0, 1.0, 0.0, np.array([0.0, math.pi]))
    assert ranges[0] == math.inf and ranges[1] == pytest.approx(0.95, abs=1e-9)


def test_unknown_space_and_the_edge_of_the_map_stop_the_beam():
    data = np.zeros((60, 100), np.int8)  # no walls at all
    data[:, 70:] = UNKNOWN
    data[40, 10:30] = OCCUPIED
    caster = RayCaster(as_map(data), range_max=20.0)
    ranges = caster.cast(1.0, 1.0, 0.0, np.array([0.0, math.pi, -math.pi / 2, math.pi / 2]))
    assert ranges == pytest.approx([2.5, 1.0, 1.0, 1.0], abs=1e-9)


def test_scan_angles_cover_the_field_of_view_without_a_duplicate_beam():
    full = LaserConfig(beams=8)
    assert full.bearings() == pytest.approx(np.arange(-4, 4) * math.pi / 4)
    fan = LaserConfig(beams=5, field_of_view=math.pi)
    assert (fan.angle_min, fan.angle_max) == pytest.approx((-math.pi / 2, math.pi / 2))


def test_noise_has_the_configured_spread_and_respects_the_limits():
    config = LaserConfig(range_max=5.0, range_min=0.1, noise_std=0.02)
    rng = np.random.default_rng(4)
    true = np.full(20_000, 2.0)
    readings = noisy_ranges(true, config, rng)
    assert readings.std() == pytest.approx(0.02, rel=0.03)
    assert abs(readings.mean() - 2.0) < 0.001
    near_min = noisy_ranges(np.full(1000, 0.1), config, rng)
    assert near_min.min() == 0.1
    # Returns pushed to range_max or beyond read as no return (+inf): P(noise > 0.01) = 0.31.
    near_max = noisy_ranges(np.full(10_000, 4.99), config, rng)
    assert np.all(near_max[np.isfinite(near_max)] < 5.0)
    assert np.mean(np.isinf(near_max)) == pytest.approx(0.3085, abs=0.02)
    assert noisy_ranges(np.array([math.inf]), config, rng)[0] == math.inf


def test_laser_config_rejects_bad_values():
    with pytest.raises(ValueError, match='laser_beams'):
        LaserConfig(beams=0)
    with pytest.raises(ValueError, match='laser_noise'):
        LaserConfig(noise_std=math.nan)
    with pytest.raises(ValueError, match='laser_range'):
        LaserConfig(range_max=-1.0)


def reference_cast(occupancy_map, range_max, x, y, yaw, bearings) -> np.ndarray:
    """The caster as first written, every sample of every beam marched in numpy: the
    definition the fast paths must reproduce exactly (same hit cell, same entry range)."""
    blocked = np.pad(occupancy_map.blocked, 1, constant_values=True)
    res = occupancy_map.resolution
    origin_x, origin_y = occupancy_map.origin[:2]
    step = res / 4
    steps = np.arange(1, math.ceil(range_max / step) + 2) * step / res
    angles = yaw + np.asarray(bearings, dtype=float)
    cos_a, sin_a = np.cos(angles), np.sin(angles)
    height, width = blocked.shape
    cols = np.clip((x - origin_x) / res + 1.0 + np.outer(cos_a, steps), 0, width - 1)
    rows = np.clip((y - origin_y) / res + 1.0 + np.outer(sin_a, steps), 0, height - 1)
    cols, rows = cols.astype(np.intp), rows.astype(np.intp)
    hit = blocked[rows, cols]
    first = np.argmax(hit, axis=1)
    beams = np.arange(len(angles))
    has_hit = hit[beams, first]
    left = origin_x + (cols[beams, first] - 1) * res
    bottom = origin_y + (rows[beams, first] - 1) * res
    ranges = np.maximum(ray_entry(x, y, cos_a, sin_a, left, bottom, res), 0.0)
    return np.where(has_hit & (ranges <= range_max), ranges, np.inf)


@pytest.mark.parametrize('name', ['maze', *PROJECT_MAPS])
@pytest.mark.parametrize('beams', [1, 8, 24, 60, 180])
def test_casting_is_exactly_the_reference_march(name, beams):
    """The caster's traced and marched paths, and the compiled kernel (the published scan's and
    the filter's cast), all give the reference's ranges bit for bit."""
    loaded = (maze_map(), None) if name == 'maze' else project_map_and_start(name)
    if loaded is None:
        pytest.skip(f'map {name} is not built')
    occupancy_map = loaded[0]
    rng = np.random.default_rng(beams)
    free = np.argwhere(~occupancy_map.blocked)
    for range_max in (12.0, 1.3):
        caster = RayCaster(occupancy_map, range_max)
        for trial in range(40):
            row, col = free[rng.integers(len(free))]
            if trial < 3:  # also starts in a wall or off the map (the general path)
                row, col = rng.integers(-5, occupancy_map.blocked.shape[0] + 5, 2)
            x = occupancy_map.origin[0] + (col + rng.random()) * occupancy_map.resolution
            y = occupancy_map.origin[1] + (row + rng.random()) * occupancy_map.resolution
            bearings = rng.uniform(-math.pi, math.pi, beams)
            bearings[: min(beams, 4)] = (0.0, math.pi / 2, math.pi, -math.pi / 2)[: min(beams, 4)]
            yaw = 0.0 if trial % 2 else float(rng.uniform(-4.0, 4.0))
            expected = reference_cast(occupancy_map, range_max, x, y, yaw, bearings)
            assert np.array_equal(caster.cast(x, y, yaw, bearings), expected)
            assert np.array_equal(laser_kernel.cast(caster, x, y, yaw, bearings), expected)
