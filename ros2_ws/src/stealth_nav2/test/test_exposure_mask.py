"""The exposure mask's values (stealth_nav2.exposure_mask): lethal at the detection threshold, a
graded band below it, dark 0, walls -1; the light field equal to the environment's model; moving
lights moving the lethal cells with time."""

import math

import numpy as np
import pytest
from stealth_core.lighting import GridFrame, point_visibility
from stealth_core.scenario import load_scenario
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion
from stealth_core.task import StealthTask
from stealth_core.visibility import visibility_field
from stealth_nav2.exposure_mask import (
    BAND_TOP,
    LETHAL,
    UNKNOWN,
    ExposureMask,
    LightField,
    mask_levels,
)

RESOLUTION = 0.1
ORIGIN = (-1.0, -2.0, 0.0)


def room(size: int = 60) -> np.ndarray:
    """A size x size cell room with walls one cell thick and a pillar in the middle."""
    blocked = np.zeros((size, size), dtype=bool)
    blocked[0, :] = blocked[-1, :] = blocked[:, 0] = blocked[:, -1] = True
    blocked[28:32, 28:32] = True
    return blocked


def test_levels_at_and_above_the_threshold_are_lethal():
    blocked = np.zeros((1, 5), dtype=bool)
    total = np.array([[0.3, 0.30000001, 0.9, 0.29999999, 5.0]])
    levels = mask_levels(total, blocked, threshold=0.3, band_start=0.5)
    assert levels[0].tolist()[:3] == [LETHAL, LETHAL, LETHAL]
    assert levels[0, 3] == BAND_TOP  # just under the threshold: the band's top, not lethal
    assert levels[0, 4] == LETHAL


def test_band_is_graded_monotonically_from_1_to_99():
    threshold, band_start = 0.3, 0.5
    total = np.linspace(0.0, 0.35, 3501).reshape(1, -1)
    levels = mask_levels(total, np.zeros(total.shape, dtype=bool), threshold, band_start)[0]
    assert np.all(np.diff(levels.astype(int)) >= 0)  # monotonic in the light
    band = (total[0] > band_start * threshold) & (total[0] < threshold)
    assert levels[band].min() == 1 and levels[band].max() == BAND_TOP
    assert set(levels[band].tolist()) == set(range(1, BAND_TOP + 1))  # every grade is used
    assert np.all(levels[total[0] <= band_start * threshold] == 0)  # dark, and below the band
    assert np.all(levels[total[0] >= threshold] == LETHAL)


def test_band_start_one_leaves_only_dark_and_lethal():
    total = np.array([[0.0, 0.1, 0.29, 0.3]])
    levels = mask_levels(total, np.zeros(total.shape, dtype=bool), 0.3, 1.0)
    assert levels[0].tolist() == [0, 0, 0, LETHAL]


def test_walls_and_unknown_cells_are_unknown_to_the_filter():
    blocked = np.array([[True, False, True]])
    levels = mask_levels(np.array([[0.9, 0.9, 0.0]]), blocked, 0.3, 0.5)
    assert levels[0].tolist() == [UNKNOWN, LETHAL, UNKNOWN]


@pytest.mark.parametrize(
    ('threshold', 'band_start', 'field', 'words'),
    [
        (0.0, 0.5, np.zeros((2, 2)), 'detection threshold'),
        (math.nan, 0.5, np.zeros((2, 2)), 'detection threshold'),
        (0.3, 1.5, np.zeros((2, 2)), 'band_start'),
        (0.3, -0.1, np.zeros((2, 2)), 'band_start'),
        (0.3, 0.5, np.zeros((3, 2)), "map's shape"),
        (0.3, 0.5, np.full((2, 2), np.inf), 'finite'),
    ],
)
def test_bad_numbers_are_refused_with_a_message(threshold, band_start, field, words):
    with pytest.raises(ValueError, match=words):
        mask_levels(field, np.zeros((2, 2), dtype=bool), threshold, band_start)


def test_static_field_is_the_environment_model_at_every_cell_centre(tmp_path):
    blocked = room()
    lights = [
        Searchlight('a', 1.0, 1.0, math.radians(30), math.radians(70), 3.0),
        Searchlight('b', 3.5, 2.0, math.radians(200), math.radians(120), 2.5, soft_edge=0.3),
    ]
    field = LightField(blocked, RESOLUTION, ORIGIN, lights, cache_dir=tmp_path).at(7.0)
    frame = GridFrame.of(blocked, RESOLUTION, ORIGIN)
    rng = np.random.default_rng(0)
    for row, col in zip(*(rng.integers(0, 60, 300) for _ in range(2)), strict=True):
        x, y = frame.cell_centre(col, row)
        expected = point_visibility(blocked, RESOLUTION, ORIGIN, lights, float(x), float(y))
        assert field[row, col] == expected  # to the last bit


