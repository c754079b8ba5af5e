"""Occupancy maps in nav2_map_server's format: load, save, transform, convert.

Loading follows nav2 Jazzy's ``map_io.cpp`` (``loadMapYaml`` + ``loadMapFromFile``) rule for rule,
so a map means the same here as it does to a nav2 map_server:

* the image is converted to 8-bit grey (colour: Rec. 601 luma, as GraphicsMagick does; 16-bit:
  scaled to 8 bits);
* trinary and scale modes compute, in 32-bit floats as nav2's Eigen code does,
  ``p = 1 - v/255`` (``p = v/255`` when ``negate``); ``p >= occupied_thresh`` is occupied (100),
  ``p <= free_thresh`` free (0), anything else unknown (-1) in trinary mode or
  ``round((p - free) / (occupied - free) * 100)`` in scale mode; then every pixel whose alpha is
  below 255 is unknown;
* raw mode keeps grey values 0..100 as they are and makes every other value unknown (alpha is
  ignored);
* rows are flipped, so row 0 of :attr:`OccupancyMap.data` is the bottom row (smallest y), exactly
  the order of ``nav_msgs/OccupancyGrid.data``.

Saving follows nav2 Jazzy's map_saver (``tryWriteMapToFile``): trinary writes a P5 PGM with 0
occupied, 254 free, 205 unknown and the fixed thresholds 0.65 / 0.196 in the YAML, so that a saved
map reloads identical.

The origin's yaw is read, kept and saved, but the world <-> cell transforms ignore it, as nav2's
costmap_2d and AMCL do (the ROS map_server documentation: "many parts of the system currently
ignore yaw"). The project's maps all have yaw 0.

Unlike nav2, which accepts any value it can parse, the loader also rejects maps nav2 would load
into something meaningless (resolution <= 0, thresholds outside [0, 1] or out of order), and every
error is one :class:`MapError` naming the file, the field and what was expected.
"""

import dataclasses
import math
import os
from pathlib import Path

import cv2
import numpy as np

from stealth_core.yaml_fields import FieldReader, read_yaml_mapping

FREE = 0
OCCUPIED = 100
UNKNOWN = -1
# A cell counts as occupied from this value on: what nav2's map_saver (occupied_thresh 0.65)
# writes as black. Trinary maps only hold 0, 100 and -1, so this matters for scale/raw maps only.
OCCUPIED_MIN = 65

MODES = ('trinary', 'scale', 'raw')
# Pixel values nav2's map_saver writes in trinary mode.
PIXEL_OCCUPIED = 0
PIXEL_FREE = 254
PIXEL_UNKNOWN = 205
# map_saver_cli's default thresholds for turning cell values into pixels.
SAVER_FREE_THRESH = 0.25
SAVER_OCCUPIED_THRESH = 0.65
# The thresholds nav2's saver writes for a trinary map: they separate 0 / 205 / 254 exactly.
TRINARY_OCCUPIED_THRESH = 0.65
TRINARY_FREE_THRESH = 0.196


class MapError(ValueError):
    """A map file or map value that cannot be used; the message names file, field, expectation."""


@dataclasses.dataclass(frozen=True)
class MapMetadata:
    """How a map was read from disk (nav2's LoadParameters), kept so it can be reported."""

    yaml_path: Path | None = None
    image_path: Path | None = None
    mode: str = 'trinary'
    negate: bool = False
    occupied_thresh: float = TRINARY_OCCUPIED_THRESH
    free_thresh: float = TRINARY_FREE_THRESH


