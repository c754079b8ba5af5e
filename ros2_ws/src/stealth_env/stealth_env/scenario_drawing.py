"""A scenario drawn at one time: walls, unknown space, the visibility heatmap, the lights'
cones, start, goals and paths, as a matplotlib Figure (no pyplot: no global state, no display).
stealth_env.render writes these figures as PNGs, animated GIFs and side-by-side comparisons;
the colours are stealth_env.palette's.
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
from mpl_toolkits.axes_grid1 import make_axes_locatable
import numpy as np

from stealth_env import palette
from stealth_env.searchlight import PatrolMotion, Searchlight, SweepMotion
from stealth_env.visibility import scenario_visibility

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
        ax.plot(points[:, 0], points[:, 1], '-', color=colour, linewidth=1.8, label=label)
        ax.plot(points[-1, 0], points[-1, 1], 'o', color=colour, markersize=4)
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
