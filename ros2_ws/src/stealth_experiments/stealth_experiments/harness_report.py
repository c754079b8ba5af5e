"""The experiment harness's report: results.csv and the table of results.md (one row per
method, learners averaged over their seeds), the learning curves with seed bands, and every
method's path. Written through run_outputs, the report writer `stealth train` runs use too.
No rclpy.
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from pathlib import Path

from matplotlib.figure import Figure
import numpy as np
from stealth_bringup.run_outputs import plot_paths, write_csv
from stealth_core import palette
from stealth_core.lattice_model import LatticeModel
from stealth_core.path_scores import (
    DEFAULT_CRITERION,
    Criterion,
    PathScores,
    describe,
    score_columns,
)
from stealth_core.reward import EpisodeOutcome

from stealth_experiments.harness import BASELINES, Baseline, RunResult, scenario_label

RESULTS_FIELDS = (
    'scenario',
    'goal',
    'method',
    'seed',
    'episodes',
    'optimal_return',
    'success_rate',
    'detection_rate',
    'timeout_rate',
    'train_mean_return',
    'greedy_outcome',
    'greedy_return',
    'greedy_over_optimum',
    'steps',
    'path_length_m',
    'peak_visibility',
    'accumulated_visibility',
    'optimal_path_length_m',
    'optimal_accumulated_visibility',
    'path_over_optimum',
    'exposure_over_optimum',
    'meets_criterion',
    'episodes_to_criterion',
    'max_path_ratio',
    'exposure_tolerance',
    'wall_seconds',
    'env_steps',
)


def _outcome_name(value) -> str:
    return '' if value is None else EpisodeOutcome(value).name


def scores_columns(summary: dict, reference: PathScores, criterion: Criterion) -> dict:
    """The score columns of a path's summary (RunResult.final's keys) against the optimum's:
    ratios, whether it meets the criterion, the criterion's options."""
    return {
        'optimal_path_length_m': reference.path_length,
        'optimal_accumulated_visibility': reference.accumulated_exposure,
        **score_columns(PathScores.of_summary(summary), reference, criterion),
        'max_path_ratio': criterion.max_path_ratio,
        'exposure_tolerance': criterion.exposure_tolerance,
    }


def run_row(result: RunResult, goal: str, reference: PathScores) -> dict:
    """One learner run's row; ``reference``: the optimum's scores (value iteration's path)."""
    final, spec = result.final, result.spec

    def rate(outcome: EpisodeOutcome) -> float:
        return float(np.mean(result.train_outcomes == outcome))

    return {
        'scenario': scenario_label(spec.scenario),
        'goal': goal,
        'method': spec.learner,
        'seed': spec.seed,
        'episodes': spec.episodes,
        'optimal_return': result.optimum,
        'success_rate': rate(EpisodeOutcome.SUCCESS),
        'detection_rate': rate(EpisodeOutcome.DETECTED),
        'timeout_rate': rate(EpisodeOutcome.TIMEOUT),
        'train_mean_return': float(result.train_returns.mean()),
        'greedy_outcome': _outcome_name(final['outcome']),
        'greedy_return': float(result.eval_returns[-1]),
        'greedy_over_optimum': float(result.eval_returns[-1]) / result.optimum,
        'steps': final['steps'],
        'path_length_m': final['path_length'],
        'peak_visibility': final['peak_visibility'],
        'accumulated_visibility': final['accumulated_visibility'],
        **scores_columns(final, reference, spec.criterion),
        'episodes_to_criterion': result.episodes_to_criterion,
        'wall_seconds': result.seconds,
        'env_steps': result.env_steps,
    }


