"""The visibility of every cell of a map at once, equal to ``lighting.point_visibility`` at the
cell centres (``stealth_core.visibility_cache`` keeps it on disk per scenario).

How it is fast: for each light only the cells within its range's bounding box and actually lit
(in range and cone) are traced, each line walked in compiled code (``sight_kernels``, numba)
with the reference's own integer arithmetic. Where numba does not import, the lines run in
lockstep instead, one numpy step for all lines at a time, with exactly the reference's integer
error-term arithmetic (``_occluded_in_lockstep``; the same answers, 4x to 100x slower).

One-bounce light (``stealth_core.bounce``, when a ``Bounce`` is given) is added on top of the
direct field: ``bounce_field`` walks, for every wall cell that receives light, the line to each
cell within the bounce range in front of it, in compiled loops (``bounce_kernels``), and adds
the visible contributions up per cell in emitter order, as the reference does, so the two agree
to the last bit. ``PointVisibility`` adds the same sum at any point. A bounce with moving
lights is refused (``bounce.check_static``).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable, Sequence
import copy
import functools
import time

import numpy as np

from stealth_core import exposure
from stealth_core.bounce import Bounce, check_static, wall_emitters
from stealth_core.lighting import (
    GridFrame,
    light_intensity,
    lights_at,
)
from stealth_core.searchlight import Searchlight, poses_at


def _lamp_window(frame: GridFrame, light: Searchlight, lamp_col: int, lamp_row: int):
    """Column and row slices of the cells that can be within the light's range."""
    reach = int(np.ceil(light.range / frame.resolution)) + 1
    cols = slice(max(lamp_col - reach, 0), min(lamp_col + reach + 1, frame.width))
    rows = slice(max(lamp_row - reach, 0), min(lamp_row + reach + 1, frame.height))
    return cols, rows


QUADRANTS = ((1, 1), (-1, 1), (1, -1), (-1, -1))  # (column step, row step) of a line


def corner_maps(blocked: np.ndarray) -> np.ndarray:
    """(4, height*width): for each quadrant (col step sc, row step sr), whether cell (c, r)'s
    diagonal step to (c + sc, r + sr) squeezes between two blocking cells."""
    padded = np.pad(blocked, 1)
    height, width = blocked.shape
    maps = np.empty((len(QUADRANTS), height * width), dtype=bool)
    for q, (col_step, row_step) in enumerate(QUADRANTS):
        beside_col = padded[1 : height + 1, 1 + col_step : width + 1 + col_step]
        beside_row = padded[1 + row_step : height + 1 + row_step, 1 : width + 1]
        maps[q] = (beside_col & beside_row).ravel()
    return maps


# Rows of the per-line state array of _occluded.
(LINE, NEG_STEPS, HALF, ERROR, STRAIGHT_ERROR, DIAGONAL_ERROR) = range(6)
(STRAIGHT_MOVE, DIAGONAL_MOVE, INDEX, CORNER_INDEX) = range(6, 10)
COMPACT_EVERY = 16  # steps between dropping lines already blocked
UNKNOWN, CLEAR, BLOCKED = 0, 1, 2  # a cell in a lamp's sight memo (PointVisibility)


@functools.cache
def _compiled_sight():
    """``sight_kernels`` where numba imports (compiled at first use, or loaded from numba's
    cache: ``make setup`` warms it), else None. Imported here, not at the top, so that
    importing this module stays light: numba comes with the first ``PointVisibility`` or
    trace."""
    from stealth_core import jit

    if jit.import_problem() is not None:
        return None
    from stealth_core import sight_kernels

    return sight_kernels


_NO_CELLS = np.zeros(0, dtype=np.int64)


def _warm_sight(blocked: np.ndarray) -> None:
    """Load the compiled trace for this map's array now: numba's import and cache cost about a
    second once a process, which a node should pay when it starts, not at the first step it
    judges."""
    kernels = _compiled_sight()
    if kernels is not None and blocked.size:
        kernels.occluded(blocked, 0, 0, _NO_CELLS, _NO_CELLS)


