"""Map tools: drawn image -> clean black-and-white PNG -> nav2 map (PGM + YAML) -> picture.

``image_to_bw`` and ``png_to_ros_map`` replace the original system's scripts of the same names;
``render_map`` draws a map for the documentation. Run them as console scripts or, before colcon
has built anything, as ``python -m stealth_sim.map_tools {image-to-bw,png-to-ros-map,render}``.

Unknown space is marked by transparency: a pixel whose alpha is below 255 is unknown, which is
nav2's own rule for images with an alpha channel. ``image_to_bw`` keeps it (the output is then a
BGRA PNG whose transparent pixels are grey 205, what map_saver writes for unknown), and
``png_to_ros_map`` turns it into 205 in the PGM.
"""

import argparse
from collections.abc import Callable, Sequence
import math
import os
from pathlib import Path
import sys

import cv2
import numpy as np
from stealth_core.occupancy_map import (
    PIXEL_UNKNOWN,
    TRINARY_FREE_THRESH,
    TRINARY_OCCUPIED_THRESH,
    MapError,
    MapMetadata,
    OccupancyMap,
    decode_image,
    load_map,
    occupancy_from_pixels,
    save_map,
)

WHITE = 255
BLACK = 0


class ToolError(ValueError):
    """A problem with a tool's input or output, reported as one line."""


def read_image(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Grey (H, W) and alpha (H, W) or None, converted as nav2's loader converts map images."""
    try:
        encoded = Path(path).read_bytes()
    except OSError as exc:
        raise ToolError(f'{path}: cannot read image: {exc.strerror}') from None
    try:
        return decode_image(encoded)
    except ValueError as exc:
        raise ToolError(f'{path}: not an image this tool can read: {exc}') from None


def write_png(path: str | os.PathLike, pixels: np.ndarray) -> None:
    ok, encoded = cv2.imencode('.png', pixels)
    try:
        if not ok:
            raise OSError(0, 'PNG encoding failed', str(path))
        Path(path).write_bytes(encoded.tobytes())
    except OSError as exc:
        raise ToolError(f'{path}: cannot write image: {exc.strerror}') from None


# --- image_to_bw --------------------------------------------------------------------------------


def otsu_level(grey: np.ndarray, opaque: np.ndarray) -> int:
    """Otsu's threshold over the opaque pixels only, so unknown areas do not skew it."""
    if not opaque.any():
        return 127
    level, _ = cv2.threshold(
        grey[opaque].reshape(1, -1), 0, WHITE, cv2.THRESH_BINARY | cv2.THRESH_OTSU
    )
    return int(level)


def remove_speckles(is_white: np.ndarray, opaque: np.ndarray, min_area: int) -> np.ndarray:
    """Flip black or white blobs (8-connected) of fewer than ``min_area`` opaque pixels.

    Both colours are judged on the thresholded image before any flip, so the result does not
    depend on which colour is cleaned first.
    """
    cleaned = is_white.copy()
    for colour in (True, False):
        blobs = (is_white == colour) & opaque
        count, labels, stats, _ = cv2.connectedComponentsWithStats(
            blobs.astype(np.uint8), connectivity=8
        )
        small = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] < min_area)
        small = small[small != 0]  # label 0 is the background
        cleaned[np.isin(labels, small)] = not colour
    return cleaned


def to_black_and_white(
    grey: np.ndarray, alpha: np.ndarray | None, level: int | None = None, despeckle: int = 0
) -> np.ndarray:
    """A clean map image: opaque pixels black or white, unknown (alpha < 255) kept.

    Pixels brighter than ``level`` (Otsu's choice when None) become white, i.e. free.
    Returns grey (H, W) when nothing is unknown, else BGRA whose unknown pixels are
    transparent grey 205.
    """
    opaque = np.ones(grey.shape, bool) if alpha is None else alpha == 255
    threshold = otsu_level(grey, opaque) if level is None else level
    is_white = grey > threshold
    if despeckle > 1:
        is_white = remove_speckles(is_white, opaque, despeckle)
    bw = np.where(is_white, WHITE, BLACK).astype(np.uint8)
    if opaque.all():
        return bw
    bw[~opaque] = PIXEL_UNKNOWN
    return np.dstack([bw, bw, bw, np.where(opaque, 255, 0).astype(np.uint8)])


