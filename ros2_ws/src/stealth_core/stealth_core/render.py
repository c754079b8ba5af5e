"""Pictures of a scenario: walls, unknown space, the visibility heatmap, cones, start, goals and
optionally paths, to PNG (for the README and for every run). The figure is drawn by
stealth_core.scenario_drawing; this module writes it (PNG, animated GIF, side-by-side
comparison) and is the `render` command.

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
from collections.abc import Sequence
import csv
import dataclasses
import math
import os
from pathlib import Path
import sys

import numpy as np

from stealth_core.scenario_drawing import (
    Overlay,
    figure_pixels,
    goal_marks,
    path_artists,
    scenario_figure,
)
from stealth_core.visibility_cache import scenario_visibility

DEFAULT_OUT_DIR = Path('docs/images/scenarios')
MAX_FPS = 100  # a GIF counts a frame's time in hundredths of a second


def gif_frame_ms(fps: float, name: str = 'fps') -> int:
    """How long a GIF frame shows at `fps` frames per second (ms); ValueError naming `name`
    unless 0 < fps <= MAX_FPS, so a bad rate stops before any frame is drawn."""
    if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise ValueError(
            f'{name}: expected frames per second, a number > 0 and at most {MAX_FPS} (a GIF '
            f'frame lasts at least 10 ms), got {fps:g}'
        )
    return round(1000 / fps)


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


def render_scenario(scenario, out_png: str | os.PathLike, **drawing) -> Path:
    """Draw the scenario (``scenario_figure``'s keyword arguments: paths, field, t, goal,
    path_labels, title, cache_dir) and write it to out_png; returns the path written."""
    fig = scenario_figure(scenario, **drawing)
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, bbox_inches='tight', pad_inches=0.15)
    return out_png


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
    duration = gif_frame_ms(fps)
    paths = [np.asarray(p, dtype=float).reshape(-1, 2) for p in paths]
    timing = getattr(scenario, 'timing', None)
    step = timing.step_seconds if timing is not None else 1.0
    if frames is None:
        cycle = timing.cycle_bins // timing.bins_per_step if timing is not None else 1
        frames = max([len(p) for p in paths] + [cycle])
    if frames < 1:
        raise ValueError(f'frames: expected a number >= 1, got {frames}')
    labels = list(path_labels) if path_labels else [f'path {k + 1}' for k in range(len(paths))]
    name = getattr(scenario, 'name', 'scenario')
    moving = any(light.is_moving for light in scenario.lights)
    phases: dict[float, list[int]] = {}  # the frames of each instant of the lights' cycle
    for k in range(frames):
        t = k * step if moving else 0.0  # static lights: every frame shows the same light
        if timing is not None:  # the same instants every cycle: one figure serves them all
            t = ((k * timing.bins_per_step) % timing.cycle_bins) * timing.bin_seconds
        phases.setdefault(t, []).append(k)
    images = [None] * frames
    done = 0
    for t, numbers in phases.items():  # a figure per phase, drawn once; its frames overlaid
        fig = scenario_figure(
            scenario, paths, t=t, goal=goal, path_labels=labels, cache_dir=cache_dir, dpi=60
        )
        drawn = path_artists(fig)
        title = fig.axes[0].title
        overlay = Overlay(fig, [title, *(artist for pair in drawn for artist in pair)])
        for k in numbers:
            for points, (line, end) in zip(paths, drawn, strict=True):
                walked = points[: min(k, len(points) - 1) + 1]
                line.set_data(walked[:, 0], walked[:, 1])
                end.set_data(walked[-1:, 0], walked[-1:, 1])
            title.set_text(f'{name}: step {k}, t = {k * step:g} s')
            images[k] = Image.fromarray(overlay.pixels()).convert('P', palette=Image.ADAPTIVE)
            done += 1
            if progress is not None:
                progress(done, frames)
    out.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(
        out,
        save_all=True,
        append_images=images[1:],
        duration=duration,
        loop=0,
        optimize=False,
    )
    return out


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

    from stealth_core.planners import optimal_path

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
        paths = [optimal_path(variant, goal)[0]] if optimum else []
        figure = scenario_figure(
            variant, paths, field=field, goal=goal, title=title, vmax=vmax,
            path_labels=['optimum (value iteration)'],
        )  # fmt: skip
        panels.append(figure_pixels(figure))
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
    from stealth_core.scenario import scenario_paths

    return list(scenario_paths())


def render_all(out_dir: str | os.PathLike = DEFAULT_OUT_DIR, cache_dir=None) -> list[Path]:
    """Write <out_dir>/<name>.png for every shipped scenario."""
    from stealth_core.scenario import load_scenario

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
        if args.animate:
            gif_frame_ms(args.fps, '--fps')
        from stealth_core.path_scores import PathScores, describe, polyline_length
        from stealth_core.planners import optimal_path
        from stealth_core.scenario import find_scenario, load_scenario

        scenario = load_scenario(find_scenario(args.scenario))
        if args.goal is not None and args.goal not in [m.name for m in goal_marks(scenario)]:
            parser.error(f'--goal {args.goal!r}: the scenario has no such goal')
        if args.bounce_compare:
            out = args.output or f'{scenario.name}-bounce-compare.png'
            print(render_bounce_comparison(scenario, out, args.goal, args.optimum, args.cache_dir))
            return 0
        paths = [read_path_csv(path) for path in args.path]
        labels = [Path(path).stem for path in args.path]
        optimum = None
        if args.optimum and scenario.exposure is not None and not args.animate:
            # the optimum with the robot's footprint at each pose, and the one without exposure
            points, optimum = optimal_path(scenario, args.goal, poses=True)
            paths.append(points)
            labels.append('optimum (value iteration), footprint at each step')
            plain = dataclasses.replace(scenario, exposure=None)
            paths.append(optimal_path(plain, args.goal)[0])
            labels.append('optimum without exposure')
        elif args.optimum:
            points, optimum = optimal_path(scenario, args.goal)
            paths.append(points)
            labels.append('optimum (value iteration)')
        if optimum is not None:  # its scores, and each given path's length against its
            given = len(args.path)
            labels[given] += f': {describe(PathScores.of_path(optimum))}'
            labels[:given] = [
                f'{label}: {polyline_length(points):.1f} m '
                f"({polyline_length(points) / optimum.path_length:.2f}x the optimum's)"
                for label, points in zip(labels[:given], paths[:given], strict=True)
            ]
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


if __name__ == '__main__':
    sys.exit(main())
