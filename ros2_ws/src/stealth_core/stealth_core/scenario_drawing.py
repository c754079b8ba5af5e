"""A scenario drawn at one time: walls, unknown space, the visibility heatmap, the lights'
cones, start, goals and paths, as a matplotlib Figure (no pyplot: no global state, no display).
stealth_core.render writes these figures as PNGs, animated GIFs and side-by-side comparisons;
the colours are stealth_core.palette's.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import math
import os
from typing import NamedTuple

from matplotlib import patches
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.text import Text
from matplotlib.transforms import Bbox
from mpl_toolkits.axes_grid1 import make_axes_locatable
import numpy as np

from stealth_core import palette
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion
from stealth_core.visibility_cache import scenario_visibility

# The gid of each path's line and end marker (path_artists finds them by it).
PATH_GID = 'path'
# Behind the names of lights, goals and the start.
LABEL_BOX = {'boxstyle': 'round,pad=0.15', 'facecolor': palette.LABEL_BACKGROUND, 'linewidth': 0}


class GoalMark(NamedTuple):
    name: str
    x: float
    y: float
    radius: float


def goal_marks(scenario) -> list[GoalMark]:
    """The scenario's goals as (name, x, y, acceptance radius)."""
    goals = scenario.goals
    items = goals.items() if hasattr(goals, 'items') else ((goal.name, goal) for goal in goals)
    marks = []
    for name, goal in items:
        marks.append(GoalMark(str(name), float(goal.x), float(goal.y), float(goal.radius)))
    return marks


def _draw_map(ax, occupancy, total: np.ndarray, threshold: float | None, vmax=None):
    """Heatmap of total visibility on free cells, walls black, unknown grey; returns the image.
    vmax: the top of the colour scale (default: the field's largest value on free cells)."""
    x0, y0, x1, y1 = occupancy.bounds
    extent = (x0, x1, y0, y1)
    blocked = occupancy.blocked
    if vmax is None:
        vmax = float(total[~blocked].max(initial=0.0))
    vmax = max(vmax, threshold or 0.0, 1e-9)
    heat = np.ma.masked_where(blocked | (total <= 0.0), total)  # dark cells show the background
    image = ax.imshow(
        heat,
        origin='lower',
        extent=extent,
        cmap=palette.HEATMAP,
        vmin=0.0,
        vmax=vmax,
        interpolation='nearest',
    )
    layers = np.zeros(blocked.shape, dtype=np.int8)
    layers[occupancy.unknown] = 1
    layers[occupancy.occupied] = 2
    walls = np.ma.masked_where(layers == 0, layers)
    ax.imshow(
        walls,
        origin='lower',
        extent=extent,
        interpolation='nearest',
        vmin=0,
        vmax=2,
        cmap=ListedColormap([(0, 0, 0, 0), palette.UNKNOWN_SPACE, palette.WALL]),
    )
    if threshold is not None and total.max() >= threshold:
        xs = x0 + (np.arange(total.shape[1]) + 0.5) * occupancy.resolution
        ys = y0 + (np.arange(total.shape[0]) + 0.5) * occupancy.resolution
        ax.contour(
            xs,
            ys,
            np.where(blocked, 0.0, total),
            levels=[threshold],
            colors=palette.DETECTION,
            linewidths=1.0,
            linestyles='--',
        )
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    return image


def _draw_cone(ax, light: Searchlight, **style):
    """Outline of the cone: two edges and the range arc (a circle for a full-circle light)."""
    half = light.fov / 2
    if light.fov >= 2 * math.pi - 1e-9:
        ax.add_patch(patches.Circle((light.x, light.y), light.range, fill=False, **style))
        return
    start, end = math.degrees(light.direction - half), math.degrees(light.direction + half)
    ax.add_patch(patches.Wedge((light.x, light.y), light.range, start, end, fill=False, **style))


def _draw_light(ax, light: Searchlight, t: float):
    now = light.at(t)
    if isinstance(light.motion, SweepMotion):  # the whole sweep, faint
        low, high = light.motion.min_direction, light.motion.max_direction
        sweep = Searchlight(
            light.name,
            now.x,
            now.y,
            (low + high) / 2,
            min(high - low + light.fov, 2 * math.pi),
            light.range,
        )
        _draw_cone(ax, sweep, edgecolor=palette.LIGHT, linewidth=0.8, linestyle=':', alpha=0.7)
    if isinstance(light.motion, PatrolMotion):  # the closed route, faint
        route = np.array([(light.x, light.y), *light.motion.waypoints, (light.x, light.y)])
        ax.plot(route[:, 0], route[:, 1], ':', color=palette.LIGHT, linewidth=1.0, alpha=0.8)
    _draw_cone(ax, now, edgecolor=palette.LIGHT, linewidth=1.0, alpha=0.6)
    ax.plot(
        now.x,
        now.y,
        marker='*',
        markersize=13,
        color=palette.LAMP,
        markeredgecolor=palette.LAMP_EDGE,
    )
    ax.annotate(
        now.name,
        (now.x, now.y),
        xytext=(6, 6),
        textcoords='offset points',
        fontsize=8,
        color=palette.LIGHT,
        fontweight='bold',
        bbox={**LABEL_BOX, 'alpha': 0.75},
    )


