"""The map loader and saver against nav2 Jazzy's map_io rules, on small hand-made maps."""

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from stealth_core.occupancy_map import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    MapError,
    OccupancyMap,
    from_occupancy_grid,
    load_map,
    save_map,
    to_occupancy_grid_data,
)

TRINARY = {'occupied_thresh': 0.65, 'free_thresh': 0.196}


def write_pgm(path: Path, pixels, maxval=255) -> Path:
    pixels = np.asarray(pixels)
    height, width = pixels.shape
    body = pixels.astype('>u2' if maxval > 255 else np.uint8).tobytes()
    path.write_bytes(f'P5\n{width} {height}\n{maxval}\n'.encode() + body)
    return path


def write_png(path: Path, pixels) -> Path:
    path.write_bytes(cv2.imencode('.png', np.asarray(pixels, dtype=np.uint8))[1].tobytes())
    return path


def write_yaml(tmp_path: Path, image='map.pgm', name='map.yaml', **fields) -> Path:
    values = {
        'image': image,
        'resolution': 0.05,
        'origin': [0.0, 0.0, 0.0],
        'negate': 0,
        **TRINARY,
    }
    values.update(fields)
    lines = [f'{key}: {value}' for key, value in values.items() if value is not None]
    path = tmp_path / name
    path.write_text('\n'.join(lines) + '\n')
    return path


def load_pixels(tmp_path, pixels, **fields) -> np.ndarray:
    pixels = np.asarray(pixels)
    if pixels.ndim == 3:
        write_png(tmp_path / 'map.png', pixels)
        return load_map(write_yaml(tmp_path, image='map.png', **fields)).data
    write_pgm(tmp_path / 'map.pgm', pixels)
    return load_map(write_yaml(tmp_path, **fields)).data


# --- nav2's rules, pixel by pixel ---------------------------------------------------------------


def nav2_cell(grey: int, alpha: int, mode: str, negate: bool, occupied: float, free: float):
    """One pixel through nav2 Jazzy's loadMapFromFile, written out as a plain scalar rule.

    float32 arithmetic as Eigen does it; occupied then free overwrite unknown; scale rounds
    halves away from zero; alpha < 255 is unknown except in raw mode.
    """
    if mode == 'raw':
        return grey if grey <= 100 else UNKNOWN
    shade = np.float32(grey) / np.float32(255.0)
    p = shade if negate else np.float32(1.0) - shade
    cell = UNKNOWN
    if p >= np.float32(occupied):
        cell = OCCUPIED
    if p <= np.float32(free):
        cell = FREE
    if mode == 'scale' and np.float32(free) < p < np.float32(occupied):
        scaled = (p - np.float32(free)) / np.float32(occupied - free) * np.float32(100.0)
        cell = int(math.floor(float(scaled) + 0.5))
    if alpha < 255:
        cell = UNKNOWN
    return cell


@pytest.mark.parametrize('mode', ['trinary', 'scale', 'raw'])
@pytest.mark.parametrize('negate', [0, 1])
def test_loader_agrees_with_nav2_rules_on_random_maps(tmp_path, mode, negate):
    rng = np.random.default_rng(7)
    grey = rng.integers(0, 256, (6, 9))
    alpha = np.where(rng.random((6, 9)) < 0.2, rng.integers(0, 255, (6, 9)), 255)
    pixels = np.dstack([grey, grey, grey, alpha])
    thresholds = {'occupied_thresh': 0.7, 'free_thresh': 0.3}
    cells = load_pixels(tmp_path, pixels, mode=mode, negate=negate, **thresholds)
    expected = [
        [nav2_cell(g, a, mode, bool(negate), 0.7, 0.3) for g, a in zip(gr, ar, strict=True)]
        for gr, ar in zip(grey, alpha, strict=True)
    ]
    assert cells.tolist() == expected[::-1]  # bottom image row first