@dataclasses.dataclass(frozen=True, eq=False)
class OccupancyMap:
    """An occupancy grid in nav_msgs/OccupancyGrid layout, immutable.

    ``data`` is int8 of shape (height, width); row 0 is the bottom row (smallest y). ``origin``
    is (x, y, yaw) of the lower-left corner of cell (0, 0); the transforms ignore yaw, as nav2's
    costmap and AMCL do. Cells are indexed (col, row) = (x, y) order in every method.
    """

    data: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    metadata: MapMetadata = MapMetadata()

    def __post_init__(self):
        fields = FieldReader(
            'OccupancyMap',
            {'resolution': self.resolution, 'origin': list(self.origin)},
            MapError,
        )
        resolution = fields.number('resolution', 'a number > 0', lambda r: r > 0)
        origin = fields.numbers('origin', 3, 'a list of 3 numbers [x, y, yaw]')
        data = np.asarray(self.data)
        if data.ndim != 2 or data.size == 0:
            fields.fail('data', 'a non-empty 2-D array (height, width)', f'shape {data.shape}')
        if data.dtype != np.int8:
            if not np.issubdtype(data.dtype, np.integer) or data.min() < -128 or data.max() > 127:
                fields.fail('data', 'int8 cell values', f'{data.dtype} values')
            data = data.astype(np.int8)
        data = np.array(data, dtype=np.int8, copy=True)
        data.flags.writeable = False
        object.__setattr__(self, 'data', data)
        object.__setattr__(self, 'resolution', resolution)
        object.__setattr__(self, 'origin', origin)

    @property
    def width(self) -> int:
        return self.data.shape[1]

    @property
    def height(self) -> int:
        return self.data.shape[0]

    @property
    def occupied(self) -> np.ndarray:
        """Cells whose value is at least OCCUPIED_MIN (65): what map_saver writes as black."""
        return self.data >= OCCUPIED_MIN

    @property
    def unknown(self) -> np.ndarray:
        return self.data == UNKNOWN

    @property
    def blocked(self) -> np.ndarray:
        """Occupied or unknown: both stop the robot and both stop light, as in the original."""
        return self.occupied | self.unknown

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of the map's area in the world frame."""
        x0, y0, _ = self.origin
        return x0, y0, x0 + self.width * self.resolution, y0 + self.height * self.resolution

    def world_to_cell(self, x, y):
        """The (col, row) of the cell holding (x, y): floor, so the lower/left edge is inside."""
        col = np.floor((np.asarray(x, dtype=float) - self.origin[0]) / self.resolution)
        row = np.floor((np.asarray(y, dtype=float) - self.origin[1]) / self.resolution)
        if col.ndim == 0:
            return int(col), int(row)
        return col.astype(np.int64), row.astype(np.int64)

    def cell_to_world(self, col, row):
        """The (x, y) of a cell's centre."""
        x = self.origin[0] + (np.asarray(col, dtype=float) + 0.5) * self.resolution
        y = self.origin[1] + (np.asarray(row, dtype=float) + 0.5) * self.resolution
        if x.ndim == 0:
            return float(x), float(y)
        return x, y

    def contains_cell(self, col, row):
        inside = (
            (np.asarray(col) >= 0)
            & (np.asarray(col) < self.width)
            & (np.asarray(row) >= 0)
            & (np.asarray(row) < self.height)
        )
        return bool(inside) if inside.ndim == 0 else inside

    def contains_point(self, x, y):
        return self.contains_cell(*self.world_to_cell(x, y))

    def value_at(self, x: float, y: float) -> int:
        """The cell value under a point; a point outside the map is UNKNOWN."""
        col, row = self.world_to_cell(x, y)
        return int(self.data[row, col]) if self.contains_cell(col, row) else UNKNOWN


# --- loading ------------------------------------------------------------------------------------


def load_map(yaml_path: str | os.PathLike) -> OccupancyMap:
    """Load a nav2_map_server map (YAML + image) exactly as nav2 Jazzy's map_server does."""
    yaml_path = Path(yaml_path).expanduser()
    fields = FieldReader(yaml_path, read_yaml_mapping(yaml_path, MapError, 'map YAML'), MapError)
    metadata = _read_metadata(fields, yaml_path)
    resolution = fields.number('resolution', 'a number > 0', lambda r: r > 0)
    origin = fields.numbers('origin', 3, 'a list of 3 numbers [x, y, yaw]')
    grey, alpha = _read_image(metadata.image_path, fields)
    data = occupancy_from_pixels(grey, alpha, metadata)
    return OccupancyMap(data, resolution, origin, metadata)


