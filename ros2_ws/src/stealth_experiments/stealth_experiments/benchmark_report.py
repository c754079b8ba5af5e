"""The benchmark's report: results.csv (one row per scenario, goal, track and method),
summary.md (per track and method) and benchmark.png; the learning track's learning.csv and
learning.png (``benchmark_learning_report``, which also writes its table). No Ray, no rclpy.

Per episode track (full, sensed) and method, over the rows that ran (``status`` ok; failed and
interrupted rows are counted apart):

- **undetected**: the fraction of episodes never detected (they reached the goal or ran out
  of steps);
- **success**: the undetected success rate, the fraction of episodes that reached the goal
  without being detected (detection ends an episode);
- **criterion**: the fraction that met the success criterion (``stealth_core.path_scores``:
  reached the goal undetected, path <= 1.1x the optimum's, accumulated exposure <= the
  optimum's + 0.1), the one the harness and `stealth train` judge greedy episodes by;
- **regret**: the mean normalised regret ``(vi_return - return) / (vi_return - floor)``, the
  floor being the return of being detected at the first step (``benchmark_methods.floor_of``):
  0 at the optimum, 1 as bad as being caught at once (a timeout that wandered in the light can
  be worse than 1);
- **mean return**: the mean undiscounted return (value iteration's is the optimum's);
- **path / optimum**: the mean over the successful rows of the path length over the optimum's
  (value iteration's path on the same scenario and goal);
- **exposure / optimum**: over the successful rows, the summed exposure over the optimum's
  summed exposure (a ratio of sums: an optimum in the dark has exposure 0); exposure is the
  accumulated visibility, the sum over the episode's steps of the judge's step visibility;
- **seconds**: the mean wall time per row (a learner's includes its training).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from matplotlib.figure import Figure
import numpy as np
from stealth_core import palette
from stealth_core.path_scores import DEFAULT_CRITERION, PathScores, meets_criterion
from stealth_core.reward import EpisodeOutcome

from stealth_experiments.benchmark_learning_report import LEARNING_FILES, learning_lines
from stealth_experiments.benchmark_methods import COLUMNS, EPISODE_TRACKS, METHODS

RESULT_FILES = ('results.csv', 'summary.md', 'benchmark.png', *LEARNING_FILES)  # all it writes


def write_csv(path: Path, rows: list[dict]) -> Path:
    """results.csv: COLUMNS, in this order; empty cells for what a failed row lacks."""
    with open(path, 'w', newline='', encoding='utf-8') as stream:
        writer = csv.DictWriter(stream, fieldnames=COLUMNS, extrasaction='ignore')
        writer.writeheader()
        for row in rows:
            writer.writerow({key: _cell(row.get(key)) for key in COLUMNS})
    return path


def _cell(value):
    if value is None:
        return ''
    if isinstance(value, float):
        return '' if math.isnan(value) else f'{value:.6g}'
    return value


def summarise(rows: list[dict]) -> list[dict]:
    """One entry per episode track and method present (EPISODE_TRACKS, then METHODS order): see
    the module docstring for each figure; None where no row gives it."""
    found = []
    for track in EPISODE_TRACKS:
        for method in METHODS:
            mine = [r for r in rows if r['track'] == track and r['method'] == method]
            if not mine:
                continue
            ran = [r for r in mine if r['status'] == 'ok']
            won = [r for r in ran if r['success']]
            met = [r for r in won if row_meets_criterion(r)]
            regrets = [r['regret'] for r in ran if _finite(r['regret'])]
            returns = [r['return'] for r in ran if _finite(r['return'])]
            lengths = [r['path_length'] / r['vi_path_length'] for r in won if r['vi_path_length']]
            vi_exposure = sum(r['vi_exposure'] for r in won)
            found.append({
                'track': track,
                'method': method,
                'rows': len(mine),
                'ran': len(ran),
                'failed': sum(r['status'] == 'failed' for r in mine),
                'interrupted': sum(r['status'] == 'interrupted' for r in mine),
                'success': len(won) / len(ran) if ran else None,
                'criterion': len(met) / len(ran) if ran else None,
                'detected': sum(bool(r['detected']) for r in ran) / len(ran) if ran else None,
                'undetected': sum(not r['detected'] for r in ran) / len(ran) if ran else None,
                'regret': float(np.mean(regrets)) if regrets else None,
                'return': float(np.mean(returns)) if returns else None,
                'path_ratio': float(np.mean(lengths)) if lengths else None,
                'exposure': float(np.mean([r['exposure'] for r in ran])) if ran else None,
                'exposure_ratio': (
                    sum(r['exposure'] for r in won) / vi_exposure if vi_exposure > 0 else None
                ),
                'seconds': float(np.mean([r['seconds'] for r in ran])) if ran else None,
            })  # fmt: skip
    return found


def row_meets_criterion(row: dict) -> bool:
    """Whether a row that ran met the success criterion (defaults) against value iteration's
    path on the same scenario and goal."""
    if not row['success']:
        return False
    scores = PathScores(EpisodeOutcome.SUCCESS, row.get('steps', 0), row['path_length'], 0.0,
                        row['exposure'])  # fmt: skip
    optimum = PathScores(EpisodeOutcome.SUCCESS, 0, row['vi_path_length'], 0.0,
                         row['vi_exposure'])  # fmt: skip
    return meets_criterion(scores, optimum, DEFAULT_CRITERION)


def _finite(value) -> bool:
    return value is not None and math.isfinite(value)


def _figure(value, digits: int = 3, percent: bool = False) -> str:
    if value is None:
        return '-'
    if percent:
        return f'{100 * value:.0f} %'
    return f'{round(value, digits) or 0.0:.{digits}f}'  # no '-0.000' for a rounding's sign


def write_summary(path: Path, rows: list[dict], settings: str, note: str = '') -> Path:
    """summary.md: a table per track (module docstring), the settings and any note."""
    lines = ['# Benchmark', '']
    if note:
        lines += [f'**{note}**', '']
    cases = {(r['scenario'], r['goal']) for r in rows}
    lines += [f'{len(cases)} scenario goals. {settings}', '']
    summary = summarise(rows)
    for track in EPISODE_TRACKS:
        mine = [s for s in summary if s['track'] == track]
        if not mine:
            continue
        lines += [
            f'## Track: {track}',
            '',
            '| method | undetected | success | criterion | regret | mean return '
            '| path / optimum | exposure / optimum | mean exposure | s per row | rows (failed) |',
            '|---|---|---|---|---|---|---|---|---|---|---|',
        ]
        for s in mine:
            failed = s['failed'] + s['interrupted']
            lines.append(
                f'| {s["method"]} | {_figure(s["undetected"], percent=True)} | '
                f'{_figure(s["success"], percent=True)} | '
                f'{_figure(s["criterion"], percent=True)} | {_figure(s["regret"])} | '
                f'{_figure(s["return"], 1)} | '
                f'{_figure(s["path_ratio"], 2)} | {_figure(s["exposure_ratio"], 2)} | '
                f'{_figure(s["exposure"], 2)} | {_figure(s["seconds"], 2)} | '
                f'{s["rows"]} ({failed}) |'
            )
        lines.append('')
    lines += [
        'undetected: never detected (reached the goal or ran out of steps). '
        'success: reached the goal undetected. criterion: met the success criterion '
        f'({DEFAULT_CRITERION.describe()}). regret: mean of (vi_return - return) / '
        '(vi_return - floor), floor = the return of being detected at the first step. '
        'mean return: the mean undiscounted return. '
        "path / optimum: mean path length over value iteration's, successful rows. "
        'exposure / optimum: summed exposure (accumulated step visibility) over the '
        "optimum's, successful rows.",
        '',
        *learning_lines(rows),
    ]
    failures: dict[tuple, list[str]] = {}
    for r in rows:
        if r['status'] != 'ok':
            key = (r['scenario'], r['goal'], r['status'], r['error'])
            failures.setdefault(key, []).append(f'{r["method"]} ({r["track"]})')
    if failures:
        lines += ['## Rows that did not run', '']
        lines += [
            f'- {scenario} {goal or "(goal unknown)"}: {status}: {", ".join(which)}: {error}'
            for (scenario, goal, status, error), which in failures.items()
        ]
        lines.append('')
    path.write_text('\n'.join(lines), encoding='utf-8')
    return path


def write_plot(path: Path, rows: list[dict]) -> Path | None:
    """benchmark.png: the success rate and the mean regret per method, a bar per episode
    track; None without rows of those."""
    summary = summarise(rows)
    methods = [m for m in METHODS if any(s['method'] == m for s in summary)]
    if not methods:
        return None
    figure = Figure(figsize=(max(8, 1.1 * len(methods) + 3), 7), dpi=100)
    width = 0.8 / len(EPISODE_TRACKS)
    x = np.arange(len(methods))
    for k, (key, title) in enumerate(
        (('success', 'undetected success rate'), ('regret', 'normalised regret (0: optimum)'))
    ):
        ax = figure.add_subplot(2, 1, k + 1)
        for t, track in enumerate(EPISODE_TRACKS):
            values = [
                next((s[key] for s in summary if s['track'] == track and s['method'] == m), None)
                for m in methods
            ]
            heights = [np.nan if v is None else v for v in values]
            ax.bar(
                x + (t - (len(EPISODE_TRACKS) - 1) / 2) * width, heights, width,
                color=palette.TRACKS[track], label=f'{track} track',
            )  # fmt: skip
        ax.set_xticks(x, methods, rotation=20, ha='right', fontsize=8)
        ax.set_ylabel(title)
        ax.grid(axis='y', alpha=0.3)
        if key == 'success':
            ax.set_ylim(0, 1.05)
            ax.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path)
    return path