def _occluded(blocked: np.ndarray, corners: np.ndarray, lamp, cols, rows) -> np.ndarray:
    """For each target cell (cols, rows: int arrays), whether its Bresenham line from the lamp
    cell (col, row) is blocked: ``lighting.line_of_sight``'s rules, compiled where numba
    imports, in lockstep otherwise (``corners``: ``corner_maps`` of ``blocked``)."""
    kernels = _compiled_sight()
    if kernels is None:
        return _occluded_in_lockstep(blocked, corners, lamp, cols, rows)
    return kernels.occluded(
        blocked, int(lamp[0]), int(lamp[1]),
        np.asarray(cols, dtype=np.int64).ravel(), np.asarray(rows, dtype=np.int64).ravel(),
    )  # fmt: skip


def _occluded_in_lockstep(
    blocked: np.ndarray, corners: np.ndarray, lamp, cols, rows
) -> np.ndarray:
    """``_occluded`` in numpy: for each target cell, whether its Bresenham line from the lamp
    is blocked.

    Same rules and the same integer arithmetic as ``lighting.line_of_sight``, written per line
    in major/minor-axis form: every step moves along the major axis (length M), and along the
    minor one (length m) too when the error s <= M // 2 (a diagonal step); s starts at M - m and
    grows by M - m after a diagonal step, by -m after a straight one. Lines run longest first,
    so the running ones are a prefix; lines already blocked are dropped every few steps.
    """
    height, width = blocked.shape
    lamp_col, lamp_row = lamp
    d_col, d_row = cols - lamp_col, rows - lamp_row
    col_step = np.where(d_col > 0, 1, -1)  # as the reference: a zero delta "steps" by -1
    row_step = np.where(d_row > 0, 1, -1)
    col_major = np.abs(d_col) >= np.abs(d_row)
    major = np.where(col_major, np.abs(d_col), np.abs(d_row))
    minor = np.where(col_major, np.abs(d_row), np.abs(d_col))
    major_move = np.where(col_major, col_step, row_step * width)
    minor_move = np.where(col_major, row_step * width, col_step)
    quadrant = (col_step < 0) + 2 * (row_step < 0)  # index into QUADRANTS

    order = np.argsort(-major, kind='stable')
    state = np.empty((10, len(order)), dtype=np.int64)
    state[LINE] = order
    state[NEG_STEPS] = -major[order]
    state[HALF] = major[order] // 2
    state[ERROR] = state[DIAGONAL_ERROR] = major[order] - minor[order]
    state[STRAIGHT_ERROR] = -minor[order]
    state[STRAIGHT_MOVE] = major_move[order]
    state[DIAGONAL_MOVE] = major_move[order] + minor_move[order]
    state[INDEX] = lamp_row * width + lamp_col
    state[CORNER_INDEX] = state[INDEX] + quadrant[order] * (height * width)
    hit = np.zeros(len(order), dtype=bool)
    blocked_flat, corners_flat = blocked.ravel(), corners.ravel()
    occluded = np.ones(len(order), dtype=bool)  # lines dropped as blocked stay True

    for k in range(int(major.max(initial=0)) + 1):
        running = int(np.searchsorted(state[NEG_STEPS], -k, side='left'))  # steps > k
        occluded[state[LINE, running:]] = hit[running:]
        state, hit = state[:, :running], hit[:running]
        if running == 0:
            break
        if k > 0:
            hit |= blocked_flat[state[INDEX]]
        diagonal = state[ERROR] <= state[HALF]
        hit |= corners_flat[state[CORNER_INDEX]] & diagonal
        state[ERROR] += np.where(diagonal, state[DIAGONAL_ERROR], state[STRAIGHT_ERROR])
        move = np.where(diagonal, state[DIAGONAL_MOVE], state[STRAIGHT_MOVE])
        state[INDEX] += move
        state[CORNER_INDEX] += move
        if k % COMPACT_EVERY == COMPACT_EVERY - 1 and np.count_nonzero(hit) > running // 8:
            keep = ~hit
            state, hit = state[:, keep], hit[keep]
    return occluded


