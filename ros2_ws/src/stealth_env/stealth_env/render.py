"""Pictures of a scenario: walls, unknown space, the visibility heatmap, cones, start, goals and
optionally paths, to PNG (for the README and for every run).

    render lgfloor -o lgfloor.png --path run.csv --time 2.5
    render --all                     # docs/images/scenarios/<name>.png for every scenario
    render map1-moving --animate map1-moving.gif --optimum --path learned.csv

``--animate`` writes an animated GIF: the lights moving (one frame per step of the scenario's
``step_seconds``) and each path walked one point per frame; ``--optimum`` adds the value-iteration
optimum on the (time-expanded) lattice. ``--bounce-compare`` draws a scenario with one-bounce
light twice, side by side on one colour scale: the direct light alone, then direct + bounce
(each with its own optimum when ``--optimum`` is given).

    render map1-bounce --bounce-compare --optimum -o docs/images/map1-bounce-compare.png
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Sequence
import csv
import dataclasses
import math
import os
from pathlib import Path
import sys
from typing import NamedTuple

from matplotlib import patches
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure  # no pyplot: no global state, no display needed (Agg)
from matplotlib.lines import Line2D
from mpl_toolkits.axes_grid1 import make_axes_locatable
import numpy as np

from stealth_env.searchlight import PatrolMotion, Searchlight, SweepMotion
from stealth_env.visibility import scenario_visibility

DEFAULT_OUT_DIR = Path('docs/images/scenarios')
HEATMAP = 'YlOrRd'
WALL_COLOUR = (0.08, 0.08, 0.1, 1.0)
UNKNOWN_COLOUR = (0.62, 0.62, 0.65, 1.0)
DARK_COLOUR = '#f4f6fb'  # free cells no light reaches
LIGHT_COLOUR = '#1f4e9e'
START_COLOUR = '#1a9641'
GOAL_COLOUR = '#7b3294'
PATH_COLOURS = ('#0571b0', '#d01c8b', '#018571', '#000000', '#8c510a', '#762a83')


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


def read_path_csv(path: str | os.PathLike) -> np.ndarray:
    """(n, 2) array of x, y (m) from a CSV of 'x,y' rows; a first row of names is skipped."""
    points = []
    with open(path, newline='', encoding='utf-8') as stream:
        for number, row in enumerate(csv.reader(stream), start=1):
            if not row or row[0].lstrip().startswith('#'):
                continue
            try:
                x, y = float(row[0]), float(row[1])
            except (ValueError, IndexError):
                if number == 1 and not points:
                    continue  # header
                message = f'{path}: line {number}: expected "x,y" numbers, got {row}'
                raise ValueError(message) from None
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ValueError(f'{path}: line {number}: coordinates must be finite, got {row}')
            points.append((x, y))
    if not points:
        raise ValueError(f'{path}: no "x,y" rows')
    return np.array(points)


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
        cmap=HEATMAP,
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
        cmap=ListedColormap([(0, 0, 0, 0), UNKNOWN_COLOUR, WALL_COLOUR]),
    )
    if threshold is not None and total.max() >= threshold:
        xs = x0 + (np.arange(total.shape[1]) + 0.5) * occupancy.resolution
        ys = y0 + (np.arange(total.shape[0]) + 0.5) * occupancy.resolution
        ax.contour(
            xs,
            ys,
            np.where(blocked, 0.0, total),
            levels=[threshold],
            colors='#b2182b',
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
        _draw_cone(ax, sweep, edgecolor=LIGHT_COLOUR, linewidth=0.8, linestyle=':', alpha=0.7)
    if isinstance(light.motion, PatrolMotion):  # the closed route, faint
        route = np.array([(light.x, light.y), *light.motion.waypoints, (light.x, light.y)])
        ax.plot(route[:, 0], route[:, 1], ':', color=LIGHT_COLOUR, linewidth=1.0, alpha=0.8)
    _draw_cone(ax, now, edgecolor=LIGHT_COLOUR, linewidth=1.0, alpha=0.6)
    ax.plot(now.x, now.y, marker='*', markersize=13, color='#ffd92f', markeredgecolor='black')
    ax.annotate(
        now.name,
        (now.x, now.y),
        xytext=(6, 6),
        textcoords='offset points',
        fontsize=8,
        color=LIGHT_COLOUR,
        fontweight='bold',
        bbox={'boxstyle': 'round,pad=0.15', 'facecolor': 'white', 'alpha': 0.75, 'linewidth': 0},
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
        bbox={'boxstyle': 'round,pad=0.15', 'facecolor': 'white', 'alpha': 0.8, 'linewidth': 0},
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


def render_scenario(scenario, out_png: str | os.PathLike, **drawing) -> Path:
    """Draw the scenario (``scenario_figure``'s keyword arguments: paths, field, t, goal,
    path_labels, title, cache_dir) and write it to out_png; returns the path written."""
    fig = scenario_figure(scenario, **drawing)
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, bbox_inches='tight', pad_inches=0.15)
    return out_png


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
    ax.set_facecolor(DARK_COLOUR)
    image = _draw_map(ax, occupancy, np.asarray(field, dtype=float), threshold, vmax)
    bar_axes = make_axes_locatable(ax).append_axes('right', size='3%', pad=0.12)
    colourbar = fig.colorbar(image, cax=bar_axes)
    colourbar.set_label('total visibility (sum of light intensities)')
    if threshold is not None:
        colourbar.ax.axhline(threshold, color='#b2182b', linestyle='--', linewidth=1.5)

    for light in scenario.lights:
        _draw_light(ax, light, t)

    footprint = getattr(scenario, 'exposure', None)
    for number, points in enumerate(paths):
        points = np.asarray(points, dtype=float)
        poses = points if points.ndim == 2 and points.shape[1] == 3 else None
        points = points.reshape(-1, 2) if poses is None else poses[:, :2]
        label = path_labels[number] if path_labels else f'path {number + 1}'
        colour = PATH_COLOURS[number % len(PATH_COLOURS)]
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
                facecolor=GOAL_COLOUR,
                alpha=0.25 * alpha,
                edgecolor=GOAL_COLOUR,
                linewidth=1.2,
            )
        )
        ax.plot(
            mark.x,
            mark.y,
            marker='X',
            markersize=10,
            color=GOAL_COLOUR,
            alpha=alpha,
            markeredgecolor='white',
            linestyle='none',
        )
        _label(ax, mark.x, mark.y, f'goal {mark.name}', GOAL_COLOUR)
    start_x, start_y = scenario.start[0], scenario.start[1]
    ax.plot(
        start_x,
        start_y,
        marker='o',
        markersize=10,
        color=START_COLOUR,
        markeredgecolor='white',
        linestyle='none',
    )
    _label(ax, start_x, start_y, 'start', START_COLOUR)

    legend = [
        patches.Patch(color=WALL_COLOUR, label='occupied'),
        patches.Patch(color=UNKNOWN_COLOUR, label='unknown (blocks light)'),
        Line2D(
            [],
            [],
            marker='*',
            color=LIGHT_COLOUR,
            markerfacecolor='#ffd92f',
            markersize=11,
            markeredgecolor='black',
            label='searchlight and cone at t',
        ),
        Line2D([], [], marker='o', color=START_COLOUR, linestyle='none', label='start'),
        Line2D([], [], marker='X', color=GOAL_COLOUR, linestyle='none', label='goal'),
    ]
    if any(light.motion is not None for light in scenario.lights):
        legend.append(
            Line2D([], [], color=LIGHT_COLOUR, linestyle=':', label='sweep / patrol route')
        )
    if threshold is not None:
        legend.append(
            Line2D([], [], color='#b2182b', linestyle='--', label=f'detection {threshold:g}')
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


def animate_scenario(
    scenario,
    out: str | os.PathLike,
    paths: Sequence[Sequence[Sequence[float]]] = (),
    path_labels: Sequence[str] | None = None,
    goal: str | None = None,
    frames: int | None = None,
    fps: float = 4.0,
    cache_dir: str | os.PathLike | None = None,
    progress=None,
) -> Path:
    """An animated GIF of the lights moving, each path walked one point per frame (a point per
    step, ``step_seconds`` of the scenario apart; a path's later frames hold its last point).

    frames: how many (default: the longest path's points, or one joint cycle of the lights);
    progress: called with (frame, frames) after each frame. Returns the path written.
    """
    from PIL import Image

    out = Path(out)
    if out.suffix.lower() != '.gif':
        raise ValueError(f'{out}: expected a .gif file name (an animated GIF)')
    paths = [np.asarray(p, dtype=float).reshape(-1, 2) for p in paths]
    timing = getattr(scenario, 'timing', None)
    step = timing.step_seconds if timing is not None else 1.0
    if frames is None:
        cycle = timing.cycle_bins // timing.bins_per_step if timing is not None else 1
        frames = max([len(p) for p in paths] + [cycle])
    if frames < 1:
        raise ValueError(f'frames: expected a number >= 1, got {frames}')
    labels = list(path_labels) if path_labels else [f'path {k + 1}' for k in range(len(paths))]
    images = []
    name = getattr(scenario, 'name', 'scenario')
    for k in range(frames):
        t = k * step
        if timing is not None:  # the same instants every cycle: the field cache serves them
            t = ((k * timing.bins_per_step) % timing.cycle_bins) * timing.bin_seconds
        walked = [p[: min(k, len(p) - 1) + 1] for p in paths]
        fig = scenario_figure(
            scenario,
            walked,
            t=t,
            goal=goal,
            path_labels=labels,
            title=f'{name}: step {k}, t = {k * step:g} s',
            cache_dir=cache_dir,
            dpi=60,
        )
        images.append(Image.fromarray(_pixels(fig)).convert('P', palette=Image.ADAPTIVE))
        if progress is not None:
            progress(k + 1, frames)
    out.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(
        out,
        save_all=True,
        append_images=images[1:],
        duration=round(1000 / fps),
        loop=0,
        optimize=False,
    )
    return out


def _pixels(fig: Figure) -> np.ndarray:
    """The figure drawn, (height, width, 3) uint8 RGB."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3]


def render_bounce_comparison(
    scenario,
    out_png: str | os.PathLike,
    goal: str | None = None,
    optimum: bool = False,
    cache_dir: str | os.PathLike | None = None,
) -> Path:
    """A PNG of the scenario's direct light beside its direct + bounce light, on one colour
    scale; with optimum, each panel shows the value-iteration optimum of its own lighting.
    ValueError when the scenario has no bounce."""
    from PIL import Image

    bounce = getattr(scenario, 'bounce', None)
    if bounce is None:
        raise ValueError(
            f'{getattr(scenario, "name", "scenario")}: no one-bounce light to compare (its'
            " albedo is 0); give a scenario with a 'bounce' field, e.g. map1-bounce"
        )
    direct = dataclasses.replace(scenario, bounce=None)
    fields = [scenario_visibility(s, cache_dir=cache_dir)[0] for s in (direct, scenario)]
    free = ~scenario.map.blocked
    vmax = max(float(field[free].max(initial=0.0)) for field in fields)
    titles = (
        f'{scenario.name}: direct light only',
        f'{scenario.name}: direct + one bounce (albedo {bounce.albedo:g}, {bounce.range:g} m)',
    )
    panels = []
    for variant, field, title in zip((direct, scenario), fields, titles, strict=True):
        paths = [optimal_points(variant, goal)] if optimum else []
        figure = scenario_figure(
            variant, paths, field=field, goal=goal, title=title, vmax=vmax,
            path_labels=['optimum (value iteration)'],
        )  # fmt: skip
        panels.append(_pixels(figure))
    height = max(panel.shape[0] for panel in panels)
    padded = [
        np.pad(p, ((0, height - p.shape[0]), (0, 0), (0, 0)), constant_values=255) for p in panels
    ]
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.concatenate(padded, axis=1)).save(out_png)
    return out_png


def shipped_scenarios() -> list[Path]:
    """Every scenarios/*.yaml of the repository."""
    from stealth_env.scenario import scenario_paths

    return list(scenario_paths())


def render_all(out_dir: str | os.PathLike = DEFAULT_OUT_DIR, cache_dir=None) -> list[Path]:
    """Write <out_dir>/<name>.png for every shipped scenario."""
    from stealth_env.scenario import load_scenario

    written = []
    for path in shipped_scenarios():
        scenario = load_scenario(path)
        written.append(
            render_scenario(scenario, Path(out_dir) / f'{scenario.name}.png', cache_dir=cache_dir)
        )
    return written


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='render',
        description='Render a stealth-nav scenario (walls, unknown, visibility heatmap, cones,'
        ' start, goals, paths) to PNG.',
    )
    parser.add_argument('scenario', nargs='?', help='scenario name (e.g. lgfloor) or YAML path')
    parser.add_argument('-o', '--output', help='PNG to write (default: <scenario name>.png)')
    parser.add_argument(
        '--path',
        action='append',
        default=[],
        metavar='FILE.csv',
        help='path to draw, a CSV of x,y rows in metres (repeatable)',
    )
    parser.add_argument('--goal', help='name of the goal pursued (highlighted)')
    parser.add_argument('--time', type=float, default=0.0, help='time (s) for moving lights')
    parser.add_argument(
        '--all',
        action='store_true',
        help=f'render every shipped scenario into --out-dir (default {DEFAULT_OUT_DIR})',
    )
    parser.add_argument('--out-dir', default=str(DEFAULT_OUT_DIR), help='directory for --all')
    parser.add_argument(
        '--animate',
        metavar='OUT.gif',
        help='write an animated GIF of the lights moving and the paths walked, step by step',
    )
    parser.add_argument(
        '--optimum',
        action='store_true',
        help='also draw the value-iteration optimum on the lattice (time-expanded where lights'
        ' move)',
    )
    parser.add_argument(
        '--bounce-compare',
        action='store_true',
        help='a scenario with one-bounce light: its direct light beside direct + bounce, on one'
        ' colour scale (with --optimum, each with its own optimum)',
    )
    parser.add_argument('--frames', type=int, help='--animate: frames (default: longest path)')
    parser.add_argument('--fps', type=float, default=4.0, help='--animate: frames per second')
    parser.add_argument('--cache-dir', help='visibility cache (default $STEALTH_NAV_CACHE)')
    args = parser.parse_args(argv)

    try:
        if args.all:
            for written in render_all(args.out_dir, args.cache_dir):
                print(written)
            return 0
        if not args.scenario:
            parser.error('give a scenario name or path, or --all')
        from stealth_env.scenario import find_scenario, load_scenario

        scenario = load_scenario(find_scenario(args.scenario))
        if args.goal is not None and args.goal not in [m.name for m in goal_marks(scenario)]:
            parser.error(f'--goal {args.goal!r}: the scenario has no such goal')
        if args.bounce_compare:
            out = args.output or f'{scenario.name}-bounce-compare.png'
            print(render_bounce_comparison(scenario, out, args.goal, args.optimum, args.cache_dir))
            return 0
        paths = [read_path_csv(path) for path in args.path]
        labels = [Path(path).stem for path in args.path]
        if args.optimum and scenario.exposure is not None and not args.animate:
            # the optimum with the robot's footprint at each pose, and the one without exposure
            paths.append(optimal_points(scenario, args.goal, poses=True))
            labels.append('optimum (value iteration), footprint at each step')
            plain = dataclasses.replace(scenario, exposure=None)
            paths.append(optimal_points(plain, args.goal))
            labels.append('optimum without exposure')
        elif args.optimum:
            paths.append(optimal_points(scenario, args.goal))
            labels.append('optimum (value iteration)')
        if args.animate:
            print(
                animate_scenario(
                    scenario,
                    args.animate,
                    paths,
                    labels,
                    goal=args.goal,
                    frames=args.frames,
                    fps=args.fps,
                    cache_dir=args.cache_dir,
                    progress=_show_progress,
                )
            )
            return 0
        out = args.output or f'{scenario.name}.png'
        written = render_scenario(
            scenario,
            out,
            paths=paths,
            t=args.time,
            goal=args.goal,
            path_labels=labels,
            cache_dir=args.cache_dir,
        )
    except (OSError, ValueError) as error:
        print(f'render: {error}', file=sys.stderr)
        return 1
    print(written)
    return 0


def _show_progress(done: int, total: int) -> None:
    print(f'\rrender: frame {done}/{total}', end='\n' if done == total else '', file=sys.stderr)


def optimal_points(scenario, goal: str | None = None, poses: bool = False) -> np.ndarray:
    """(steps + 1, 2): the positions of the value-iteration optimum from the start; with
    ``poses``, (steps + 1, 3) with the yaw (rad) of each place's heading."""
    from stealth_env.planners import LatticeModel, follow, value_iteration, walk
    from stealth_env.task import StealthTask

    model = LatticeModel.build(StealthTask(scenario, goal))
    optimum = value_iteration(model)
    path = follow(model, lambda i: int(optimum.policy[i]))
    points = walk(model, path).points
    if not poses:
        return points
    yaws = model.heading_of(path[: len(points)]) * (np.pi / 2)
    return np.column_stack([points, yaws])


if __name__ == '__main__':
    sys.exit(main())
