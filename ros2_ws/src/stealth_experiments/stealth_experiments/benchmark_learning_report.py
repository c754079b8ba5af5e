"""The learning track's report (``benchmark_learning``): its table in summary.md, learning.csv
(one line per seed) and learning.png (the regret curves). No Ray, no rclpy.

Per method, over the scenario goals its learning rows ran on: on how many the median seed met
the criterion, and the median over them of each row's median (a row whose median seed never
met it counting as more than any, as ``benchmark_learning.median_of``) of the episodes to the
criterion, the detections, steps and seconds before it, and the detections over the
whole budget.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from matplotlib.figure import Figure
import numpy as np
from stealth_core import palette
from stealth_core.path_scores import DEFAULT_CRITERION

from stealth_experiments.benchmark_learning import LEARNING_COLUMNS, median_of
from stealth_experiments.harness import STREAK

LEARNING_FILES = ('learning.csv', 'learning.png')
SEED_COLUMNS = (
    'scenario', 'goal', 'method', 'seed', 'episodes_to_criterion', 'detections_to_criterion',
    'steps_to_criterion', 'seconds_to_criterion', 'episodes', 'budget', 'training_detections',
    'cumulative_detections',
)  # fmt: skip
MAX_PANELS = 12  # scenario goals drawn in learning.png (every one is in learning.csv)


def learning_rows(rows: list[dict]) -> list[dict]:
    """The learning track's rows that ran, with their seeds."""
    return [r for r in rows if r['track'] == 'learning' and r['status'] == 'ok' and r.get('seeds')]


def summarise_learning(rows: list[dict]) -> list[dict]:
    """One entry per method with learning rows (module docstring), in their order."""
    found = []
    for method in dict.fromkeys(r['method'] for r in rows if r['track'] == 'learning'):
        mine = [r for r in rows if r['track'] == 'learning' and r['method'] == method]
        ran = [r for r in mine if r['status'] == 'ok']
        entry = {
            'method': method,
            'rows': len(mine),
            'ran': len(ran),
            'met': sum(r['episodes_to_criterion'] is not None for r in ran),
            'seconds': float(np.mean([r['seconds'] for r in ran])) if ran else None,
        }
        for key in LEARNING_COLUMNS[1:]:
            entry[key] = median_of(r[key] for r in ran)
        found.append(entry)
    return found


def learning_lines(rows: list[dict]) -> list[str]:
    """summary.md's section of the learning track (none without learning rows)."""
    summary = summarise_learning(rows)
    if not summary:
        return []
    seeds = {len(r['seeds']) for r in learning_rows(rows)}
    lines = [
        '## Track: learning',
        '',
        '| method | criterion met (median seed) | episodes to criterion | detections before it '
        '| steps before it | s before it | detections in the budget | s per row | rows (failed) |',
        '|---|---|---|---|---|---|---|---|---|',
    ]
    for s in summary:
        lines.append(
            f'| {s["method"]} | {s["met"]}/{s["ran"]} | {_number(s["episodes_to_criterion"])} | '
            f'{_number(s["detections_to_criterion"])} | {_number(s["steps_to_criterion"])} | '
            f'{_number(s["seconds_to_criterion"], 2)} | {_number(s["training_detections"])} | '
            f'{_number(s["seconds"], 2)} | {s["rows"]} ({s["rows"] - s["ran"]}) |'
        )
    lines += [
        '',
        f'episodes to criterion: training episodes until the first of {STREAK} greedy '
        f'evaluations in a row that met the success criterion ({DEFAULT_CRITERION.describe()}), '
        'a greedy evaluation after every episode; detections (training episodes that ended '
        'DETECTED), environment steps and wall time (its greedy evaluations included) up to it. '
        f'Each row the median over its {"/".join(str(n) for n in sorted(seeds)) or "-"} seeds, '
        'each figure here the median over the scenario goals (a row whose median seed never met '
        'the criterion counts as more than any; never: most never did). Per seed: learning.csv; '
        'cumulative detections against episodes: learning.png.',
        '',
    ]
    return lines