def light_field(
    blocked: np.ndarray, corners: np.ndarray, frame: GridFrame, light: Searchlight
) -> np.ndarray:
    """Visibility of one static light on every cell, (height, width); corners from corner_maps."""
    lamp_col, lamp_row = frame.cell_of(light.x, light.y, what=f'searchlight {light.name!r}')
    field = np.zeros((frame.height, frame.width))
    col_slice, row_slice = _lamp_window(frame, light, lamp_col, lamp_row)
    rows, cols = np.mgrid[row_slice, col_slice]
    x, y = frame.cell_centre(cols, rows)
    values = light_intensity(light, x - light.x, y - light.y)
    lit = np.nonzero(values > 0.0)
    lit_cols, lit_rows = cols[lit], rows[lit]
    occluded = _occluded(blocked, corners, (lamp_col, lamp_row), lit_cols, lit_rows)
    field[lit_rows, lit_cols] = np.where(occluded, 0.0, values[lit])
    return field


def bounce_field(frame: GridFrame, blocked: np.ndarray, direct: np.ndarray, bounce: Bounce):
    """The bounced light on every cell, (height, width): ``bounce.point_bounce`` at each cell
    centre, with each emitter's received light read from ``direct``, the direct total field."""
    from stealth_core import bounce_kernels  # numba is imported only where bounces are made

    emitters = wall_emitters(blocked)
    received = np.ascontiguousarray(direct[emitters.rows, emitters.cols])
    x_of_col, _ = frame.cell_centre(np.arange(frame.width), 0)
    _, y_of_row = frame.cell_centre(0, np.arange(frame.height))
    reach = int(np.ceil(bounce.range / frame.resolution)) + 1
    return bounce_kernels.field(
        np.ascontiguousarray(blocked),
        bounce_kernels.emitter_table(emitters),
        received,
        x_of_col,
        y_of_row,
        reach,
        bounce_kernels.parameters(bounce, frame.resolution),
    )


def active_bounce(bounce: Bounce | None) -> Bounce | None:
    return bounce if bounce is not None and bounce.albedo > 0.0 else None