def _label(ax, x, y, text, colour):
    ax.annotate(
        text,
        (x, y),
        xytext=(7, -12),
        textcoords='offset points',
        fontsize=8,
        color=colour,
        fontweight='bold',
        bbox={**LABEL_BOX, 'alpha': 0.8},
    )


def _draw_footprint(ax, footprint, x: float, y: float, yaw: float, colour) -> None:
    """The robot's rectangle (exposure.Footprint) at (x, y) facing yaw (rad)."""
    cos, sin = np.cos(yaw), np.sin(yaw)
    corner = (
        x - (footprint.length * cos - footprint.width * sin) / 2,
        y - (footprint.length * sin + footprint.width * cos) / 2,
    )
    ax.add_patch(
        patches.Rectangle(
            corner,
            footprint.length,
            footprint.width,
            angle=float(np.degrees(yaw)),
            facecolor='none',
            edgecolor=colour,
            linewidth=0.8,
        )
    )


def scenario_figure(
    scenario,
    paths: Iterable[Sequence[Sequence[float]]] = (),
    field: np.ndarray | None = None,
    t: float = 0.0,
    goal: str | None = None,
    path_labels: Sequence[str] | None = None,
    title: str | None = None,
    cache_dir: str | os.PathLike | None = None,
    dpi: int = 110,
    vmax: float | None = None,
) -> Figure:
    """The scenario at time t (s) as a Figure: walls, the visibility heatmap, cones, start,
    goals and paths.

    field: total visibility (height, width) to show instead of computing (cached) the
    scenario's; paths: sequences of (x, y) in metres; goal: the goal pursued, highlighted;
    vmax: the top of the colour scale (default: the field's largest value).
    """
    occupancy = scenario.map
    if field is None:
        field, _ = scenario_visibility(scenario, t=t, cache_dir=cache_dir)
    if np.shape(field) != occupancy.blocked.shape:
        raise ValueError(f'field: expected shape {occupancy.blocked.shape}, got {np.shape(field)}')
    threshold = getattr(scenario, 'detection_threshold', None)
    x0, y0, x1, y1 = occupancy.bounds
    aspect = (y1 - y0) / (x1 - x0)
    width_in = 9.0 if aspect <= 1.2 else max(9.0 / aspect * 1.2, 5.0)
    fig = Figure(figsize=(width_in + 1.4, width_in * aspect + 1.6), dpi=dpi)
    ax = fig.add_subplot()
    ax.set_facecolor(palette.DARK_FLOOR)
    image = _draw_map(ax, occupancy, np.asarray(field, dtype=float), threshold, vmax)
    bar_axes = make_axes_locatable(ax).append_axes('right', size='3%', pad=0.12)
    colourbar = fig.colorbar(image, cax=bar_axes)
    colourbar.set_label('total visibility (sum of light intensities)')
    if threshold is not None:
        colourbar.ax.axhline(threshold, color=palette.DETECTION, linestyle='--', linewidth=1.5)

    for light in scenario.lights:
        _draw_light(ax, light, t)

    footprint = getattr(scenario, 'exposure', None)
    for number, points in enumerate(paths):
        points = np.asarray(points, dtype=float)
        poses = points if points.ndim == 2 and points.shape[1] == 3 else None
        points = points.reshape(-1, 2) if poses is None else poses[:, :2]
        label = path_labels[number] if path_labels else f'path {number + 1}'
        colour = palette.PATHS[number % len(palette.PATHS)]
        style = {'color': colour, 'gid': PATH_GID}
        ax.plot(points[:, 0], points[:, 1], '-', linewidth=1.8, label=label, **style)
        ax.plot(points[-1, 0], points[-1, 1], 'o', markersize=4, **style)
        if poses is not None and footprint is not None:
            for x, y, yaw in poses:
                _draw_footprint(ax, footprint, x, y, yaw, colour)

    for mark in goal_marks(scenario):
        pursued = goal is None or mark.name == goal
        alpha = 1.0 if pursued else 0.45
        ax.add_patch(
            patches.Circle(
                (mark.x, mark.y),
                mark.radius,
                facecolor=palette.GOAL,
                alpha=0.25 * alpha,
                edgecolor=palette.GOAL,
                linewidth=1.2,
            )
        )
        ax.plot(
            mark.x,
            mark.y,
            marker='X',
            markersize=10,
            color=palette.GOAL,
            alpha=alpha,
            markeredgecolor=palette.MARK_EDGE,
            linestyle='none',
        )
        _label(ax, mark.x, mark.y, f'goal {mark.name}', palette.GOAL)
    start_x, start_y = scenario.start[0], scenario.start[1]
    ax.plot(
        start_x,
        start_y,
        marker='o',
        markersize=10,
        color=palette.START,
        markeredgecolor=palette.MARK_EDGE,
        linestyle='none',
    )
    _label(ax, start_x, start_y, 'start', palette.START)

    legend = [
        patches.Patch(color=palette.WALL, label='occupied'),
        patches.Patch(color=palette.UNKNOWN_SPACE, label='unknown (blocks light)'),
        Line2D(
            [],
            [],
            marker='*',
            color=palette.LIGHT,
            markerfacecolor=palette.LAMP,
            markersize=11,
            markeredgecolor=palette.LAMP_EDGE,
            label='searchlight and cone at t',
        ),
        Line2D([], [], marker='o', color=palette.START, linestyle='none', label='start'),
        Line2D([], [], marker='X', color=palette.GOAL, linestyle='none', label='goal'),
    ]
    if any(light.motion is not None for light in scenario.lights):
        legend.append(
            Line2D([], [], color=palette.LIGHT, linestyle=':', label='sweep / patrol route')
        )
    if threshold is not None:
        legend.append(
            Line2D(
                [], [], color=palette.DETECTION, linestyle='--', label=f'detection {threshold:g}'
            )
        )
    handles = legend + ax.get_legend_handles_labels()[0]
    ax.legend(
        handles=handles,
        loc='upper left',
        bbox_to_anchor=(0.0, -0.07),
        ncol=4,
        fontsize=8,
        frameon=False,
    )
    ax.set_aspect('equal')
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    name = getattr(scenario, 'name', 'scenario')
    ax.set_title(title or f'{name}: visibility at t = {t:g} s')
    return fig