def baseline_row(
    scenario: str,
    goal: str,
    optimum: float,
    baseline: Baseline,
    reference: PathScores | None = None,
    criterion: Criterion = DEFAULT_CRITERION,
) -> dict:
    """A planner's row; its scores against ``reference`` (the optimum's) when given."""
    summary = baseline.summary
    outcome = summary['outcome']
    found = outcome is not None
    scores = dict.fromkeys(
        (
            'optimal_path_length_m', 'optimal_accumulated_visibility', 'path_over_optimum',
            'exposure_over_optimum', 'meets_criterion', 'max_path_ratio', 'exposure_tolerance',
        ),
        '',
    )  # fmt: skip
    if found and reference is not None:
        scores = scores_columns(summary, reference, criterion)
    return {
        'scenario': scenario,
        'goal': goal,
        'method': baseline.name,
        'seed': '',
        'episodes': '',
        'optimal_return': optimum,
        'success_rate': float(outcome == EpisodeOutcome.SUCCESS),
        'detection_rate': float(outcome == EpisodeOutcome.DETECTED),
        'timeout_rate': float(outcome == EpisodeOutcome.TIMEOUT),
        'train_mean_return': '',
        'greedy_outcome': _outcome_name(outcome) if found else 'no path',
        'greedy_return': summary.get('total_reward', ''),
        'greedy_over_optimum': summary['total_reward'] / optimum if found else '',
        'steps': summary.get('steps', ''),
        'path_length_m': summary.get('path_length', ''),
        'peak_visibility': summary.get('peak_visibility', ''),
        'accumulated_visibility': summary.get('accumulated_visibility', ''),
        **scores,
        'episodes_to_criterion': '',
        'wall_seconds': baseline.seconds,
        'env_steps': '',
    }


def _mean(rows, key) -> float:
    return float(np.mean([row[key] for row in rows]))


def _episodes_text(rows) -> str:
    reached = sorted(
        row['episodes_to_criterion'] for row in rows if row['episodes_to_criterion'] is not None
    )
    budget = rows[0]['episodes']
    if not reached:
        return f'**not met in {budget}**'
    median = int(np.median(reached))
    if len(reached) == len(rows):
        return f'{median} ({reached[0]}-{reached[-1]})'
    listed = ', '.join(map(str, reached))
    return f'**{len(reached)}/{len(rows)} seeds** ({listed}); the rest not in {budget}'


def _met(value) -> str:
    return 'yes' if value is True else 'no' if value is False else ''


def markdown_table(rows: Sequence[dict]) -> str:
    """One table for all scenarios: baselines first, then learners averaged over seeds."""
    header = (
        '| scenario | method | success | detected | timeout | train return | greedy return '
        '| path (m) | path / opt. | steps | acc. visibility | exposure vs opt. | meets '
        '| episodes to criterion | wall (s) |\n'
        '| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- '
        '| --- |\n'
    )
    lines = []
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row['scenario'], row['method']), []).append(row)
    for (scenario, method), group in groups.items():
        first = group[0]
        if method in BASELINES:
            found = first['greedy_outcome'] != 'no path'
            lines.append(
                f'| {scenario} | {method} | {first["greedy_outcome"].lower()} | | | '
                f'| {first["greedy_return"]:.1f} | {first["path_length_m"]:.1f} '
                f'| {_number(first["path_over_optimum"], ".2f")} | {first["steps"]} '
                f'| {first["accumulated_visibility"]:.3f} '
                f'| {_number(first["exposure_over_optimum"], "+.3f")} '
                f'| {_met(first["meets_criterion"])} | | {first["wall_seconds"]:.3f} |'
                if found
                else f'| {scenario} | {method} | no path | | | | | | | | | | | | |'
            )
            continue
        greedy = [row['greedy_return'] for row in group]
        outcomes = sorted({row['greedy_outcome'].lower() for row in group})
        met = sum(row['meets_criterion'] is True for row in group)
        lines.append(
            f'| {scenario} | {method} ({len(group)} seeds) | {_mean(group, "success_rate"):.2f} '
            f'| {_mean(group, "detection_rate"):.2f} | {_mean(group, "timeout_rate"):.2f} '
            f'| {_mean(group, "train_mean_return"):.1f} '
            f'| {np.mean(greedy):.1f} ± {np.std(greedy):.1f} ({"/".join(outcomes)}) '
            f'| {_mean(group, "path_length_m"):.1f} | {_mean(group, "path_over_optimum"):.2f} '
            f'| {_mean(group, "steps"):.0f} | {_mean(group, "accumulated_visibility"):.3f} '
            f'| {_mean(group, "exposure_over_optimum"):+.3f} | {met}/{len(group)} '
            f'| {_episodes_text(group)} | {_mean(group, "wall_seconds"):.1f} |'
        )
    return header + '\n'.join(lines) + '\n'


