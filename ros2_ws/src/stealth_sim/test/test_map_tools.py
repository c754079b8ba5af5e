"""image_to_bw, png_to_ros_map and render: behaviour, command lines, and the shipped maps."""

import os
from pathlib import Path
import re
import subprocess
import sys

import cv2
import numpy as np
import pytest
from stealth_core.occupancy_map import load_map
from stealth_sim.map_tools import (
    image_to_bw_main,
    main,
    png_to_ros_map_main,
    render_map_main,
    to_black_and_white,
)

REPO = Path(__file__).resolve().parents[4]
PACKAGE_ROOT = Path(__file__).resolve().parents[1]


def write_png(path: Path, pixels) -> Path:
    path.write_bytes(cv2.imencode('.png', np.asarray(pixels, np.uint8))[1].tobytes())
    return path


def read_png(path: Path) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(path.read_bytes(), np.uint8), cv2.IMREAD_UNCHANGED)


# --- image_to_bw --------------------------------------------------------------------------------


def test_otsu_separates_ink_from_paper():
    rng = np.random.default_rng(0)
    ink = rng.random((40, 40)) < 0.3
    grey = np.where(ink, 40, 215) + rng.integers(-25, 26, (40, 40))
    bw = to_black_and_white(grey.astype(np.uint8), None)
    assert set(np.unique(bw)) <= {0, 255}
    assert np.array_equal(bw == 0, ink)


def test_a_given_level_overrides_otsu():
    grey = np.array([[10, 100, 101, 250]], np.uint8)
    assert to_black_and_white(grey, None, level=100).tolist() == [[0, 0, 255, 255]]


def test_despeckle_removes_small_blobs_of_either_colour_and_keeps_larger_ones():
    grey = np.full((20, 20), 255, np.uint8)
    grey[2, 2] = 0  # a speck of dust
    grey[10:13, 10:13] = 0  # a chair leg, 9 pixels
    grey[0:6, 14:20] = 0
    grey[2, 17] = 255  # a pin hole in a wall
    bw = to_black_and_white(grey, None, despeckle=6)
    assert bw[2, 2] == 255 and bw[2, 17] == 0
    assert (bw[10:13, 10:13] == 0).all()
    assert (to_black_and_white(grey, None)[2, 2]) == 0  # off by default


def test_transparent_pixels_stay_unknown():
    grey = np.full((3, 4), 230, np.uint8)
    grey[:, 0] = 20
    alpha = np.full((3, 4), 255, np.uint8)
    alpha[:, 3] = 0
    alpha[0, 2] = 254
    bw = to_black_and_white(grey, alpha)
    assert bw.shape == (3, 4, 4)
    assert bw[:, :, 3].tolist() == [[255, 255, 0, 0], [255, 255, 255, 0], [255, 255, 255, 0]]
    assert bw[0, 2, 0] == 205 and bw[1, 0, 0] == 0 and bw[1, 1, 0] == 255


def test_image_to_bw_command(tmp_path):
    source = write_png(tmp_path / 'drawn.png', [[[0, 0, 200], [250, 250, 250]]])  # red, white
    assert image_to_bw_main([str(source), '-o', str(tmp_path / 'bw.png')]) == 0
    assert read_png(tmp_path / 'bw.png').tolist() == [[0, 255]]
    assert image_to_bw_main([str(source)]) == 0  # default output beside the input
    assert (tmp_path / 'drawn_bw.png').exists()


# --- png_to_ros_map -----------------------------------------------------------------------------


def test_png_to_ros_map_keeps_unknown(tmp_path):
    bgra = np.zeros((2, 3, 4), np.uint8)
    bgra[..., 3] = 255
    bgra[0, 0, :3] = 255  # free, top left
    bgra[1, 2, 3] = 0  # unknown, bottom right
    source = write_png(tmp_path / 'bw.png', bgra)
    output = ['-o', str(tmp_path / 'out')]
    code = png_to_ros_map_main(
        [str(source), *output, '--resolution', '0.1', '--origin', '-2', '3', '0']
    )
    assert code == 0
    assert (tmp_path / 'out.pgm').read_bytes() == b'P5\n3 2\n255\n' + bytes([254, 0, 0, 0, 0, 205])
    occupancy = load_map(tmp_path / 'out.yaml')
    assert occupancy.data.tolist() == [[100, 100, -1], [0, 100, 100]]
    assert occupancy.resolution == 0.1 and occupancy.origin == (-2.0, 3.0, 0.0)


def test_png_to_ros_map_negate(tmp_path):
    source = write_png(tmp_path / 'inverse.png', [[0, 255]])
    assert png_to_ros_map_main([str(source), '--resolution', '1', '--negate']) == 0
    assert load_map(tmp_path / 'inverse.yaml').data.tolist() == [[0, 100]]


def test_render_writes_a_picture(tmp_path):
    source = write_png(tmp_path / 'bw.png', [[0, 255], [255, 255]])
    assert png_to_ros_map_main([str(source), '--resolution', '0.5']) == 0
    picture = tmp_path / 'picture.png'
    assert render_map_main([str(tmp_path / 'bw.yaml'), '-o', str(picture), '--title', 'x']) == 0
    assert read_png(picture).shape[0] > 100


# --- command lines ------------------------------------------------------------------------------


