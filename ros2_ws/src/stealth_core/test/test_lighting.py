"""The per-point lighting model: formulas by hand, Bresenham in every octant, occlusion rules."""

import math

import numpy as np
import pytest
from stealth_core.lighting import (
    GridFrame,
    bresenham_line,
    cone_factor,
    intensity,
    light_intensity,
    line_of_sight,
    point_light_visibilities,
    point_visibility,
)
from stealth_core.occupancy_map import OccupancyMap
from stealth_core.searchlight import Searchlight, SweepMotion

PI = math.pi
ORIGIN = (0.0, 0.0, 0.0)


def lamp(x=0.05, y=0.05, direction=0.0, fov=PI / 2, rng=4.0, **more):
    return Searchlight('L', x, y, direction, fov, rng, **more)


def open_map(width=100, height=100):
    return np.zeros((height, width), dtype=bool)


# --- formulas ---------------------------------------------------------------------------------


def test_intensity_is_one_at_the_lamp_and_delta_at_the_range():
    beta = lamp().beta  # R = 4 m, delta = 0.1
    assert intensity(0.0, beta) == 1.0
    assert intensity(2.0, beta) == pytest.approx(1 / 3.25)  # the hand value
    assert intensity(4.0, beta) == pytest.approx(0.1)
    np.testing.assert_allclose(intensity([0.0, 2.0, 4.0], beta), [1.0, 1 / 3.25, 0.1])


@pytest.mark.parametrize(
    ('angle_deg', 'soft_edge', 'expected'),
    [
        (0.0, 0.0, 1.0),
        (44.9, 0.0, 1.0),
        (45.0, 0.0, 1.0),  # the rim itself is inside
        (45.1, 0.0, 0.0),
        (-44.9, 0.0, 1.0),
        (180.0, 0.0, 0.0),
        (22.5, 0.5, 1.0),  # soft rim: outer half of the 45 degree half-angle
        (30.0, 0.5, 2 / 3),  # (45 - 30) / 22.5
        (-40.0, 0.5, 2 / 9),
        (45.0, 0.5, 0.0),
        (0.0, 1.0, 1.0),
        (15.0, 1.0, 2 / 3),  # tapering from the axis
    ],
)
def test_cone_factor_by_hand(angle_deg, soft_edge, expected):
    factor = cone_factor(math.radians(angle_deg), PI / 2, soft_edge)
    assert factor == pytest.approx(expected)


def test_a_full_circle_light_shines_everywhere_in_range():
    full = lamp(fov=2 * PI)
    for angle in np.linspace(-PI, PI, 13):
        assert light_intensity(full, math.cos(angle), math.sin(angle)) == pytest.approx(
            intensity(1.0, full.beta)
        )


def test_light_intensity_combines_range_cone_and_falloff():
    east = lamp(direction=0.0, fov=PI / 2, rng=4.0)
    assert light_intensity(east, 2.0, 0.0) == pytest.approx(1 / 3.25)
    assert light_intensity(east, 4.0, 0.0) == pytest.approx(0.1)  # d == R is in range
    assert light_intensity(east, 4.0 + 1e-9, 0.0) == 0.0
    assert light_intensity(east, -2.0, 0.0) == 0.0  # behind the lamp
    assert light_intensity(east, 2.0, 2.1) == 0.0  # just outside the 45 degree half-angle
    assert light_intensity(east, 0.0, 0.0) == 1.0  # at the lamp
    north = lamp(direction=PI / 2)
    assert light_intensity(north, 0.0, 2.0) == pytest.approx(1 / 3.25)
    soft = lamp(soft_edge=0.5)
    at_30_deg = (2 * math.cos(PI / 6), 2 * math.sin(PI / 6))
    assert light_intensity(soft, *at_30_deg) == pytest.approx(2 / 3 / 3.25)


# --- Bresenham ---------------------------------------------------------------------------------

# By hand, from the error-term loop: (0,0) -> (4,1) and (0,0) -> (1,4).
SHALLOW = [(0, 0), (1, 0), (2, 1), (3, 1), (4, 1)]
STEEP = [(0, 0), (0, 1), (1, 2), (1, 3), (1, 4)]