def _number(value, spec: str) -> str:
    return '' if value == '' else format(value, spec)


# --- pictures -----------------------------------------------------------------------------------


def columns_text(criterion: Criterion = DEFAULT_CRITERION) -> str:
    """What results.md's columns mean, the criterion's options stated."""
    return (
        'Returns are undiscounted sums of the rewards after the first state. success / '
        'detected / timeout: outcome rates over all training episodes (planners: their one '
        'path). train return: mean over training episodes. greedy return: the final greedy '
        'policy, mean ± sd over seeds, and its outcomes. path, steps, acc. visibility: of the '
        'final greedy episode (visibility summed over the poses after each step: the '
        "accumulated exposure). path / opt.: its path length over value iteration's path's; "
        "exposure vs opt.: its accumulated exposure minus the optimum's. meets: final greedy "
        f'episodes that meet the criterion ({criterion.describe()}). episodes to criterion: '
        'from when on every greedy evaluation met the criterion, median (min-max) over seeds. '
        'wall: seconds per run.'
    )


COLUMNS = columns_text()
PATH_SHIFT = 0.08  # of a step, between the lines of two methods


def plot_curves(ax, results: Sequence[RunResult], optimum: float, title: str) -> None:
    """Greedy return (mean over seeds, min-max band) and training return (faint) per learner."""
    by_learner: dict[str, list[RunResult]] = {}
    for result in results:
        by_learner.setdefault(result.spec.learner, []).append(result)
    for learner, runs in by_learner.items():
        colour = palette.LEARNERS.get(learner)
        x = runs[0].eval_at
        greedy = np.array([r.eval_returns for r in runs])
        ax.plot(x, greedy.mean(axis=0), color=colour, linewidth=1.6, label=f'{learner} (greedy)')
        ax.fill_between(x, greedy.min(axis=0), greedy.max(axis=0), color=colour, alpha=0.2)
        window = max(len(runs[0].train_returns) // 40, 1)
        kernel = np.ones(window) / window
        train = np.array([np.convolve(r.train_returns, kernel, mode='valid') for r in runs])
        episodes = np.arange(window, window + train.shape[1])
        ax.plot(
            episodes,
            train.mean(axis=0),
            color=colour,
            linewidth=0.8,
            alpha=0.45,
            linestyle=':',
            label=f'{learner} (training, mean of {window})',
        )
    ax.axhline(optimum, color=palette.PLOT_INK, linewidth=1.0, label=f'optimum {optimum:.1f}')
    for learner, runs in by_learner.items():
        reached = [r.episodes_to_criterion for r in runs if r.episodes_to_criterion is not None]
        if reached:  # where the greedy policy meets the criterion for good (median over seeds)
            ax.axvline(
                float(np.median(reached)),
                color=palette.LEARNERS.get(learner),
                linewidth=0.9,
                linestyle='--',
                label=f'{learner}: criterion met from (median, {len(reached)}/{len(runs)} seeds)',
            )
    ax.set_title(title)
    ax.set_xlabel('training episodes')
    ax.set_ylabel('return (undiscounted)')
    ax.grid(alpha=0.3)


def write_curves(out: Path, results: Sequence[RunResult], optima: dict[str, float]) -> list[Path]:
    scenarios = list(dict.fromkeys(r.spec.scenario for r in results))
    written = []
    columns = min(2, len(scenarios))
    rows = math.ceil(len(scenarios) / columns)
    combined = Figure(figsize=(7 * columns, 4.5 * rows), dpi=100)
    for k, scenario in enumerate(scenarios):
        mine = [r for r in results if r.spec.scenario == scenario]
        single = Figure(figsize=(8, 5), dpi=100)
        for ax in (single.add_subplot(), combined.add_subplot(rows, columns, k + 1)):
            plot_curves(ax, mine, optima[scenario], scenario_label(scenario))
        single.axes[0].legend(fontsize=7, loc='lower right')
        single.tight_layout()
        written.append(out / f'curves_{scenario_label(scenario)}.png')
        single.savefig(written[-1])
    combined.axes[0].legend(fontsize=7, loc='lower right')
    combined.tight_layout()
    written.append(out / 'learning_curves.png')
    combined.savefig(written[-1])
    return written


def _labelled_paths(found: list[Baseline], results, baselines=BASELINES):
    """(points, label) of the baselines named and each learner's first seed, each labelled
    with its scores against the optimum's (value iteration's path)."""
    reference = optimum_reference(found)
    labelled = []
    for baseline in found:
        if baseline.name in baselines and baseline.summary.get('points') is not None:
            scores = PathScores.of_summary(baseline.summary)
            optimum = None if baseline.name == 'value iteration' else reference
            label = f'{baseline.name}: {describe(scores, optimum)}'
            labelled.append((baseline.summary['points'], label))
    seen = set()
    for result in results:
        if result.spec.learner in seen:
            continue
        seen.add(result.spec.learner)
        scores = PathScores.of_summary(result.final)
        label = f'{result.spec.learner} seed {result.spec.seed}: {describe(scores, reference)}'
        labelled.append((result.final['points'], label))
    return labelled


def write_animation(out: Path, model: LatticeModel, found: list[Baseline], results) -> Path:
    """paths_<scenario>.gif: the lights moving, the optimum and each learner's first seed's
    greedy path walked step by step (scenarios with moving lights)."""
    from stealth_core.render import animate_scenario

    labelled = _labelled_paths(found, results, baselines=('value iteration',))
    task = model.task
    lengths = [len(points) for points, _ in labelled]
    # A greedy path that loops until the step limit adds nothing after twice the optimum's.
    frames = min(max(lengths), 2 * lengths[0]) if lengths else None
    return animate_scenario(
        task.scenario,
        out / f'paths_{task.scenario.name}.gif',
        [points for points, _ in labelled],
        [label for _, label in labelled],
        goal=task.goal.name,
        frames=frames,
    )


def write_paths(out: Path, model: LatticeModel, found: list[Baseline], results) -> Path:
    """The scenario picture with every method's path (learners: their first seed's)."""
    labelled = _labelled_paths(found, results)
    task = model.task
    return plot_paths(
        task.scenario,
        task.goal.name,
        out / f'paths_{task.scenario.name}.png',
        labelled,
        f'{task.title}: paths (drawn slightly apart where they coincide)',
        spread=PATH_SHIFT * task.scenario.step_distance,
    )


def optimum_reference(found: list[Baseline]) -> PathScores:
    """The optimum's scores: value iteration's path among the baselines."""
    summary = next(b.summary for b in found if b.name == 'value iteration')
    return PathScores.of_summary(summary)


# --- the whole report ---------------------------------------------------------------------------


def write_results(
    out: Path,
    models: dict[str, LatticeModel],
    planned: dict[str, tuple[float, list[Baseline]]],
    results: Sequence[RunResult],
    settings: str,
    plots: bool = True,
    criterion: Criterion = DEFAULT_CRITERION,
) -> list[dict]:
    """results.csv, results.md and (with `plots`) the pictures it shows, for the baselines
    `planned` and the learners' `results` on each scenario's model; returns the CSV rows.
    The planners' rows are judged by ``criterion`` (the learners' by their runs' own)."""
    rows = []
    for scenario, model in models.items():
        optimum, found = planned[scenario]
        goal_name = model.task.goal.name
        label = scenario_label(scenario)
        reference = optimum_reference(found)
        rows += [
            baseline_row(label, goal_name, optimum, baseline, reference, criterion)
            for baseline in found
        ]
        rows += [run_row(r, goal_name, reference) for r in results if r.spec.scenario == scenario]
    write_csv(rows, RESULTS_FIELDS, out / 'results.csv')
    text = (
        f'# stealth-nav evaluation\n\n{settings}\n\n{columns_text(criterion)}\n\n'
        f'{markdown_table(rows)}'
    )
    if plots:
        optima = {scenario: planned[scenario][0] for scenario in models}
        images = write_curves(out, results, optima)
        for scenario, model in models.items():
            mine = [r for r in results if r.spec.scenario == scenario]
            images.append(write_paths(out, model, planned[scenario][1], mine))
            if model.task.scenario.has_moving_lights:
                images.append(write_animation(out, model, planned[scenario][1], mine))
        text += '\n' + '\n'.join(f'![{p.stem}]({p.name})' for p in images) + '\n'
    (out / 'results.md').write_text(text, encoding='utf-8')
    return rows