@pytest.mark.parametrize('entry', [image_to_bw_main, png_to_ros_map_main, render_map_main])
def test_every_tool_has_help(entry, capsys):
    with pytest.raises(SystemExit) as raised:
        entry(['--help'])
    assert raised.value.code == 0
    assert 'usage:' in capsys.readouterr().out


def test_module_dispatch(capsys):
    assert main(['--help']) == 0
    assert 'image-to-bw' in capsys.readouterr().out
    assert main(['no-such-tool']) == 2
    assert 'map_tools: error:' in capsys.readouterr().err


@pytest.mark.parametrize(
    ('entry', 'prog', 'arguments', 'complaint'),
    [
        (image_to_bw_main, 'image_to_bw', ['absent.png'], 'cannot read image'),
        (image_to_bw_main, 'image_to_bw', ['text.png'], 'not an image'),
        (image_to_bw_main, 'image_to_bw', ['ok.png', '-o', 'no/dir/out.png'], 'cannot write'),
        (png_to_ros_map_main, 'png_to_ros_map', ['ok.png', '--resolution', '-1'], 'resolution'),
        (
            png_to_ros_map_main,
            'png_to_ros_map',
            ['ok.png', '--resolution', '1', '--free-thresh', '0.9'],
            'expected 0 <= free < occupied <= 1',
        ),
        (png_to_ros_map_main, 'png_to_ros_map', ['absent.png', '--resolution', '1'], 'absent'),
        (render_map_main, 'render_map', ['absent.yaml', '-o', 'x.png'], 'cannot read map YAML'),
    ],
)
def test_bad_input_is_one_line_and_exit_code_2(
    tmp_path, monkeypatch, capsys, entry, prog, arguments, complaint
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / 'text.png').write_text('not a picture')
    write_png(tmp_path / 'ok.png', [[0, 255]])
    assert entry(arguments) == 2
    error = capsys.readouterr().err
    assert error.startswith(f'{prog}: error: ') and complaint in error
    assert error.count('\n') == 1 and 'Traceback' not in error


def test_python_m_runs_without_a_traceback(tmp_path):
    # the package from its source, with the world model it reads maps with
    source = os.pathsep.join(str(p) for p in (PACKAGE_ROOT, PACKAGE_ROOT.parent / 'stealth_core'))
    environment = {**os.environ, 'PYTHONPATH': source}
    result = subprocess.run(
        [sys.executable, '-m', 'stealth_sim.map_tools', 'image-to-bw', str(tmp_path / 'no.png')],
        capture_output=True,
        text=True,
        env=environment,
        check=False,
    )
    assert result.returncode == 2
    assert result.stderr.startswith('image_to_bw: error: ') and 'Traceback' not in result.stderr


# --- the shipped maps ---------------------------------------------------------------------------


def make_variables() -> dict[str, str]:
    """The simple ``NAME := value`` assignments of maps/maps.mk, which the rebuild must use."""
    text = (REPO / 'maps' / 'maps.mk').read_text()
    return dict(re.findall(r'^([\w-]+) := (.*)$', text, flags=re.MULTILINE))


MAKE = make_variables()
SHIPPED = MAKE['MAP_NAMES'].split()
# Cells (width, height) at 0.05 m: 30 x 30, 20 x 20, 40 x 25 and 15 x 15 m.
SIZES = {
    'lgfloor': (600, 600),
    'map1': (400, 400),
    'floorplan': (800, 500),
    'simple-maze': (300, 300),
}


def test_four_maps_are_shipped():
    assert sorted(SHIPPED) == sorted(SIZES)


@pytest.mark.parametrize('name', SHIPPED)
def test_tools_rebuild_the_shipped_map_byte_identical(tmp_path, name):
    bw = tmp_path / f'{name}_bw.png'
    source = REPO / 'maps' / 'src' / f'{name}.png'
    despeckle = ['--despeckle', MAKE['MAP_DESPECKLE']]
    assert image_to_bw_main([str(source), '-o', str(bw), *despeckle]) == 0
    origin = MAKE[f'MAP_ORIGIN_{name}'].split()
    resolution = MAKE['MAP_RESOLUTION']
    arguments = [str(bw), '-o', str(tmp_path / name), '--resolution', resolution, '--origin']
    assert png_to_ros_map_main([*arguments, *origin]) == 0
    for suffix in ('.pgm', '.yaml'):
        shipped = (REPO / 'maps' / f'{name}{suffix}').read_bytes()
        assert (tmp_path / f'{name}{suffix}').read_bytes() == shipped, f'{name}{suffix}'


@pytest.mark.parametrize('name', SHIPPED)
def test_shipped_map_loads(name):
    occupancy = load_map(REPO / 'maps' / f'{name}.yaml')
    assert (occupancy.width, occupancy.height) == SIZES[name]
    assert occupancy.resolution == 0.05
    assert occupancy.occupied.any() and (occupancy.data == 0).any()
    assert set(np.unique(occupancy.data)) <= {0, 100, -1}


def test_lgfloor_has_unknown_space_around_it():
    occupancy = load_map(REPO / 'maps' / 'lgfloor.yaml')
    border = np.concatenate(
        [occupancy.data[0], occupancy.data[-1], occupancy.data[:, 0], occupancy.data[:, -1]]
    )
    assert (border == -1).all()
    assert occupancy.unknown.mean() > 0.3