def image_to_bw(
    source: str | os.PathLike,
    output: str | os.PathLike,
    level: int | None = None,
    despeckle: int = 0,
) -> None:
    grey, alpha = read_image(source)
    write_png(output, to_black_and_white(grey, alpha, level, despeckle))


# --- png_to_ros_map -----------------------------------------------------------------------------


def png_to_ros_map(
    source: str | os.PathLike,
    stem: str | os.PathLike,
    resolution: float,
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    negate: bool = False,
    occupied_thresh: float = TRINARY_OCCUPIED_THRESH,
    free_thresh: float = TRINARY_FREE_THRESH,
) -> Path:
    """Read an image as nav2's map_server would and save it as nav2's map_saver would.

    Returns the YAML's path; the PGM beside it holds 0 occupied, 254 free, 205 unknown.
    """
    if not (math.isfinite(resolution) and resolution > 0):
        raise ToolError(f'--resolution: expected a number > 0, got {resolution:g}')
    if not 0 <= free_thresh < occupied_thresh <= 1:
        raise ToolError(
            f'--free-thresh {free_thresh:g} / --occupied-thresh {occupied_thresh:g}: '
            'expected 0 <= free < occupied <= 1'
        )
    grey, alpha = read_image(source)
    rules = MapMetadata(
        mode='trinary', negate=negate, occupied_thresh=occupied_thresh, free_thresh=free_thresh
    )
    cells = occupancy_from_pixels(grey, alpha, rules)
    return save_map(OccupancyMap(cells, resolution, tuple(origin)), stem)


# --- render -------------------------------------------------------------------------------------


def render_map(
    occupancy_map: OccupancyMap, output: str | os.PathLike, title: str = '', dpi: int = 100
) -> None:
    """A picture of a map in metres: free white, occupied black, unknown grey."""
    import matplotlib

    matplotlib.use('Agg')
    from matplotlib import pyplot as plt

    shade = np.full(occupancy_map.data.shape, 1.0)
    shade[occupancy_map.unknown] = 0.8
    shade[occupancy_map.occupied] = 0.0
    x_min, y_min, x_max, y_max = occupancy_map.bounds
    width_m, height_m = x_max - x_min, y_max - y_min
    scale = 7.0 / max(width_m, height_m)
    figure, axes = plt.subplots(figsize=(width_m * scale + 1.2, height_m * scale + 1.0))
    axes.imshow(
        shade,
        cmap='gray',
        vmin=0.0,
        vmax=1.0,
        origin='lower',
        extent=(x_min, x_max, y_min, y_max),
        interpolation='nearest',
    )
    axes.set_xlabel('x [m]')
    axes.set_ylabel('y [m]')
    if title:
        axes.set_title(title)
    figure.tight_layout()
    try:
        figure.savefig(output, dpi=dpi, metadata={'Software': None})
    except OSError as exc:
        raise ToolError(f'{output}: cannot write picture: {exc.strerror}') from None
    finally:
        plt.close(figure)


# --- command line -------------------------------------------------------------------------------


def _add_image_to_bw_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('input', help='the drawn or scanned image (any format OpenCV reads)')
    parser.add_argument(
        '-o', '--output', help='the black-and-white PNG to write (default: INPUT_bw.png)'
    )
    parser.add_argument(
        '--level',
        type=int,
        choices=range(256),
        metavar='0-255',
        help='grey level above which a pixel is white/free (default: Otsu over opaque pixels)',
    )
    parser.add_argument(
        '--despeckle',
        type=int,
        default=0,
        metavar='PIXELS',
        help='turn black or white blobs smaller than PIXELS into the other colour (default: off)',
    )


def _run_image_to_bw(args: argparse.Namespace) -> None:
    source = Path(args.input)
    output = args.output or source.with_name(source.stem + '_bw.png')
    image_to_bw(source, output, args.level, args.despeckle)