def test_trinary_at_the_thresholds(tmp_path):
    # p = 1 - v/255: 89 -> 0.651 occupied, 90 -> 0.647 unknown, 205 -> 0.19608 > 0.196
    # unknown, 206 -> 0.192 free.
    cells = load_pixels(tmp_path, [[0, 89, 90, 204, 205, 206, 254, 255]])
    assert cells.tolist() == [[100, 100, -1, -1, -1, 0, 0, 0]]


def test_trinary_negated(tmp_path):
    cells = load_pixels(tmp_path, [[0, 49, 50, 166, 255]], negate=1)
    # p = v/255: 49 -> 0.192 free, 50 -> 0.196 in between, 166 -> 0.651 occupied.
    assert cells.tolist() == [[0, 0, -1, 100, 100]]


def test_negate_accepts_booleans_like_nav2(tmp_path):
    assert load_pixels(tmp_path, [[0, 255]], negate='true').tolist() == [[0, 100]]


def test_scale_mode_scales_between_the_thresholds(tmp_path):
    # free 0.2, occupied 0.8: v = 128 -> p = 0.498 -> (0.498 - 0.2) / 0.6 * 100 = 49.7 -> 50;
    # v = 204 -> p = 0.2 -> free; v = 51 -> p = 0.8 -> occupied; v = 230 -> p = 0.098 -> free;
    # v = 100 -> p = 0.608 -> 68.0 -> 68.
    cells = load_pixels(
        tmp_path, [[128, 204, 51, 230, 100]], mode='scale', occupied_thresh=0.8, free_thresh=0.2
    )
    assert cells.tolist() == [[50, 0, 100, 0, 68]]


def test_raw_mode_keeps_values_up_to_100(tmp_path):
    cells = load_pixels(tmp_path, [[0, 1, 50, 100, 101, 200, 255]], mode='raw')
    assert cells.tolist() == [[0, 1, 50, 100, -1, -1, -1]]


def test_alpha_below_255_is_unknown_except_in_raw_mode(tmp_path):
    pixels = np.array([[[255, 255, 255, 255], [255, 255, 255, 254], [0, 0, 0, 0]]])
    assert load_pixels(tmp_path, pixels).tolist() == [[0, -1, -1]]
    assert load_pixels(tmp_path, pixels, mode='scale').tolist() == [[0, -1, -1]]
    assert load_pixels(tmp_path, pixels, mode='raw').tolist() == [[-1, -1, 0]]


def test_colour_is_converted_to_grey_as_graphicsmagick_does(tmp_path):
    # Rec. 601 luma: red 76 (p 0.70, occupied), green 150 (p 0.41, unknown), blue 29 (occupied).
    bgr = np.array([[[0, 0, 255], [0, 255, 0], [255, 0, 0], [255, 255, 255]]])
    assert load_pixels(tmp_path, bgr).tolist() == [[100, -1, 100, 0]]


def test_rows_are_flipped_so_row_0_is_the_bottom(tmp_path):
    cells = load_pixels(tmp_path, [[0, 0], [254, 205]])
    assert cells.tolist() == [[0, -1], [100, 100]]


@pytest.mark.parametrize(
    ('header', 'body'),
    [
        (b'P5\n# a comment\n3 1\n15\n', bytes([0, 7, 15])),  # maxval 15 scales to 255
        (b'P2\n3 1\n15\n', b'0 7\n15\n'),
        (b'P5\n3 1\n65535\n', np.array([0, 30840, 65535], '>u2').tobytes()),
    ],
)
def test_pgm_variants_are_scaled_to_8_bits(tmp_path, header, body):
    (tmp_path / 'map.pgm').write_bytes(header + body)
    # 7/15 of 255 = 119 and 30840/257 = 120: p 0.53, unknown.
    assert load_map(write_yaml(tmp_path)).data.tolist() == [[100, -1, 0]]


