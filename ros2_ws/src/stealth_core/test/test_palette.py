"""The palette's three forms show one thing in one colour: the markers' and the frames' colours
are the pictures' colours, and the markers' heatmap is the pictures' colour map."""

from matplotlib import colormaps
from matplotlib.colors import to_rgb
import numpy as np
import pytest
from stealth_core import palette


def rounded(colour, decimals=3):
    return tuple(round(value, decimals) for value in to_rgb(colour))


@pytest.mark.parametrize(
    'marker, picture',
    [
        (palette.MARKER_LIGHT, palette.LIGHT),
        (palette.MARKER_MOTION, palette.LIGHT),
        (palette.MARKER_LAMP, palette.LAMP),
        (palette.MARKER_START, palette.START),
        (palette.MARKER_GOAL, palette.GOAL),
    ],
)
def test_a_marker_has_its_pictures_colour(marker, picture):
    assert marker[:3] == rounded(picture) and 0.0 < marker[3] <= 1.0


@pytest.mark.parametrize(
    'frame, picture',
    [
        (palette.FRAME_PATH, palette.PATHS[0]),
        (palette.FRAME_ROBOT, palette.START),
        (palette.FRAME_GOAL, palette.GOAL),
    ],
)
def test_a_frame_has_its_pictures_colour(frame, picture):
    assert frame == tuple(round(255 * value) for value in to_rgb(picture))


def test_the_markers_heatmap_is_the_pictures_colour_map():
    stops = np.array(palette.MARKER_HEATMAP_STOPS)
    colour_map = colormaps[palette.HEATMAP]
    expected = [colour_map(at)[:3] for at in np.linspace(0.0, 1.0, len(stops))]
    np.testing.assert_allclose(stops, expected, atol=0.005)  # the colour map's 256 levels
    assert palette.MARKER_DETECTION[:3] == tuple(stops[3])  # the heat of a bright light