def figure_pixels(fig: Figure) -> np.ndarray:
    """The figure drawn, (height, width, 3) uint8 RGB."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3]


def path_artists(fig: Figure) -> list[tuple[Line2D, Line2D]]:
    """(line, end marker) of each path ``scenario_figure`` drew, in the order of its paths."""
    drawn = [line for ax in fig.axes for line in ax.get_lines() if line.get_gid() == PATH_GID]
    return list(zip(drawn[::2], drawn[1::2], strict=True))


class Overlay:
    """A figure drawn many times with only some artists changing (a path's data, a title):
    everything else is drawn once into a kept background, and each ``pixels`` restores it and
    draws the changing artists and those drawn over them, in the figure's own order, so the
    pixels are those of drawing the whole figure (``figure_pixels``) at a fraction of the cost.

    ``changing``: artists of ``fig``'s axes. What the figure draws after the first of them
    goes to the background too where it touches nothing drawn after it that is redrawn (each
    with a margin of MARGIN_POINTS around it): not where a changing artist may draw (a clipped
    one's clip box, an unclipped one's band across the figure: a text may grow sideways).
    """

    MARGIN_POINTS = 4.0  # antialiasing, a tick mark or a text's box (its pad) past its extent

    def __init__(self, fig: Figure, changing: Iterable):
        changing = set(changing)
        order = []  # every artist in the order Figure.draw and Axes.draw draw them
        for child in sorted(fig.get_children()[1:], key=lambda a: a.get_zorder()):  # [0]: patch
            if hasattr(child, 'apply_aspect'):  # an Axes: its patch, then its artists
                inner = [a for a in child.get_children() if a is not child.patch]
                order += [child.patch, *sorted(inner, key=lambda a: a.get_zorder())]
            else:
                order.append(child)
        first = next(k for k, artist in enumerate(order) if artist in changing)
        self.canvas = FigureCanvasAgg(fig)
        renderer = self.canvas.get_renderer()
        fig.draw_without_rendering()  # lays the figure out: the extents below are final
        margin = self.MARGIN_POINTS * fig.dpi / 72
        self._over, taken = [], []  # what each frame draws; where it may draw (with margins)
        for artist in order[first:]:
            if not artist.get_visible():
                continue
            area = self._area(artist, fig, renderer, artist in changing)
            if area is None:  # draws nothing
                continue
            if artist in changing or any(area.overlaps(other) for other in taken):
                self._over.append(artist)
                taken.append(area.padded(margin))
        for artist in self._over:
            artist.set_animated(True)  # left out of the figure's own draw: the background
        self.canvas.draw()
        self._background = self.canvas.copy_from_bbox(fig.bbox)

    @staticmethod
    def _area(artist, fig: Figure, renderer, changing: bool) -> Bbox | None:
        """Where `artist` draws (may draw, if changing); None for an empty text; an artist
        that does not tell (an axis with no tick labels, say): its axes' box, else the whole
        figure."""
        clip = artist.get_clip_box() if artist.get_clip_on() else None
        box = clip if changing and clip is not None else artist.get_tightbbox(renderer)
        if box is None or not np.isfinite(box.extents).all():
            if not changing and isinstance(artist, Text):
                return None
            box = artist.axes.bbox if artist.axes is not None else fig.bbox
        if changing and clip is None:
            box = Bbox.from_extents(fig.bbox.x0, box.y0, fig.bbox.x1, box.y1)
        return box.padded(1.0)  # antialiasing

    def pixels(self) -> np.ndarray:
        """The figure as it stands now, (height, width, 3) uint8 RGB (a copy)."""
        self.canvas.restore_region(self._background)
        renderer = self.canvas.get_renderer()
        for artist in self._over:
            artist.draw(renderer)
        return np.array(self.canvas.buffer_rgba())[..., :3]