def test_metadata_and_paths(tmp_path):
    write_pgm(tmp_path / 'map.pgm', [[254]])
    occupancy = load_map(write_yaml(tmp_path, origin=[-1.5, 2.0, 0.0], resolution=0.1))
    assert occupancy.resolution == 0.1
    assert occupancy.origin == (-1.5, 2.0, 0.0)
    assert occupancy.metadata.image_path == tmp_path / 'map.pgm'
    assert occupancy.metadata.mode == 'trinary'
    assert (occupancy.metadata.occupied_thresh, occupancy.metadata.free_thresh) == (0.65, 0.196)


def test_mode_defaults_to_trinary_and_is_case_insensitive(tmp_path):
    write_pgm(tmp_path / 'map.pgm', [[254]])
    assert load_map(write_yaml(tmp_path)).metadata.mode == 'trinary'
    assert load_map(write_yaml(tmp_path, mode='Scale')).metadata.mode == 'scale'


def test_absolute_image_path(tmp_path):
    image = write_pgm(tmp_path / 'elsewhere.pgm', [[0]])
    (tmp_path / 'sub').mkdir()
    assert load_map(write_yaml(tmp_path / 'sub', image=str(image))).data.tolist() == [[100]]


# --- saving -------------------------------------------------------------------------------------


def random_trinary(rng, shape=(7, 11)) -> np.ndarray:
    return rng.choice(np.array([FREE, OCCUPIED, UNKNOWN], np.int8), size=shape)


def test_saved_map_reloads_identical(tmp_path):
    original = OccupancyMap(random_trinary(np.random.default_rng(1)), 0.05, (-3.2, 4.75, 0.0))
    yaml_path = save_map(original, tmp_path / 'saved')
    reloaded = load_map(yaml_path)
    assert np.array_equal(reloaded.data, original.data)
    assert reloaded.resolution == original.resolution
    assert reloaded.origin == original.origin


def test_saver_writes_what_nav2_map_saver_writes(tmp_path):
    data = np.array([[0, 100, -1], [25, 26, 65]], np.int8)
    yaml_path = save_map(OccupancyMap(data, 0.05, (-10.0, 2.5, 0.0)), tmp_path / 'nav2')
    assert yaml_path.read_text() == (
        'image: nav2.pgm\nmode: trinary\nresolution: 0.050\norigin: [-10.000, 2.500, 0]\n'
        'negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196'
    )
    # Top image row first; 0 occupied, 254 free, 205 unknown; <= 25 free, >= 65 occupied.
    assert (tmp_path / 'nav2.pgm').read_bytes() == b'P5\n3 2\n255\n' + bytes(
        [254, 205, 0, 254, 0, 205]
    )


@pytest.mark.parametrize('mode', ['scale', 'raw'])
def test_trinary_maps_survive_the_other_save_modes(tmp_path, mode):
    original = OccupancyMap(random_trinary(np.random.default_rng(2)), 0.1)
    reloaded = load_map(save_map(original, tmp_path / mode, mode=mode))
    assert reloaded.metadata.mode == mode
    assert np.array_equal(reloaded.data, original.data)


def test_yaw_is_kept_and_saved_but_not_applied(tmp_path):
    occupancy = OccupancyMap(np.zeros((2, 2), np.int8), 1.0, (0.0, 0.0, 0.5))
    assert occupancy.world_to_cell(1.5, 0.5) == (1, 0)  # as if yaw were 0, like costmap_2d
    assert load_map(save_map(occupancy, tmp_path / 'yawed')).origin == (0.0, 0.0, 0.5)


def test_save_rejects_bad_thresholds(tmp_path):
    occupancy = OccupancyMap(np.zeros((1, 1), np.int8), 1.0)
    with pytest.raises(MapError, match="'free_thresh'"):
        save_map(occupancy, tmp_path / 'm', free_thresh=0.7, occupied_thresh=0.6)


# --- geometry and layout ------------------------------------------------------------------------


def small_map() -> OccupancyMap:
    data = np.array([[0, 0, 100], [-1, 50, 70]], np.int8)
    return OccupancyMap(data, 0.5, (-1.0, 2.0, 0.0))