def visibility_field(
    blocked: np.ndarray,
    resolution: float,
    origin: Sequence[float],
    lights: Iterable[Searchlight],
    t: float = 0.0,
    bounce: Bounce | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(total (height, width), per_light (n_lights, height, width)) at time t (s).

    Cell (row, col) holds ``lighting.point_visibility`` at that cell's centre, exactly, plus
    with a bounce (albedo > 0) ``bounce.point_bounce`` there; per_light is the direct light
    only (the bounce is not split by light). A bounce with moving lights is refused.
    """
    lights = tuple(lights)
    bounce = active_bounce(bounce)
    if bounce is not None:
        check_static(lights)
    frame = GridFrame.of(blocked, resolution, origin)
    static = lights_at(lights, t)
    per_light = np.zeros((len(static), frame.height, frame.width))
    total = np.zeros((frame.height, frame.width))
    corners = corner_maps(blocked)
    for i, light in enumerate(static):
        per_light[i] = light_field(blocked, corners, frame, light)
        total += per_light[i]  # in the lights' order, as the reference adds them
    if bounce is not None:
        total = total + bounce_field(frame, blocked, total, bounce)
    return total, per_light


class PointVisibility:
    """``lighting.point_visibility`` (and ``point_light_visibilities``) on one fixed map and
    set of lights, equal to it to the last bit and cheap per point.

    The intensities are the reference's own functions (a point beyond a light's range, d^2 >
    range^2 in the same float arithmetic, skips them: its value is 0). The occlusion test is
    what is faster: the line of sight from a lamp's cell is computed for a whole TILE x TILE
    block of target cells at once (``_occluded``, the same integer Bresenham and corner rule)
    and kept, keyed by the lamp's cell and the block (``many`` traces the cells it needs in
    one ``_occluded`` call, or, without numba, asks the blocks when a light lights few cells).
    Keying by the lamp's cell serves every kind of light: static and sweeping lights (only the
    direction changes) reuse the blocks of their one cell, patrolling lights those of the
    cells they pass; the least recently used blocks beyond ``max_tiles`` are dropped. Above
    the blocks, each lamp cell keeps a memo of every cell's line of sight traced so far (one
    int8 per map cell, the ``max_lamps`` most recently used lamp cells), so a cell is traced
    once per lamp cell however many calls ask for it. ``blocked`` must not change afterwards.

    With a ``footprint`` (``exposure.Footprint``), a point asked for with the robot's heading
    has each light's value multiplied by the exposure factor before the lights are added
    (``stealth_core.exposure``); without a heading, the light at the point is the whole of it.
    With a ``bounce`` (static lights only), ``__call__`` and ``many`` add the bounced light at
    the point (``bounce.point_bounce``, to the last bit); ``light_visibilities`` stays direct.
    """

    TILE = 16  # cells along each side of a block of targets
    # Without numba, ``many`` at up to this many lit cells per light (a move's samples, judged
    # every step) asks the block cache cell by cell: tracing them afresh in lockstep cost ~1 ms
    # a light, a numpy step per cell along the longest line, however few the targets.
    # Compiled, a trace of a few cells costs microseconds: they are traced afresh.
    FEW_CELLS = 64

    def __init__(
        self,
        blocked: np.ndarray,
        resolution: float,
        origin: Sequence[float],
        lights: Iterable[Searchlight],
        max_tiles: int = 4096,
        footprint: exposure.Footprint | None = None,
        bounce: Bounce | None = None,
        max_lamps: int = 64,
    ):
        self.frame = GridFrame.of(blocked, resolution, origin)
        self.footprint = footprint
        self.blocked = blocked
        _warm_sight(blocked)
        self.lights = tuple(lights)
        self.max_tiles = max_tiles
        self.max_lamps = max_lamps
        self.bounce = active_bounce(bounce)
        if self.bounce is not None:
            check_static(self.lights)
        self._corners: np.ndarray | None = None
        self._tiles: OrderedDict[tuple[int, int, int, int], np.ndarray] = OrderedDict()
        # Per lamp cell, per map cell: UNKNOWN, CLEAR or BLOCKED line of sight (_sight_of).
        self._sight: OrderedDict[tuple[int, int], np.ndarray] = OrderedDict()
        self._sources: _BounceSources | None = None

    def light_visibilities(
        self, x: float, y: float, t: float = 0.0, heading: float | None = None
    ) -> list[float]:
        """Each light's visibility at (x, y) m at time t s (``point_light_visibilities``),
        weighed by exposure when the robot's heading (rad) is given and the footprint known."""
        frame = self.frame
        target = frame.cell_of(x, y)
        values = []
        for light in lights_at(self.lights, t):
            lamp = frame.cell_of(light.x, light.y, what=f'searchlight {light.name!r}')
            dx, dy = x - light.x, y - light.y
            if dx * dx + dy * dy > light.range * light.range:
                values.append(0.0)  # out of range: the reference's own test, in plain floats
                continue
            value = float(light_intensity(light, dx, dy))
            if value > 0.0 and not self.line_of_sight(lamp, target):
                value = 0.0
            if value > 0.0 and self._weighs(heading):
                value *= float(exposure.factor(self.footprint, heading, dx, dy))
            values.append(value)
        return values

    def with_lights(self, lights: Iterable[Searchlight], bounce: bool = True) -> PointVisibility:
        """The same map, footprint and bounce (direct light only: ``bounce`` False) with other
        lights, sharing this one's traced lines of sight (a learner weighing light hypotheses
        asks the same lamp cells over and over)."""
        if self._corners is None:
            self._corners = corner_maps(self.blocked)
        other = copy.copy(self)  # the sight memos and blocks are the same objects
        other.lights = tuple(lights)
        if not bounce:
            other.bounce = None
        if other.bounce is not None:
            check_static(other.lights)
        other._sources = None  # the bounce's emitters receive these lights' light
        return other

    def sight_from(self, x: float, y: float, xs, ys) -> np.ndarray:
        """Bool per point (arrays of x and y, m): whether the cell of (x, y) sees the point's
        cell, all traced from (x, y) in one ``_occluded`` call (not memoised: from a lamp, ask
        ``line_of_sight``). ValueError for a point off the map."""
        if self._corners is None:
            self._corners = corner_maps(self.blocked)
        source = self.frame.cell_of(x, y)
        cols, rows = self._cells(
            np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64)
        )
        return ~_occluded(self.blocked, self._corners, source, cols, rows)

    def _weighs(self, heading) -> bool:
        return heading is not None and self.footprint is not None

    def __call__(self, x: float, y: float, t: float = 0.0, heading: float | None = None) -> float:
        """Total visibility at (x, y) at time t (with a heading: weighed by exposure), added in
        the lights' order (plus the bounce)."""
        total = 0.0
        for value in self.light_visibilities(x, y, t, heading):
            total += value
        if self.bounce is not None:
            col, row = self.frame.cell_of(x, y)
            point = (np.array([float(x)]), np.array([float(y)]))
            total += float(self._bounce(*point, np.array([col]), np.array([row]))[0])
        return total

    def many(self, xs, ys, t: float = 0.0, headings=None) -> np.ndarray:
        """Total visibility at many points (arrays of x and y, m) at one time t (s): the same
        model as ``__call__`` point by point (the lines of sight traced for all points at once;
        headings, rad, an array like xs or None). ValueError when a point is off the map or not
        finite."""
        return self.turning(xs, ys, t, [headings])[0]

    def turning(self, xs, ys, t: float, headings) -> list[np.ndarray]:
        """``many`` at the same points for each array (or None) of ``headings`` in turn: a robot
        turning in place, its lights traced once."""
        xs = np.asarray(xs, dtype=np.float64)
        ys = np.asarray(ys, dtype=np.float64)
        cols, rows = self._cells(xs, ys)
        per_light = self._direct_many(xs, ys, cols, rows, t)
        bounced = None
        if self.bounce is not None:  # not weighed by exposure: the scenario refuses both
            bounced = self._bounce(xs.ravel(), ys.ravel(), cols.ravel(), rows.ravel())
        totals = []
        for heading in headings:
            total = np.zeros(np.shape(xs))
            for value, dx, dy in per_light:
                if self._weighs(heading):
                    value = value * exposure.factor(self.footprint, heading, dx, dy)
                total += value  # in the lights' order, as the reference adds them
            if bounced is not None:
                total = total + bounced.reshape(xs.shape)
            totals.append(total)
        return totals

    def many_at_times(self, xs, ys, ts, headings=None, time_index=None) -> np.ndarray:
        """``many`` at points each at its own time (arrays ts like xs, s): equal to asking
        ``__call__`` point by point (to rounding: a pose's cosine), each light's poses taken at
        all the times at once (``searchlight.poses_at``) and its lines of sight traced per lamp
        cell, so a moving light over a lattice's samples costs a few array passes, not a call
        per time. With ``time_index`` (an int array like xs), ts are the distinct times and
        point k's is ``ts[time_index[k]]``: a lattice's thousands of samples share a few dozen
        times, so each light's poses are taken once a time. Direct light only: moving lights
        have no bounce."""
        xs = np.asarray(xs, dtype=np.float64)
        ys = np.asarray(ys, dtype=np.float64)
        ts = np.asarray(ts, dtype=np.float64)
        if time_index is None:
            ts, time_index = np.broadcast_to(ts, xs.shape), None
        cols, rows = self._cells(xs, ys)
        if self._corners is None:
            self._corners = corner_maps(self.blocked)
        frame, total = self.frame, np.zeros(xs.shape)
        for light in self.lights:
            lamp_x, lamp_y, direction = poses_at(light, ts)
            if time_index is not None:
                lamp_x, lamp_y = lamp_x[time_index], lamp_y[time_index]
                direction = direction[time_index]
            dx, dy = xs - lamp_x, ys - lamp_y
            value = np.zeros(xs.shape)
            near = dx * dx + dy * dy <= light.range * light.range
            # A static light keeps the reference's own scalar cosine, to the last bit.
            aims = direction[near] if light.is_moving else None
            value[near] = light_intensity(light, dx[near], dy[near], aims)
            lit = np.flatnonzero(value > 0.0)
            if lit.size:
                lamp_cols = np.floor((lamp_x.ravel()[lit] - frame.origin_x) / frame.resolution)
                lamp_rows = np.floor((lamp_y.ravel()[lit] - frame.origin_y) / frame.resolution)
                off = (lamp_cols < 0) | (lamp_cols >= frame.width) | (lamp_rows < 0)
                off |= lamp_rows >= frame.height
                if np.any(off):  # the reference's own error, naming the light
                    k = lit[int(np.flatnonzero(off)[0])]
                    frame.cell_of(
                        lamp_x.ravel()[k], lamp_y.ravel()[k], what=f'searchlight {light.name!r}'
                    )
                lamps = lamp_rows.astype(np.int64) * frame.width + lamp_cols.astype(np.int64)
                flat = rows.ravel()[lit] * frame.width + cols.ravel()[lit]
                shown = value.ravel()
                for lamp in np.unique(lamps).tolist():
                    at = lit[lamps == lamp]
                    col, row = lamp % frame.width, lamp // frame.width
                    cells = flat[lamps == lamp]
                    sight = self._sight_of((col, row), np.unique(cells))
                    shown[at] = np.where(sight[cells] == BLOCKED, 0.0, shown[at])
                value = shown.reshape(xs.shape)
            if self._weighs(headings):
                value = value * exposure.factor(self.footprint, headings, dx, dy)
            total += value
        return total

    def _cells(self, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(cols, rows) of points; ValueError naming the first one off the map or not finite."""
        frame = self.frame
        if not (np.all(np.isfinite(xs)) and np.all(np.isfinite(ys))):
            raise ValueError('points: coordinates must be finite numbers')
        cols = np.floor((xs - frame.origin_x) / frame.resolution).astype(np.int64)
        rows = np.floor((ys - frame.origin_y) / frame.resolution).astype(np.int64)
        off = (cols < 0) | (cols >= frame.width) | (rows < 0) | (rows >= frame.height)
        if np.any(off):
            k = int(np.flatnonzero(off.ravel())[0])
            frame.cell_of(xs.ravel()[k], ys.ravel()[k])  # raises, naming the point
        return cols, rows

    def _direct_many(self, xs, ys, cols, rows, t: float) -> list:
        """(value, dx, dy) of each light at many points: its direct light, unweighted, and the
        offsets from its lamp (``many`` without exposure and bounce)."""
        frame = self.frame
        if self._corners is None:
            self._corners = corner_maps(self.blocked)
        per_light = []
        for light in lights_at(self.lights, t):
            lamp = frame.cell_of(light.x, light.y, what=f'searchlight {light.name!r}')
            dx, dy = xs - light.x, ys - light.y
            near = dx * dx + dy * dy <= light.range * light.range
            value = np.zeros(np.shape(dx))  # intensities of the points in range only
            value[near] = light_intensity(light, dx[near], dy[near])
            lit = value > 0.0
            if np.any(lit):
                flat = rows[lit] * frame.width + cols[lit]
                sight = self._sight_of(lamp, np.unique(flat))
                value[lit] = np.where(sight[flat] == BLOCKED, 0.0, value[lit])
            per_light.append((value, dx, dy))
        return per_light

    def _sight_of(self, lamp: tuple[int, int], cells: np.ndarray) -> np.ndarray:
        """The lamp cell's sight memo (flat, per map cell: UNKNOWN, CLEAR or BLOCKED), with
        the cells given (flat indices, unique) known: only those it did not know yet are
        traced (few through the block cache, many in one ``_occluded`` call). The memo is why
        a lattice model's step samples cost one trace per light, not one per sample and light."""
        sight = self._sight.get(lamp)
        if sight is None:
            sight = np.full(self.blocked.size, UNKNOWN, dtype=np.int8)
            self._sight[lamp] = sight
            if len(self._sight) > self.max_lamps:
                self._sight.popitem(last=False)
        else:
            self._sight.move_to_end(lamp)
        new = cells[sight[cells] == UNKNOWN]
        if new.size:
            width = self.frame.width
            if new.size <= self.FEW_CELLS and _compiled_sight() is None:  # the block cache
                occluded = np.array(
                    [not self.line_of_sight(lamp, (c % width, c // width)) for c in new.tolist()],
                    dtype=bool,
                )
            else:
                occluded = _occluded(self.blocked, self._corners, lamp, new % width, new // width)
            sight[new] = np.where(occluded, BLOCKED, CLEAR)
        return sight

    def _bounce(self, xs, ys, cols, rows) -> np.ndarray:
        """The bounced light at points (1-D arrays) in cells (cols, rows): for each point, the
        contributions of the emitters in sight of its cell, added up in emitter order."""
        if self._sources is None:
            self._sources = _BounceSources(self)
        return self._sources.at(xs, ys, cols, rows)

    def line_of_sight(self, lamp: tuple[int, int], target: tuple[int, int]) -> bool:
        """``lighting.line_of_sight(blocked, lamp, target)``, from the block cache."""
        tile = self.TILE
        col, row = target
        key = (lamp[0], lamp[1], col // tile, row // tile)
        block = self._tiles.get(key)
        if block is None:
            block = self._sight_block(lamp, key[2] * tile, key[3] * tile)
            self._tiles[key] = block
            if len(self._tiles) > self.max_tiles:
                self._tiles.popitem(last=False)
        else:
            self._tiles.move_to_end(key)
        return bool(block[row % tile, col % tile])

    def _sight_block(self, lamp, col0: int, row0: int) -> np.ndarray:
        """(TILE, TILE) line of sight from the lamp to the block at (col0, row0); cells off the
        map are left False (never asked: ``cell_of`` refuses them)."""
        if self._corners is None:
            self._corners = corner_maps(self.blocked)
        frame, tile = self.frame, self.TILE
        rows, cols = np.mgrid[
            row0 : min(row0 + tile, frame.height), col0 : min(col0 + tile, frame.width)
        ]
        block = np.zeros((tile, tile), dtype=bool)
        occluded = _occluded(self.blocked, self._corners, lamp, cols.ravel(), rows.ravel())
        block[rows - row0, cols - col0] = ~occluded.reshape(rows.shape)
        return block


class _BounceSources:
    """The emitters of a ``PointVisibility`` that receive light, ready for the kernel."""

    def __init__(self, points: PointVisibility):
        from stealth_core import bounce_kernels  # numba only where bounces are made

        self.kernels = bounce_kernels
        frame, emitters = points.frame, wall_emitters(points.blocked)
        x, y = frame.cell_centre(emitters.cols, emitters.rows)
        received = np.zeros(np.shape(x))
        for value, _, _ in points._direct_many(x, y, emitters.cols, emitters.rows, 0.0):
            received += value  # in the lights' order, as the reference adds them
        keep = received > 0.0  # the others add nothing; emitter order is kept
        self.blocked = np.ascontiguousarray(points.blocked)
        self.emitters = np.ascontiguousarray(bounce_kernels.emitter_table(emitters)[:, keep])
        self.received = received[keep]
        self.centres = np.stack([x[keep], y[keep]])
        self.parameters = bounce_kernels.parameters(points.bounce, frame.resolution)

    def at(self, xs, ys, cols, rows) -> np.ndarray:
        as_float = [np.ascontiguousarray(v, dtype=np.float64) for v in (xs, ys)]
        as_int = [np.ascontiguousarray(v, dtype=np.int64) for v in (cols, rows)]
        return self.kernels.at_points(
            self.blocked, *as_float, *as_int, self.emitters, self.received, self.centres,
            self.parameters,
        )  # fmt: skip


def warm_up_kernels() -> float | None:
    """Compile the line-of-sight and bounce kernels (or load them from numba's cache) on a
    throwaway map, so that no scenario load pays for it (``make setup`` calls this): the
    seconds, None without numba."""
    from stealth_core import jit

    if jit.import_problem() is not None:
        return None
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[0] = True
    lights = [Searchlight('warm-up', 0.35, 0.35, 1.5, 1.0, 1.0)]
    bounce = Bounce(0.5, 0.5)
    started = time.perf_counter()
    visibility_field(blocked, 0.1, (0.0, 0.0), lights, bounce=bounce)
    PointVisibility(blocked, 0.1, (0.0, 0.0), lights, bounce=bounce)(0.45, 0.45)
    return time.perf_counter() - started


def scenario_point_visibility(scenario) -> PointVisibility:
    """The ``PointVisibility`` of a ``stealth_core.scenario.Scenario`` (its bounce included)."""
    occupancy = scenario.map
    return PointVisibility(
        occupancy.blocked,
        occupancy.resolution,
        occupancy.origin,
        scenario.lights,
        footprint=getattr(scenario, 'exposure', None),
        bounce=getattr(scenario, 'bounce', None),
    )
