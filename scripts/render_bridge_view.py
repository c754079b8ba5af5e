#!/usr/bin/env python3
"""Draw what the Foxglove bridge served, top-down, as the layout's 3D panel shows it.

    python scripts/render_bridge_view.py SAMPLES.json OUT.png [--title TEXT]

SAMPLES.json is what tools/foxglove-ws-check/client.mjs writes with --samples: the last message
of each topic, decoded by Foxglove's own CDR reader from the schema the bridge advertised. Drawn
(frame map, metres): /map (free white, occupied black, unknown grey), /visibility_grid over it
(0-100 of the detection threshold, YlOrRd, dark cells left clear) over the searchlight cones
of /searchlight_markers (their own vertex colours, faint), /planned_path (value iteration's
optimum), /ground_truth and /amcl_pose (with its 2-sigma covariance ellipse) and the /scan
points from the estimate. A rendering of the bridge's data with matplotlib, not a screenshot
of Foxglove. A missing topic is left out; a file that is not such JSON is one line and exit
status 1.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys

import numpy as np

FREE, UNKNOWN, OCCUPIED = (1.0, 1.0, 1.0), (0.75, 0.75, 0.75), (0.0, 0.0, 0.0)
CONE_ALPHA = 0.25  # the cones faint, under the visibility grid


def grid_image(grid: dict) -> tuple[np.ndarray, list[float]]:
    """(data as a (height, width) array, extent [x0, x1, y0, y1]) of an OccupancyGrid."""
    info = grid['info']
    width, height, resolution = info['width'], info['height'], info['resolution']
    data = np.asarray(grid['data'], dtype=np.int16).reshape(height, width)
    x0, y0 = info['origin']['position']['x'], info['origin']['position']['y']
    return data, [x0, x0 + width * resolution, y0, y0 + height * resolution]


def map_rgb(data: np.ndarray) -> np.ndarray:
    rgb = np.empty((*data.shape, 3))
    rgb[:] = UNKNOWN
    rgb[(data >= 0) & (data < 50)] = FREE
    rgb[data >= 50] = OCCUPIED
    return rgb


def yaw_of(q: dict) -> float:
    return math.atan2(2 * (q['w'] * q['z'] + q['x'] * q['y']), 1 - 2 * (q['y'] ** 2 + q['z'] ** 2))


def covariance_ellipse(covariance: list[float], sigmas: float = 2.0):
    """(width, height, angle in degrees) of the x-y block of a 6x6 pose covariance."""
    block = np.array([[covariance[0], covariance[1]], [covariance[6], covariance[7]]])
    values, vectors = np.linalg.eigh(block)
    values = np.clip(values, 0.0, None)
    angle = math.degrees(math.atan2(vectors[1, 1], vectors[0, 1]))
    return 2 * sigmas * math.sqrt(values[1]), 2 * sigmas * math.sqrt(values[0]), angle


def draw(samples: dict, out: Path, title: str | None = None) -> Path:
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure
    from matplotlib.patches import Ellipse, FancyArrow

    fig = Figure(figsize=(8, 8), dpi=110)
    ax = fig.add_subplot()
    ax.set_aspect('equal')
    ax.set_xlabel('x (m, frame map)')
    ax.set_ylabel('y (m)')
    if 'map' in samples:
        data, extent = grid_image(samples['map'])
        ax.imshow(map_rgb(data), origin='lower', extent=extent, interpolation='nearest')
    for marker in samples.get('searchlight_markers', {}).get('markers', []):
        if marker['ns'] != 'cones' or len(marker['points']) < 3:
            continue
        points = [(p['x'], p['y']) for p in marker['points']]
        colours = [(c['r'], c['g'], c['b'], CONE_ALPHA) for c in marker['colors']] or None
        triangles = [points[i : i + 3] for i in range(0, len(points) - 2, 3)]
        faces = colours[0::3] if colours else 'orange'
        ax.add_collection(PolyCollection(triangles, facecolors=faces, edgecolors='none'))
    if 'visibility_grid' in samples:
        levels, extent = grid_image(samples['visibility_grid'])
        shown = np.ma.masked_where(levels <= 0, levels)
        image = ax.imshow(shown, origin='lower', extent=extent, cmap='YlOrRd', vmin=0,
                          vmax=100, alpha=0.6, interpolation='nearest')  # fmt: skip
        fig.colorbar(image, ax=ax, shrink=0.7, label='visibility_grid (% of detection threshold)')
    if 'planned_path' in samples:
        xy = [(p['pose']['position']['x'], p['pose']['position']['y'])
              for p in samples['planned_path']['poses']]  # fmt: skip
        if xy:
            ax.plot(*np.array(xy).T, color='#253494', linestyle=':', linewidth=2,
                    label='planned_path (value iteration)')  # fmt: skip
    if 'ground_truth' in samples:
        pose = samples['ground_truth']['pose']['pose']
        ax.plot(pose['position']['x'], pose['position']['y'], 'o', color='#1a9641',
                markersize=7, label='ground_truth')  # fmt: skip
    if 'amcl_pose' in samples:
        pose = samples['amcl_pose']['pose']
        x, y = pose['pose']['position']['x'], pose['pose']['position']['y']
        yaw = yaw_of(pose['pose']['orientation'])
        width, height, angle = covariance_ellipse(pose['covariance'])
        ax.add_patch(Ellipse((x, y), max(width, 0.05), max(height, 0.05), angle=angle,
                             facecolor='#19875455', edgecolor='#198754'))  # fmt: skip
        ax.add_patch(FancyArrow(x, y, 0.6 * math.cos(yaw), 0.6 * math.sin(yaw), width=0.08,
                                color='#1f4e9e', label='amcl_pose (2-sigma ellipse)'))  # fmt: skip
        if 'scan' in samples:
            scan = samples['scan']
            ranges = np.asarray(scan['ranges'], dtype=float)
            angles = scan['angle_min'] + scan['angle_increment'] * np.arange(len(ranges))
            ok = (
                np.isfinite(ranges) & (ranges >= scan['range_min']) & (ranges <= scan['range_max'])
            )
            ax.scatter(x + ranges[ok] * np.cos(yaw + angles[ok]),
                       y + ranges[ok] * np.sin(yaw + angles[ok]), s=4, color='#ff5f1f',
                       label='scan (from the estimate)')  # fmt: skip
    ax.legend(loc='upper right', fontsize=8)
    ax.set_title(title or 'What the bridge served (rendered with matplotlib, not Foxglove)')
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, bbox_inches='tight')
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('samples', type=Path, help='client.mjs --samples output (JSON)')
    parser.add_argument('out', type=Path, help='the PNG to write')
    parser.add_argument('--title', help='title above the picture')
    args = parser.parse_args(argv)
    try:
        raw = json.loads(args.samples.read_text())
    except (OSError, ValueError) as error:
        print(f'render_bridge_view: {args.samples}: not readable JSON ({error})', file=sys.stderr)
        return 1
    if not isinstance(raw, dict):
        print(f'render_bridge_view: {args.samples}: expected an object by topic', file=sys.stderr)
        return 1
    samples = {topic.lstrip('/'): message for topic, message in raw.items()}
    print(draw(samples, args.out, args.title))
    return 0


if __name__ == '__main__':
    sys.exit(main())