def test_world_to_cell_floors_and_works_on_arrays():
    occupancy = small_map()
    assert occupancy.world_to_cell(-1.0, 2.0) == (0, 0)
    assert occupancy.world_to_cell(-0.01, 2.99) == (1, 1)
    assert occupancy.world_to_cell(-1.01, 1.99) == (-1, -1)
    cols, rows = occupancy.world_to_cell(np.array([-0.9, 0.4]), np.array([2.1, 2.6]))
    assert cols.tolist() == [0, 2] and rows.tolist() == [0, 1]


def test_cell_to_world_gives_centres_and_inverts_world_to_cell():
    occupancy = small_map()
    assert occupancy.cell_to_world(2, 1) == (0.25, 2.75)
    xs, ys = occupancy.cell_to_world(np.arange(3), np.array([0, 1, 0]))
    assert occupancy.world_to_cell(xs, ys)[0].tolist() == [0, 1, 2]


def test_contains():
    occupancy = small_map()
    assert occupancy.contains_cell(2, 1) and not occupancy.contains_cell(3, 0)
    assert occupancy.contains_point(0.49, 2.99) and not occupancy.contains_point(0.5, 2.5)
    assert occupancy.contains_cell(np.array([0, 3]), np.array([0, 0])).tolist() == [True, False]
    assert (occupancy.width, occupancy.height) == (3, 2)
    assert occupancy.bounds == (-1.0, 2.0, 0.5, 3.0)


def test_masks():
    occupancy = small_map()
    assert occupancy.occupied.tolist() == [[False, False, True], [False, False, True]]
    assert occupancy.unknown.tolist() == [[False, False, False], [True, False, False]]
    assert occupancy.blocked.tolist() == [[False, False, True], [True, False, True]]


def test_data_is_read_only():
    with pytest.raises(ValueError):
        small_map().data[0, 0] = 5


def test_occupancy_grid_layout_round_trip():
    occupancy = small_map()
    data = to_occupancy_grid_data(occupancy)
    assert data == [0, 0, 100, -1, 50, 70]  # row-major, bottom row first
    back = from_occupancy_grid(3, 2, 0.5, (-1.0, 2.0, 0.0), data)
    assert np.array_equal(back.data, occupancy.data) and back.origin == occupancy.origin


def test_occupancy_grid_with_the_wrong_size_is_rejected():
    with pytest.raises(MapError, match="field 'data': expected width x height = 3 x 2"):
        from_occupancy_grid(3, 2, 0.5, (0.0, 0.0, 0.0), [0] * 5)


@pytest.mark.parametrize(
    ('kwargs', 'field'),
    [
        ({'resolution': 0.0}, 'resolution'),
        ({'origin': (0.0, 0.0)}, 'origin'),
        ({'data': np.zeros((2, 2), bool)}, 'data'),
        ({'data': np.zeros(4, np.int8)}, 'data'),
    ],
)
def test_occupancy_map_rejects_bad_values(kwargs, field):
    values = {'data': np.zeros((2, 2), np.int8), 'resolution': 1.0, **kwargs}
    with pytest.raises(MapError, match=f"OccupancyMap: field '{field}'"):
        OccupancyMap(**values)


# --- bad input: one clear error naming file, field and expectation ------------------------------


def assert_map_error(yaml_path: Path, *parts: str) -> None:
    with pytest.raises(MapError) as raised:
        load_map(yaml_path)
    message = str(raised.value)
    assert str(yaml_path) in message
    for part in parts:
        assert part in message, message
    assert '\n' not in message


@pytest.fixture
def image(tmp_path) -> Path:
    return write_pgm(tmp_path / 'map.pgm', [[0, 254]])


def test_missing_yaml(tmp_path):
    assert_map_error(tmp_path / 'absent.yaml', 'cannot read map YAML', 'No such file')


def test_unreadable_yaml(tmp_path):
    (tmp_path / 'dir.yaml').mkdir()
    assert_map_error(tmp_path / 'dir.yaml', 'cannot read map YAML')