def moving_lights():
    """A static light, a sweeping one and a patrolling one, interleaved in that order."""
    return [
        Searchlight('static', 0.2, 0.0, 0.0, math.radians(60), 2.0),
        Searchlight(
            'sweep', 3.5, 3.5, math.radians(200), math.radians(40), 3.0,
            motion=SweepMotion(math.radians(180), math.radians(270), 0.5),
        ),
        Searchlight('late-static', 4.0, -1.0, math.radians(120), math.radians(50), 2.0),
        Searchlight(
            'patrol', 0.0, 3.0, math.radians(-90), math.radians(50), 2.0,
            motion=PatrolMotion(((3.0, 3.0),), 0.7),
        ),
    ]  # fmt: skip


@pytest.mark.parametrize('t', [0.0, 1.3, 4.75, 11.0, -2.5])
def test_moving_field_equals_the_visibility_field_at_each_time(tmp_path, t):
    blocked, lights = room(), moving_lights()
    field = LightField(blocked, RESOLUTION, ORIGIN, lights, cache_dir=tmp_path)
    for _ in range(2):  # the second time from the sight memos
        reference, _ = visibility_field(blocked, RESOLUTION, ORIGIN, lights, t)
        assert np.array_equal(field.at(t), reference)


def test_moving_light_moves_the_lethal_cells_with_time(tmp_path):
    blocked = room()
    patrol = Searchlight(
        'patrol', 0.0, 3.0, math.radians(-90), math.radians(40), 2.0,
        motion=PatrolMotion(((3.0, 3.0),), 0.5),
    )  # fmt: skip
    mask = ExposureMask(blocked, RESOLUTION, ORIGIN, [patrol], 0.3, cache_dir=tmp_path)
    assert mask.moving
    frame = GridFrame.of(blocked, RESOLUTION, ORIGIN)
    centres = []
    for t in (0.0, 2.0, 4.0):
        lethal = np.argwhere(mask.at(t) == LETHAL)
        assert len(lethal)
        x, _ = frame.cell_centre(lethal[:, 1], lethal[:, 0])
        lamp_x = patrol.at(t).x
        assert np.all(np.abs(x - lamp_x) < 1.0)  # under the lamp, wherever it is
        centres.append(float(np.mean(x)))
    assert centres[0] < centres[1] < centres[2]  # eastwards with the lamp, 1 m each 2 s


def test_static_mask_does_not_change_with_time(tmp_path):
    blocked = room()
    light = Searchlight('a', 1.0, 1.0, math.radians(30), math.radians(70), 3.0)
    mask = ExposureMask(blocked, RESOLUTION, ORIGIN, [light], 0.3, cache_dir=tmp_path)
    assert not mask.moving
    assert np.array_equal(mask.at(0.0), mask.at(123.4))
    assert np.count_nonzero(mask.at(0.0) == LETHAL) > 0


def test_scenario_mask_is_lethal_exactly_where_the_task_detects_a_robot(tmp_path):
    """map1-moving at two times: every free cell's value against StealthTask's own judgement
    at its centre (detected <=> 100), on a sample of cells."""
    scenario = load_scenario('map1-moving')
    task = StealthTask(scenario)
    mask = ExposureMask.of_scenario(scenario, cache_dir=tmp_path)
    occupancy = scenario.map
    frame = GridFrame.of(occupancy.blocked, occupancy.resolution, occupancy.origin)
    for t in (0.0, 9.0):
        levels = mask.at(t)
        lit = np.argwhere(levels > 0)
        rng = np.random.default_rng(1)
        sample = np.concatenate([lit[rng.choice(len(lit), 150)], rng.integers(0, 400, (150, 2))])
        for row, col in sample:
            x, y = (float(v) for v in frame.cell_centre(col, row))
            if occupancy.blocked[row, col]:
                assert levels[row, col] == UNKNOWN
                continue
            detected = task.judge(x, y, t, 1).detected
            assert (levels[row, col] == LETHAL) == detected, (x, y, t)


def test_scenario_band_start_out_of_range_is_refused(tmp_path):
    with pytest.raises(ValueError, match='band_start'):
        ExposureMask.of_scenario(load_scenario('simple-maze'), band_start=2.0, cache_dir=tmp_path)


def test_a_lamp_that_leaves_the_map_is_refused_when_the_mask_is_built(tmp_path):
    patrol = Searchlight(
        'rail', 1.0, 1.0, 0.0, 1.0, 2.0, motion=PatrolMotion(((1.0, 1.0), (9.0, 1.0)), 0.5)
    )
    with pytest.raises(ValueError, match="searchlight 'rail' .* is outside the map"):
        LightField(room(), RESOLUTION, ORIGIN, [patrol], cache_dir=tmp_path)