@pytest.mark.parametrize('sign_col', [1, -1])
@pytest.mark.parametrize('sign_row', [1, -1])
@pytest.mark.parametrize('line', [SHALLOW, STEEP], ids=['shallow', 'steep'])
def test_bresenham_in_every_octant(line, sign_col, sign_row):
    start = (10, 20)
    expected = [(start[0] + sign_col * c, start[1] + sign_row * r) for c, r in line]
    end = expected[-1]
    assert bresenham_line(*start, *end) == expected


def test_bresenham_straight_and_diagonal_lines():
    assert bresenham_line(0, 0, 3, 0) == [(0, 0), (1, 0), (2, 0), (3, 0)]
    assert bresenham_line(0, 0, 0, -2) == [(0, 0), (0, -1), (0, -2)]
    assert bresenham_line(0, 0, -2, 2) == [(0, 0), (-1, 1), (-2, 2)]
    assert bresenham_line(5, 5, 5, 5) == [(5, 5)]


def test_bresenham_properties_for_all_offsets():
    """Ends included, 8-connected, one cell per major-axis step, within half a cell of the line."""
    for d_col in range(-12, 13):
        for d_row in range(-12, 13):
            cells = bresenham_line(0, 0, d_col, d_row)
            assert cells[0] == (0, 0) and cells[-1] == (d_col, d_row)
            assert len(cells) == max(abs(d_col), abs(d_row)) + 1
            assert all(isinstance(c, int) and isinstance(r, int) for c, r in cells)
            for (c0, r0), (c1, r1) in zip(cells, cells[1:], strict=False):
                assert max(abs(c1 - c0), abs(r1 - r0)) == 1
            for c, r in cells[1:]:
                if abs(d_col) >= abs(d_row):
                    assert abs(r - c * d_row / d_col) <= 0.5 + 1e-12
                else:
                    assert abs(c - r * d_col / d_row) <= 0.5 + 1e-12


# --- occlusion ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    'target',
    [(18, 13), (13, 18), (2, 13), (7, 18), (2, 7), (7, 2), (18, 7), (13, 2)],
    ids=['ENE', 'NNE', 'WNW', 'NNW', 'WSW', 'SSW', 'ESE', 'SSE'],
)
def test_a_wall_on_the_line_blocks_in_every_octant(target):
    blocked = open_map(21, 21)
    lamp_cell = (10, 10)
    assert line_of_sight(blocked, lamp_cell, target)
    for col, row in bresenham_line(*lamp_cell, *target)[1:-1]:
        wall = blocked.copy()
        wall[row, col] = True
        assert not line_of_sight(wall, lamp_cell, target)
    off_line = blocked.copy()
    off_line[10, 0] = off_line[0, 10] = off_line[20, 20] = True
    assert line_of_sight(off_line, lamp_cell, target)


def test_the_end_cells_do_not_block():
    blocked = open_map(10, 10)
    blocked[2, 2] = blocked[2, 6] = True
    assert line_of_sight(blocked, (2, 2), (6, 2))  # lamp in a wall, target in a wall
    assert line_of_sight(blocked, (2, 2), (2, 2))


@pytest.mark.parametrize('step', [(1, 1), (-1, 1), (1, -1), (-1, -1)])
def test_no_light_leaks_between_diagonally_touching_walls(step):
    sc, sr = step
    lamp_cell = (5, 5)
    for length in (1, 3):
        target = (5 + sc * length, 5 + sr * length)
        blocked = open_map(11, 11)
        # the line's last diagonal step, squeezed between two wall cells touching at a corner
        last = (5 + sc * (length - 1), 5 + sr * (length - 1))
        blocked[last[1], last[0] + sc] = True
        assert line_of_sight(blocked, lamp_cell, target)  # one wall cell: the gap is open
        blocked[last[1] + sr, last[0]] = True
        assert not line_of_sight(blocked, lamp_cell, target)


def test_point_visibility_by_hand_and_additive():
    blocked = open_map(100, 100)
    east = lamp(x=1.0, y=1.0)
    north = lamp(x=3.0, y=-0.0 + 0.5, direction=PI / 2)
    here = (3.0, 1.0)  # 2 m east of one lamp, 0.5 m north of the other
    alone = point_visibility(blocked, 0.05, ORIGIN, [east], *here)
    assert alone == pytest.approx(1 / 3.25)
    both = point_light_visibilities(blocked, 0.05, ORIGIN, [east, north], *here)
    assert both == pytest.approx([1 / 3.25, 1 / (1 + north.beta * 0.25)])
    assert point_visibility(blocked, 0.05, ORIGIN, [east, north], *here) == pytest.approx(
        sum(both)
    )


