"""Draw the source images of the project's four maps: ``python maps/src/draw_sources.py``.

Each map is drawn in metres in its own world frame (the origin given to ``png_to_ros_map`` in
``maps/maps.mk``) at 0.05 m per pixel, the way a person would draw or scan a floor plan: grey
ink, a little paper noise and dust, which ``image_to_bw`` cleans. Unknown space is transparent
(alpha 0): nav2 reads a pixel with alpha < 255 as unknown, and so do the tools.

The drawing is deterministic (fixed seeds), so rerunning this script reproduces the committed
PNGs; ``make maps`` then turns them into ``maps/<name>.pgm`` + ``.yaml``.

Coordinates are chosen so that doors and corridors line up with the robot's move lattice
(start + multiples of 0.5 m) with room to spare for its 0.2 m radius.
"""

from collections.abc import Iterable
from pathlib import Path
import sys

import cv2
import numpy as np

RESOLUTION = 0.05  # m per pixel
INK = 25  # grey of drawn walls before cleaning
PAPER = 235  # grey of paper (free space) before cleaning
HERE = Path(__file__).resolve().parent


class Canvas:
    """A grey + alpha image addressed in world metres (x right, y up), pixel-exact."""

    def __init__(self, width_m: float, height_m: float, origin=(0.0, 0.0), known=True):
        self.origin = origin
        self.width = round(width_m / RESOLUTION)
        self.height = round(height_m / RESOLUTION)
        self.grey = np.full((self.height, self.width), PAPER, np.uint8)
        self.alpha = np.full((self.height, self.width), 255 if known else 0, np.uint8)

    def col(self, x: float) -> int:
        return round((x - self.origin[0]) / RESOLUTION)

    def row(self, y: float) -> int:
        """Image row of the pixel boundary at world y (rows count down from the top)."""
        return self.height - round((y - self.origin[1]) / RESOLUTION)

    def _region(self, x0, y0, x1, y1):
        (x0, x1), (y0, y1) = sorted((x0, x1)), sorted((y0, y1))
        return slice(self.row(y1), self.row(y0)), slice(self.col(x0), self.col(x1))

    def fill(self, x0, y0, x1, y1, grey=INK):
        self.grey[self._region(x0, y0, x1, y1)] = grey

    def clear(self, x0, y0, x1, y1):
        self.fill(x0, y0, x1, y1, PAPER)

    def known(self, x0, y0, x1, y1):
        self.alpha[self._region(x0, y0, x1, y1)] = 255

    def unknown(self, x0, y0, x1, y1):
        self.alpha[self._region(x0, y0, x1, y1)] = 0

    def wall(self, x0, y0, x1, y1, thickness=0.1, doors: Iterable[tuple[float, float]] = ()):
        """An axis-aligned wall centred on the segment, with (centre, width) door gaps."""
        half = thickness / 2
        horizontal = y0 == y1
        start, end = sorted((x0, x1) if horizontal else (y0, y1))
        pieces, position = [], start - half
        for centre, width in sorted(doors):
            pieces.append((position, centre - width / 2))
            position = centre + width / 2
        pieces.append((position, end + half))
        for a, b in pieces:
            if b <= a:
                continue
            if horizontal:
                self.fill(a, y0 - half, b, y0 + half)
            else:
                self.fill(x0 - half, a, x0 + half, b)

    def box(self, x0, y0, x1, y1, outline=0.0):
        """Furniture: a filled rectangle, or an outlined one of the given line width."""
        self.fill(x0, y0, x1, y1)
        if outline:
            self.clear(x0 + outline, y0 + outline, x1 - outline, y1 - outline)

    def disc(self, x, y, radius):
        centre = (self.col(x), self.row(y))
        cv2.circle(self.grey, centre, round(radius / RESOLUTION), INK, -1, cv2.LINE_AA)

    def scan_noise(self, seed: int, sigma=10.0, dust=40):
        """Paper grain and dust specks, so the result needs image_to_bw's cleaning."""
        rng = np.random.default_rng(seed)
        noisy = self.grey + rng.normal(0.0, sigma, self.grey.shape)
        rows = rng.integers(0, self.height, dust)
        cols = rng.integers(0, self.width, dust)
        noisy[rows, cols] = INK
        noisy[rows[: dust // 2], np.minimum(cols[: dust // 2] + 1, self.width - 1)] = INK
        self.grey = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)

    def slam_texture(self, rng: np.random.Generator, stray_hits=400, legs=12):
        """What a laser scan makes of the drawing: walls ragged by a pixel here and there,
        stray single-pixel hits (cleaned away), a few chair legs (kept), noisy grey levels and
        a ragged edge where the known space meets the unknown."""
        wall = self.grey < 128
        grown = cv2.dilate(wall.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        self.grey[grown & ~wall & (rng.random(wall.shape) < 0.25)] = INK
        free = (self.alpha == 255) & ~grown
        rows, cols = np.nonzero(free)
        picks = rng.choice(rows.size, stray_hits + legs, replace=False)
        self.grey[rows[picks[:stray_hits]], cols[picks[:stray_hits]]] = INK
        for row, col in zip(rows[picks[stray_hits:]], cols[picks[stray_hits:]], strict=True):
            self.grey[row - 1 : row + 2, col - 1 : col + 2] = INK
        known = self.alpha == 255
        edge = cv2.dilate(known.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
        self.alpha[edge & ~known & (rng.random(known.shape) < 0.3)] = 255
        noisy = self.grey + rng.normal(0.0, 14.0, self.grey.shape)
        self.grey = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)

    def image(self) -> np.ndarray:
        if (self.alpha == 255).all():
            return self.grey
        grey = np.where(self.alpha == 255, self.grey, PAPER).astype(np.uint8)
        return np.dstack([grey, grey, grey, self.alpha])


def simple_maze() -> Canvas:
    """15 x 15 m, thin (0.1 m) walls on a 2 m grid: a straight shortcut corridor up the middle,
    a serpentine on the east side and two columns on the west side."""
    canvas = Canvas(15.0, 15.0)
    walls = [
        # (x0, y0, x1, y1): outer walls, then the inner ones on the lines 0.5 + 2k.
        (0.5, 0.5, 14.5, 0.5),
        (0.5, 14.5, 14.5, 14.5),
        (0.5, 0.5, 0.5, 14.5),
        (14.5, 0.5, 14.5, 14.5),
        (2.5, 2.5, 12.5, 2.5),  # over the bottom row, open at both ends
        (2.5, 4.5, 2.5, 12.5),  # west column | middle
        (4.5, 6.5, 6.5, 6.5),  # middle zig-zag
        (2.5, 10.5, 4.5, 10.5),
        (6.5, 4.5, 6.5, 14.5),  # middle | shortcut
        (8.5, 2.5, 8.5, 12.5),  # shortcut | serpentine
        (10.5, 4.5, 14.5, 4.5),  # serpentine, open at alternate ends
        (8.5, 6.5, 12.5, 6.5),
        (10.5, 8.5, 14.5, 8.5),
        (8.5, 10.5, 12.5, 10.5),
        (10.5, 12.5, 14.5, 12.5),
    ]
    for x0, y0, x1, y1 in walls:
        canvas.wall(x0, y0, x1, y1, thickness=0.1)
    canvas.scan_noise(seed=4, sigma=8.0, dust=30)
    return canvas


def map1() -> Canvas:
    """20 x 20 m apartment: living room, study, kitchen, hallway, two bedrooms sharing a
    bathroom. Every room has two ways in, so there is always a way round."""
    canvas = Canvas(20.0, 20.0)
    outer, inner = 0.25, 0.12
    canvas.wall(1.0, 1.0, 19.0, 1.0, outer)
    canvas.wall(1.0, 19.0, 19.0, 19.0, outer)
    canvas.wall(1.0, 1.0, 1.0, 19.0, outer)
    canvas.wall(19.0, 1.0, 19.0, 19.0, outer)
    # Hallway y in [11, 13] across the flat.
    canvas.wall(1.0, 11.0, 19.0, 11.0, inner, doors=[(4.0, 1.0), (16.0, 1.0)])
    canvas.wall(1.0, 13.0, 19.0, 13.0, inner, doors=[(4.0, 1.0), (17.5, 1.0)])
    # North: bedroom 1 [1, 8], bathroom [8, 11.5], bedroom 2 [11.5, 19].
    canvas.wall(8.0, 13.0, 8.0, 19.0, inner, doors=[(17.0, 1.0)])
    canvas.wall(11.5, 13.0, 11.5, 19.0, inner, doors=[(17.0, 1.0)])
    # South: living room [1, 12]; east of it the kitchen [6, 11] over the study [1, 6].
    canvas.wall(12.0, 1.0, 12.0, 11.0, inner, doors=[(3.5, 1.0), (8.5, 1.0)])
    canvas.wall(12.0, 6.0, 19.0, 6.0, inner, doors=[(17.5, 1.0)])
    # Furniture.
    canvas.box(5.0, 5.0, 8.0, 7.0)  # dining table
    canvas.box(1.25, 8.0, 2.0, 10.75)  # sideboard
    canvas.box(9.0, 1.25, 11.75, 2.0)  # sofa
    canvas.box(14.5, 7.0, 16.0, 8.0)  # kitchen table
    canvas.box(18.25, 6.25, 18.75, 10.75)  # kitchen counter
    canvas.box(16.0, 1.25, 18.75, 2.5)  # desk
    canvas.box(1.25, 16.5, 3.5, 18.75)  # bed 1
    canvas.box(9.5, 17.5, 11.25, 18.75)  # bath tub
    canvas.box(12.0, 17.75, 14.0, 18.75)  # bed 2
    canvas.box(18.0, 17.0, 18.75, 18.75)  # wardrobe
    canvas.scan_noise(seed=1)
    return canvas


def floorplan() -> Canvas:
    """40 x 25 m office floor: a corridor along the middle, furnished rooms either side, and
    pairs of neighbouring rooms joined by inner doors."""
    canvas = Canvas(40.0, 25.0)
    outer, inner = 0.3, 0.15
    canvas.wall(1.0, 1.0, 39.0, 1.0, outer)
    canvas.wall(1.0, 24.0, 39.0, 24.0, outer)
    canvas.wall(1.0, 1.0, 1.0, 24.0, outer)
    canvas.wall(39.0, 1.0, 39.0, 24.0, outer)
    # Corridor y in [11, 14]; doors from it into each room.
    canvas.wall(
        1.0, 11.0, 39.0, 11.0, inner, doors=[(6.0, 1.0), (16.0, 1.0), (25.0, 1.0), (35.0, 1.0)]
    )
    canvas.wall(
        1.0, 14.0, 39.0, 14.0, inner, doors=[(8.0, 1.0), (21.0, 1.0), (30.0, 1.0), (37.0, 1.0)]
    )
    # South rooms split at x = 11, 22, 30; north rooms at x = 13, 26. Inner doors join
    # N1-N2 and S3-S4.
    canvas.wall(11.0, 1.0, 11.0, 11.0, inner)
    canvas.wall(22.0, 1.0, 22.0, 11.0, inner)
    canvas.wall(30.0, 1.0, 30.0, 11.0, inner, doors=[(4.0, 1.0)])
    canvas.wall(13.0, 14.0, 13.0, 24.0, inner, doors=[(20.0, 1.0)])
    canvas.wall(26.0, 14.0, 26.0, 24.0, inner)
    # Furniture: desks, a meeting table, shelves, benches, cubicles.
    for x in (2.5, 6.5):
        canvas.box(x, 3.0, x + 2.5, 4.0)
        canvas.box(x, 7.0, x + 2.5, 8.0)
    canvas.box(13.0, 3.0, 19.0, 6.0)  # meeting table
    for x in (23.5, 26.5):
        canvas.box(x, 6.0, x + 0.8, 9.5)  # shelves
    canvas.box(32.0, 6.5, 37.5, 7.5)  # desks
    canvas.box(32.0, 9.0, 34.0, 9.5)
    canvas.box(3.0, 17.0, 10.0, 18.0)  # lab benches
    canvas.box(3.0, 21.5, 10.0, 22.5)
    for x in (15.0, 18.5, 22.0):
        canvas.box(x, 21.5, x + 2.0, 23.5)  # cubicles
    canvas.box(28.5, 19.0, 35.5, 20.0)  # long table
    canvas.scan_noise(seed=3)
    return canvas


def lgfloor() -> Canvas:
    """About 26 x 20 m of a lower-ground floor inside a 30 x 30 m map, as a SLAM scan shows it:
    ragged walls, stray laser hits, unknown space outside and in two rooms never entered.

    Three parallel corridors (north, middle, south) joined at both ends and by a short
    connector between the middle and north ones; offices between them. The map frame's origin
    is the map's centre, where the scan started.
    """
    canvas = Canvas(30.0, 30.0, origin=(-15.0, -15.0), known=False)
    rng = np.random.default_rng(2)
    canvas.known(-13.1, -10.1, 13.1, 10.1)
    walls = [
        # Outside walls.
        (-13.0, -10.0, 13.0, -10.0, ()),
        (-13.0, 10.0, 13.0, 10.0, ()),
        (-13.0, -10.0, -13.0, 10.0, ()),
        (13.0, -10.0, 13.0, 10.0, ()),
        # The middle corridor y in [-1, 1], open at both ends.
        (-11.0, 1.0, 11.0, 1.0, ((-8.5, 1.2), (-4.0, 1.2), (0.0, 2.0), (3.5, 1.2))),
        (-11.0, -1.0, 11.0, -1.0, ((-5.5, 1.2), (0.0, 1.2), (9.0, 1.2))),
        # The north corridor y in [8, 10] and the south one y in [-10, -8].
        (-11.0, 8.0, 11.0, 8.0, ((-2.5, 1.2), (0.0, 2.0), (4.5, 1.2))),
        (-11.0, -8.0, 11.0, -8.0, ((-8.0, 1.2), (0.0, 1.2))),
        # The end corridors x in [-13, -11] and [11, 13] are the walls' open ends; offices:
        (-6.0, 1.0, -6.0, 8.0, ()),
        (-1.0, 1.0, -1.0, 8.0, ()),  # the connector x in [-1, 1] between middle and north
        (1.0, 1.0, 1.0, 8.0, ()),
        (6.0, 1.0, 6.0, 8.0, ()),
        (-11.0, 1.0, -11.0, 8.0, ()),
        (11.0, 1.0, 11.0, 8.0, ()),
        (-3.0, -8.0, -3.0, -1.0, ()),
        (3.0, -8.0, 3.0, -1.0, ()),
        (7.0, -8.0, 7.0, -1.0, ()),
        (-11.0, -8.0, -11.0, -1.0, ()),
        (11.0, -8.0, 11.0, -1.0, ()),
    ]
    for x0, y0, x1, y1, doors in walls:
        canvas.wall(x0, y0, x1, y1, thickness=0.15, doors=doors)
    # Rooms the robot never entered: nothing is known inside them.
    canvas.unknown(6.1, 1.1, 10.9, 7.9)
    canvas.unknown(3.1, -7.9, 6.9, -1.1)
    # Furniture the laser saw from one side only: the far side stays unknown.
    for x0, y0, x1, y1 in (
        (-10.5, 5.5, -8.5, 7.5),
        (-10.5, -7.5, -9.0, -4.0),
        (8.0, -7.5, 10.5, -6.5),
    ):
        canvas.fill(x0, y0, x1, y1)
        canvas.unknown(x0 + 0.15, y0 + 0.15, x1 - 0.15, y1 - 0.15)
    canvas.slam_texture(rng)
    return canvas


MAPS = {
    'simple-maze': simple_maze,
    'map1': map1,
    'floorplan': floorplan,
    'lgfloor': lgfloor,
}


def main(argv: list[str]) -> int:
    names = argv or list(MAPS)
    for name in names:
        path = HERE / f'{name}.png'
        ok, encoded = cv2.imencode('.png', MAPS[name]().image())
        path.write_bytes(encoded.tobytes())
        print(f'drew {path.relative_to(HERE.parent.parent)}')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