def _read_metadata(fields: FieldReader, yaml_path: Path) -> MapMetadata:
    image = fields.string('image', 'the image file name (a non-empty string)')
    image_path = Path(image) if os.path.isabs(image) else yaml_path.parent / image
    mode = fields.string('mode', f'one of {", ".join(MODES)}', default='trinary')
    if mode.lower() not in MODES:
        fields.fail('mode', f'one of {", ".join(MODES)}', mode)
    # nav2 reads negate as an int, else as a bool; anything but 0/1/true/false is a mistake.
    negate = fields.raw('negate', '0, 1, true or false')
    if not isinstance(negate, bool) and not (isinstance(negate, int) and negate in (0, 1)):
        fields.fail('negate', '0, 1, true or false', negate)
    in_unit = 'a number in [0, 1]'
    occupied = fields.number('occupied_thresh', in_unit, lambda t: 0 <= t <= 1)
    free = fields.number('free_thresh', in_unit, lambda t: 0 <= t <= 1)
    if not free < occupied:
        fields.fail('free_thresh', f'a number smaller than occupied_thresh ({occupied:g})', free)
    return MapMetadata(yaml_path, image_path, mode.lower(), bool(negate), occupied, free)


def _read_image(path: Path, fields: FieldReader) -> tuple[np.ndarray, np.ndarray | None]:
    try:
        encoded = path.read_bytes()
    except OSError as exc:
        fields.fail_with('image', 'a readable PGM or PNG file', f'{path} ({exc.strerror})')
    try:
        return decode_image(encoded)
    except ValueError as exc:
        fields.fail_with('image', 'a PGM or PNG map image', f'{path} ({exc})')