def test_unknown_cells_block_like_walls():
    data = np.zeros((20, 100), dtype=np.int8)
    grid = OccupancyMap(data, 0.05, ORIGIN)
    east = lamp(x=1.0, y=0.5)
    assert point_visibility(grid.blocked, 0.05, ORIGIN, [east], 3.0, 0.5) > 0.0
    for value in (100, -1):
        data[10, 40] = value  # cell holding (2.0 .. 2.05, 0.5 .. 0.55), on the ray
        grid = OccupancyMap(data, 0.05, ORIGIN)
        assert point_visibility(grid.blocked, 0.05, ORIGIN, [east], 3.0, 0.5) == 0.0


def test_visibility_at_a_time_follows_the_moving_light():
    blocked = open_map(100, 100)
    sweep = lamp(x=2.5, y=2.5, direction=0.0, fov=0.2, motion=SweepMotion(0.0, PI / 2, PI / 4))
    east, north = (4.5, 2.5), (2.5, 4.5)
    assert point_visibility(blocked, 0.05, ORIGIN, [sweep], *east, t=0.0) > 0.0
    assert point_visibility(blocked, 0.05, ORIGIN, [sweep], *north, t=0.0) == 0.0
    assert point_visibility(blocked, 0.05, ORIGIN, [sweep], *east, t=2.0) == 0.0
    assert point_visibility(blocked, 0.05, ORIGIN, [sweep], *north, t=2.0) > 0.0


def test_a_coarse_cell_shares_one_occlusion_verdict_but_not_one_distance():
    blocked = open_map(10, 10)
    east = lamp(x=0.5, y=0.5, rng=9.0)
    near = point_visibility(blocked, 1.0, ORIGIN, [east], 3.1, 0.5)
    far = point_visibility(blocked, 1.0, ORIGIN, [east], 3.9, 0.5)
    assert near > far > 0.0


# --- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ('x', 'y', 'message'),
    [
        (-0.01, 1.0, 'outside the map'),
        (1.0, 5.0, 'outside the map'),  # the upper edge belongs to no cell
        (math.nan, 1.0, 'finite'),
        (1.0, math.inf, 'finite'),
    ],
)
def test_bad_points_are_errors_not_zeros(x, y, message):
    with pytest.raises(ValueError, match=message):
        point_visibility(open_map(100, 100), 0.05, ORIGIN, [lamp()], x, y)


def test_a_lamp_off_the_map_is_an_error_naming_it():
    with pytest.raises(ValueError, match="searchlight 'L'.*outside the map"):
        point_visibility(open_map(10, 10), 0.05, ORIGIN, [lamp(x=-1.0)], 0.1, 0.1)


@pytest.mark.parametrize(
    ('blocked', 'resolution', 'origin', 'message'),
    [
        (np.zeros((10, 10), dtype=np.int8), 0.05, ORIGIN, 'boolean'),
        (np.zeros(10, dtype=bool), 0.05, ORIGIN, '2-D'),
        (np.zeros((10, 10), dtype=bool), 0.0, ORIGIN, 'resolution'),
        (np.zeros((10, 10), dtype=bool), math.nan, ORIGIN, 'resolution'),
        (np.zeros((10, 10), dtype=bool), 0.05, (0.0, math.nan), 'origin'),
        (np.zeros((10, 10), dtype=bool), 0.05, (0.0,), 'origin'),
    ],
)
def test_bad_maps_are_refused(blocked, resolution, origin, message):
    with pytest.raises(ValueError, match=message):
        GridFrame.of(blocked, resolution, origin)


def test_cells_match_the_occupancy_map():
    grid = OccupancyMap(np.zeros((30, 40), dtype=np.int8), 0.05, (-1.0, 2.0, 0.3))
    frame = GridFrame.of(grid.blocked, grid.resolution, grid.origin)
    for col, row in [(0, 0), (39, 29), (17, 4)]:
        centre = tuple(float(v) for v in frame.cell_centre(col, row))
        assert centre == grid.cell_to_world(col, row)
        assert frame.cell_of(*centre) == grid.world_to_cell(*centre) == (col, row)