def _add_png_to_ros_map_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('input', help='the black-and-white map image (PNG; alpha < 255 = unknown)')
    parser.add_argument(
        '-o',
        '--output',
        metavar='STEM',
        help='write STEM.pgm and STEM.yaml (default: INPUT without its extension)',
    )
    parser.add_argument(
        '--resolution', type=float, required=True, help='metres per pixel, e.g. 0.05'
    )
    parser.add_argument(
        '--origin',
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=('X', 'Y', 'YAW'),
        help='world pose of the lower-left pixel corner, metres and radians (default: 0 0 0)',
    )
    parser.add_argument(
        '--negate', action='store_true', help='white is occupied and black free in the image'
    )
    parser.add_argument(
        '--occupied-thresh',
        type=float,
        default=TRINARY_OCCUPIED_THRESH,
        help=f'occupancy p = 1 - grey/255 from which a pixel is occupied (default: '
        f'{TRINARY_OCCUPIED_THRESH})',
    )
    parser.add_argument(
        '--free-thresh',
        type=float,
        default=TRINARY_FREE_THRESH,
        help=f'occupancy up to which a pixel is free (default: {TRINARY_FREE_THRESH})',
    )


def _run_png_to_ros_map(args: argparse.Namespace) -> None:
    source = Path(args.input)
    stem = args.output or source.with_suffix('')
    png_to_ros_map(
        source,
        stem,
        args.resolution,
        tuple(args.origin),
        args.negate,
        args.occupied_thresh,
        args.free_thresh,
    )


def _add_render_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('map', help='the nav2 map YAML')
    parser.add_argument('-o', '--output', required=True, help='the PNG picture to write')
    parser.add_argument('--title', default='', help='a title above the picture')
    parser.add_argument('--dpi', type=int, default=100, help='pixels per inch (default: 100)')


def _run_render(args: argparse.Namespace) -> None:
    render_map(load_map(args.map), args.output, args.title, args.dpi)


TOOLS: dict[str, tuple[str, str, Callable, Callable]] = {
    'image-to-bw': (
        'image_to_bw',
        'Clean a drawn map image into a black-and-white PNG: grey, threshold (Otsu by default), '
        'optional speckle removal; transparent pixels (unknown) stay transparent.',
        _add_image_to_bw_arguments,
        _run_image_to_bw,
    ),
    'png-to-ros-map': (
        'png_to_ros_map',
        'Turn a black-and-white PNG into a nav2 map (PGM + YAML) as nav2 map_server reads it '
        'and map_saver writes it: 0 occupied, 254 free, 205 unknown (transparent pixels).',
        _add_png_to_ros_map_arguments,
        _run_png_to_ros_map,
    ),
    'render': (
        'render_map',
        'Draw a nav2 map as a PNG picture in metres: free white, occupied black, unknown grey.',
        _add_render_arguments,
        _run_render,
    ),
}


def run_tool(tool: str, argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` for one tool and run it; a bad input is one line on stderr, exit code 2."""
    prog, description, add_arguments, run = TOOLS[tool]
    parser = argparse.ArgumentParser(prog=prog, description=description)
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        run(args)
    except (ToolError, MapError) as exc:
        print(f'{prog}: error: {exc}', file=sys.stderr)
        return 2
    return 0


def image_to_bw_main(argv: Sequence[str] | None = None) -> int:
    return run_tool('image-to-bw', argv)


def png_to_ros_map_main(argv: Sequence[str] | None = None) -> int:
    return run_tool('png-to-ros-map', argv)


def render_map_main(argv: Sequence[str] | None = None) -> int:
    return run_tool('render', argv)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m stealth_sim.map_tools TOOL ...``: every tool under one command."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] not in TOOLS:
        names = ', '.join(TOOLS)
        if argv and argv[0] in ('-h', '--help'):
            print(f'usage: python -m stealth_sim.map_tools {{{names}}} [-h] ...\n\n{__doc__}')
            return 0
        print(
            f'map_tools: error: expected a tool name ({names}), got {argv[0] if argv else None!r}',
            file=sys.stderr,
        )
        return 2
    return run_tool(argv[0], argv[1:])


if __name__ == '__main__':
    sys.exit(main())