def decode_image(encoded: bytes) -> tuple[np.ndarray, np.ndarray | None]:
    """Decode image bytes into 8-bit grey (H, W) and alpha (H, W) or None, as GraphicsMagick.

    PGMs are parsed here because OpenCV does not scale a maxval other than 255/65535.
    """
    if encoded[:2] in (b'P2', b'P5'):
        return _decode_pgm(encoded), None
    pixels = None
    if encoded:
        try:
            pixels = cv2.imdecode(np.frombuffer(encoded, np.uint8), cv2.IMREAD_UNCHANGED)
        except cv2.error:
            pixels = None
    if pixels is None:
        raise ValueError('not a decodable image')
    if pixels.dtype == np.uint16:
        pixels = ((pixels.astype(np.uint32) + 128) // 257).astype(np.uint8)
    elif pixels.dtype != np.uint8:
        raise ValueError(f'{pixels.dtype} pixels, expected 8- or 16-bit')
    if pixels.ndim == 3 and pixels.shape[2] == 1:
        pixels = pixels[:, :, 0]
    if pixels.ndim == 2:
        return pixels, None
    if pixels.ndim != 3 or pixels.shape[2] not in (3, 4):
        raise ValueError(f'pixel array of shape {pixels.shape}, expected grey, BGR or BGRA')
    grey = rec601_luma(pixels[:, :, :3])
    alpha = pixels[:, :, 3] if pixels.shape[2] == 4 else None
    return grey, alpha


def round_half_away(values: np.ndarray) -> np.ndarray:
    """Round halves away from zero as C++ std::round and Eigen do; numpy rounds them to even."""
    whole = np.trunc(values)
    return whole + np.sign(values) * (np.abs(values - whole) >= 0.5)


def rec601_luma(bgr: np.ndarray) -> np.ndarray:
    """GraphicsMagick's grey of a colour pixel: 0.299 R + 0.587 G + 0.114 B, rounded."""
    b, g, r = (bgr[:, :, i].astype(np.float64) for i in range(3))
    return np.floor(0.299 * r + 0.587 * g + 0.114 * b + 0.5).astype(np.uint8)


def _decode_pgm(encoded: bytes) -> np.ndarray:
    tokens, position = [], 2
    while len(tokens) < 3:
        while position < len(encoded) and encoded[position : position + 1].isspace():
            position += 1
        if encoded[position : position + 1] == b'#':
            position = encoded.find(b'\n', position)
            if position < 0:
                raise ValueError('truncated PGM header')
            continue
        start = position
        while position < len(encoded) and not encoded[position : position + 1].isspace():
            position += 1
        if start == position:
            raise ValueError('truncated PGM header')
        tokens.append(encoded[start:position])
    try:
        width, height, maxval = (int(t) for t in tokens)
    except ValueError:
        raise ValueError('malformed PGM header') from None
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        raise ValueError(f'PGM of {width} x {height} pixels with maxval {maxval}')
    body = encoded[position + 1 :]
    if encoded[:2] == b'P2':
        values = np.array(body.split(), dtype=np.int64)
    else:
        dtype = np.dtype('>u2' if maxval > 255 else 'u1')
        values = np.frombuffer(body, dtype, count=min(width * height, len(body) // dtype.itemsize))
    if values.size != width * height or values.max(initial=0) > maxval:
        raise ValueError(f'PGM data does not hold {width} x {height} pixels of at most {maxval}')
    scaled = np.floor(values.astype(np.float64) * 255.0 / maxval + 0.5)
    return scaled.astype(np.uint8).reshape(height, width)


def occupancy_from_pixels(
    grey: np.ndarray, alpha: np.ndarray | None, metadata: MapMetadata
) -> np.ndarray:
    """nav2 Jazzy's loadMapFromFile on decoded pixels: cell values, bottom row first."""
    if metadata.mode == 'raw':
        cells = np.where(grey <= OCCUPIED, grey, UNKNOWN).astype(np.int8)
        return np.flipud(cells)
    occupancy = grey.astype(np.float32) / np.float32(255.0)
    if not metadata.negate:
        occupancy = np.float32(1.0) - occupancy
    free_thresh = np.float32(metadata.free_thresh)
    occupied_thresh = np.float32(metadata.occupied_thresh)
    cells = np.full(grey.shape, UNKNOWN, dtype=np.int8)
    cells[occupancy >= occupied_thresh] = OCCUPIED
    cells[occupancy <= free_thresh] = FREE
    if metadata.mode == 'scale':
        between = (occupancy > free_thresh) & (occupancy < occupied_thresh)
        span = np.float32(metadata.occupied_thresh - metadata.free_thresh)
        scaled = (occupancy - free_thresh) / span * np.float32(100.0)
        cells[between] = round_half_away(scaled[between]).astype(np.int8)
    if alpha is not None:
        cells[alpha < 255] = UNKNOWN
    return np.flipud(cells)


# --- saving -------------------------------------------------------------------------------------


def save_map(
    occupancy_map: OccupancyMap,
    stem: str | os.PathLike,
    mode: str = 'trinary',
    free_thresh: float = SAVER_FREE_THRESH,
    occupied_thresh: float = SAVER_OCCUPIED_THRESH,
) -> Path:
    """Write ``<stem>.pgm`` (``.png`` in scale mode) and ``<stem>.yaml`` as nav2's map_saver does.

    The thresholds decide which cell values become which pixels (map_saver's parameters); the
    YAML of a trinary map carries the fixed 0.65 / 0.196 that separate those pixels again.
    Returns the YAML's path.
    """
    fields = FieldReader(
        'save_map',
        {'mode': mode, 'free_thresh': free_thresh, 'occupied_thresh': occupied_thresh},
        MapError,
    )
    if mode not in MODES:
        fields.fail('mode', f'one of {", ".join(MODES)}', mode)
    occupied_thresh = fields.number('occupied_thresh', 'a number in [0, 1]', lambda t: 0 <= t <= 1)
    free_thresh = fields.number(
        'free_thresh', f'a number in [0, {occupied_thresh:g})', lambda t: 0 <= t < occupied_thresh
    )
    stem = Path(stem)
    image_path = stem.with_name(stem.name + ('.png' if mode == 'scale' else '.pgm'))
    yaml_path = stem.with_name(stem.name + '.yaml')
    pixels = pixels_from_occupancy(occupancy_map.data, mode, free_thresh, occupied_thresh)
    if mode == 'scale':
        image_bytes = cv2.imencode('.png', pixels)[1].tobytes()
    else:
        image_bytes = pgm_bytes(pixels)
    if mode == 'trinary':
        thresholds = (f'{TRINARY_OCCUPIED_THRESH:g}', f'{TRINARY_FREE_THRESH:g}')
    else:
        thresholds = (f'{occupied_thresh:.3f}', f'{free_thresh:.3f}')
    x, y, yaw = occupancy_map.origin
    yaw = math.atan2(math.sin(yaw), math.cos(yaw))  # what tf2's getEulerYPR gives back
    text = (
        f'image: {image_path.name}\n'
        f'mode: {mode}\n'
        f'resolution: {occupancy_map.resolution:.3f}\n'
        f'origin: [{x:.3f}, {y:.3f}, {yaw:.7g}]\n'
        'negate: 0\n'
        f'occupied_thresh: {thresholds[0]}\n'
        f'free_thresh: {thresholds[1]}'  # yaml-cpp's emitter ends without a newline
    )
    try:
        image_path.write_bytes(image_bytes)
        yaml_path.write_text(text, encoding='utf-8')
    except OSError as exc:
        raise MapError(f'{exc.filename}: cannot write map: {exc.strerror}') from None
    return yaml_path


def pixels_from_occupancy(
    cells: np.ndarray, mode: str, free_thresh: float, occupied_thresh: float
) -> np.ndarray:
    """nav2 Jazzy's map_saver pixel rules; top image row first. Scale mode gives BGRA."""
    cells = np.flipud(np.asarray(cells, dtype=np.int16))
    outside = (cells < 0) | (cells > 100)
    if mode == 'trinary':
        pixels = np.full(cells.shape, PIXEL_UNKNOWN, np.uint8)
        pixels[cells <= round(free_thresh * 100)] = PIXEL_FREE
        pixels[cells >= round(occupied_thresh * 100)] = PIXEL_OCCUPIED
        pixels[outside] = PIXEL_UNKNOWN
        return pixels
    if mode == 'raw':
        return np.where(outside, 255, cells).astype(np.uint8)
    grey = np.floor((100 - cells) / 100 * 255 + 0.5)
    grey = np.where(outside, 128, grey).astype(np.uint8)
    alpha = np.where(outside, 0, 255).astype(np.uint8)
    return np.dstack([grey, grey, grey, alpha])


def pgm_bytes(pixels: np.ndarray) -> bytes:
    """A binary (P5) 8-bit PGM with the header GraphicsMagick writes."""
    height, width = pixels.shape
    return f'P5\n{width} {height}\n255\n'.encode('ascii') + pixels.astype(np.uint8).tobytes()


# --- nav_msgs/OccupancyGrid layout ------------------------------------------------------------


def to_occupancy_grid_data(occupancy_map: OccupancyMap) -> list[int]:
    """The map's cells as nav_msgs/OccupancyGrid.data: row-major, bottom row first."""
    return occupancy_map.data.ravel().tolist()


def from_occupancy_grid(
    width: int,
    height: int,
    resolution: float,
    origin: tuple[float, float, float],
    data,
) -> OccupancyMap:
    """Build a map from the fields of a nav_msgs/OccupancyGrid (origin yaw already extracted)."""
    cells = np.asarray(data)
    if width <= 0 or height <= 0 or cells.size != width * height:
        raise MapError(
            f"OccupancyGrid: field 'data': expected width x height = {width} x {height} "
            f'cells, got {cells.size}'
        )
    return OccupancyMap(cells.reshape(height, width), resolution, tuple(origin))