def _number(value, digits: int = 0) -> str:
    return 'never' if value is None else f'{value:.{digits}f}'


def write_learning_csv(path: Path, rows: list[dict]) -> Path | None:
    """learning.csv: one line per learning row and seed (SEED_COLUMNS; cumulative_detections,
    the regret curve: the count after each training episode, space-separated); None without
    learning rows."""
    ran = learning_rows(rows)
    if not ran:
        return None
    with open(path, 'w', newline='', encoding='utf-8') as stream:
        writer = csv.DictWriter(stream, fieldnames=SEED_COLUMNS, extrasaction='ignore')
        writer.writeheader()
        for row in ran:
            for seed in row['seeds']:
                writer.writerow({
                    **{key: _cell(value) for key, value in seed.items()},
                    'scenario': row['scenario'],
                    'goal': row['goal'],
                    'method': row['method'],
                    'cumulative_detections': ' '.join(str(v) for v in seed['curve']),
                })  # fmt: skip
    return path


def _cell(value):
    if value is None:
        return ''
    return f'{value:.6g}' if isinstance(value, float) else value


def band(curves: list[list[int]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(median, min, max) over seeds at each episode, over the episodes every seed trained (a
    seed's curve ends where its training did)."""
    length = min(len(c) for c in curves)
    stacked = np.array([c[:length] for c in curves], dtype=float)
    return np.median(stacked, axis=0), stacked.min(axis=0), stacked.max(axis=0)


def learner_colours(methods) -> dict[str, str]:
    """Each learner's colour (palette.LEARNERS), one of the path colours no learner has for a
    learner without one (light-model, a new learner)."""
    free = [c for c in palette.PATHS if c not in palette.LEARNERS.values()] or list(palette.PATHS)
    others = [m for m in methods if m not in palette.LEARNERS]
    return {m: palette.LEARNERS.get(m) or free[others.index(m) % len(free)] for m in methods}


def write_learning_plot(path: Path, rows: list[dict]) -> Path | None:
    """learning.png: per scenario goal (the first MAX_PANELS), per method, the cumulative
    training detections against episodes, the median over seeds as a line and the min-max as a
    band, a dot where the median seed met the criterion; None without learning rows."""
    ran = learning_rows(rows)
    if not ran:
        return None
    cases = list(dict.fromkeys((r['scenario'], r['goal']) for r in ran))
    shown = cases[:MAX_PANELS]
    columns = min(3, len(shown))
    lines = math.ceil(len(shown) / columns)
    figure = Figure(
        figsize=(max(5.5, 4.6 * columns), 3.4 * lines + 0.6), dpi=100, layout='constrained'
    )
    methods = list(dict.fromkeys(r['method'] for r in ran))
    colours = learner_colours(methods)
    for k, (scenario, goal) in enumerate(shown):
        ax = figure.add_subplot(lines, columns, k + 1)
        for row in (r for r in ran if (r['scenario'], r['goal']) == (scenario, goal)):
            median, low, high = band([seed['curve'] for seed in row['seeds']])
            episodes = np.arange(1, len(median) + 1)
            colour = colours[row['method']]
            ax.fill_between(episodes, low, high, color=colour, alpha=0.2, linewidth=0)
            ax.plot(episodes, median, color=colour, label=row['method'])
            reached = row['episodes_to_criterion']
            if reached is not None and reached <= len(median):
                ax.plot([reached], [median[int(reached) - 1]], 'o', color=colour, markersize=5)
        ax.set_xscale('log')
        ax.set_title(f'{scenario} ({goal})' if goal else scenario, fontsize=9)
        ax.set_xlabel('training episode', fontsize=8)
        ax.set_ylabel('detections so far', fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7)
    more = (
        f'\n{len(cases) - len(shown)} more scenario goals in learning.csv'
        if cases[MAX_PANELS:]
        else ''
    )
    figure.suptitle(
        'cumulative training detections: median over seeds, band min-max\n'
        f'dot: the median seed met the criterion {STREAK} times in a row{more}',
        fontsize=9,
    )
    figure.savefig(path)
    return path