def test_yaml_that_is_not_text(tmp_path):
    (tmp_path / 'binary.yaml').write_bytes(b'\xff\xfe\x00image')
    assert_map_error(tmp_path / 'binary.yaml', 'cannot read map YAML')


def test_yaml_syntax_error(tmp_path):
    path = tmp_path / 'broken.yaml'
    path.write_text('image: map.pgm\norigin: [0, 0, 0\nresolution: 0.05\n')
    assert_map_error(path, 'YAML syntax error at line')


def test_yaml_that_is_not_a_mapping(tmp_path):
    path = tmp_path / 'list.yaml'
    path.write_text('- image\n- resolution\n')
    assert_map_error(path, 'expected a YAML mapping')


@pytest.mark.parametrize(
    'field', ['image', 'resolution', 'origin', 'negate', 'occupied_thresh', 'free_thresh']
)
def test_missing_field(tmp_path, image, field):
    assert_map_error(write_yaml(tmp_path, **{field: None}), f"field '{field}'", 'missing')


@pytest.mark.parametrize(
    ('field', 'value'),
    [
        ('image', '[1, 2]'),
        ('resolution', 'fine'),
        ('resolution', 'true'),
        ('negate', '2'),
        ('negate', '0.5'),
        ('occupied_thresh', 'high'),
        ('free_thresh', '[0.1]'),
        ('mode', '3'),
    ],
)
def test_wrongly_typed_field(tmp_path, image, field, value):
    assert_map_error(write_yaml(tmp_path, **{field: value}), f"field '{field}'", 'expected')


@pytest.mark.parametrize('value', ['0', '-1', '.nan', '.inf'])
def test_resolution_not_positive(tmp_path, image, value):
    assert_map_error(
        write_yaml(tmp_path, resolution=value), "field 'resolution'", 'expected a number > 0'
    )


@pytest.mark.parametrize('value', ['[0, 0]', '[0, 0, 0, 0]', '[0, a, 0]', '5', '[0, 0, .nan]'])
def test_origin_not_three_numbers(tmp_path, image, value):
    assert_map_error(
        write_yaml(tmp_path, origin=value), "field 'origin'", 'expected a list of 3 numbers'
    )


def test_thresholds_out_of_order(tmp_path, image):
    assert_map_error(
        write_yaml(tmp_path, free_thresh=0.7, occupied_thresh=0.65),
        "field 'free_thresh'",
        'smaller than occupied_thresh (0.65)',
    )


@pytest.mark.parametrize(
    ('field', 'value'), [('occupied_thresh', 1.5), ('free_thresh', -0.1), ('free_thresh', 2)]
)
def test_thresholds_outside_unit_interval(tmp_path, image, field, value):
    assert_map_error(
        write_yaml(tmp_path, **{field: value}), f"field '{field}'", 'a number in [0, 1]'
    )


def test_unknown_mode(tmp_path, image):
    assert_map_error(
        write_yaml(tmp_path, mode='binary'),
        "field 'mode'",
        'expected one of trinary, scale, raw',
        "'binary'",
    )


def test_missing_image(tmp_path):
    assert_map_error(
        write_yaml(tmp_path, image='absent.pgm'),
        "field 'image'",
        'a readable PGM or PNG file',
        'No such file',
    )


def test_unreadable_image(tmp_path):
    (tmp_path / 'folder.pgm').mkdir()
    assert_map_error(write_yaml(tmp_path, image='folder.pgm'), "field 'image'", 'readable')


@pytest.mark.parametrize(
    'content',
    [
        b'this is not an image',
        b'P5\n4 4\n255\n\x00\x00',  # truncated
        b'P5\n4\n',  # header cut short
        b'P5\nfour four\n255\n',
        b'\x89PNG\r\n\x1a\n garbage',
        b'',
    ],
)
def test_image_that_is_not_a_map(tmp_path, content):
    (tmp_path / 'map.pgm').write_bytes(content)
    assert_map_error(write_yaml(tmp_path), "field 'image'", 'expected a PGM or PNG map image')
