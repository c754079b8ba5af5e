"""Benchmark: episodes until Q-learning, Dyna-Q and prioritized sweeping converge, against value
iteration's optimum, on every static scenario, with the experiment harness's settings and
budgets.

"Converged" is the harness's: the first greedy evaluation from which every later one meets the
success criterion (stealth_core.path_scores: reached the goal undetected, path and exposure
against value iteration's path). Printed per scenario and learner:
the median over seeds of those episodes, its final greedy return over the optimum; then
prioritized sweeping's episodes relative to Q-learning's (target <= 0.1x) and Dyna-Q's
(target <= 0.5x). SARSA is left out: it is no faster than Q-learning and doubles the bench.

Run: source scripts/ros_env.sh && python bench/bench_learners.py [scenario ...] (or with
PYTHONPATH holding every ros2_ws/src/stealth_* package: the harness's command line needs
stealth_bringup and stealth_tools too); also part of `make bench`.
"""

from __future__ import annotations

import argparse
import math
import os

import numpy as np
from stealth_core.path_scores import DEFAULT_CRITERION
from stealth_experiments.experiments import run_grid

# Every shipped scenario whose lights stand still (the -moving ones have their own budgets).
SCENARIOS = (
    'simple-maze',
    'map1',
    'lgfloor',
    'floorplan',
    'simple-maze-exposure',
    'map1-exposure',
    'map1-bounce',
    'lgfloor-bounce',
)
LEARNERS = ('qlearning', 'dyna', 'prioritized')
SEEDS = (0, 1, 2)
TARGETS = {'qlearning': 0.1, 'dyna': 0.5}  # prioritized sweeping's episodes at most this x


def median_episodes(runs) -> float | None:
    """The median over seeds of the episodes to settle, a seed that never settled counting as
    more than any; None when the median itself is such a seed."""
    reached = [r.episodes_to_criterion for r in runs]
    median = float(np.median([math.inf if e is None else e for e in reached]))
    return None if math.isinf(median) else median


def run(report=print, scenarios=SCENARIOS) -> dict:
    results = run_grid(
        list(scenarios), LEARNERS, SEEDS, jobs=min(os.cpu_count() or 1, 2), progress=False
    )
    report(
        'episodes until every greedy evaluation meets the criterion '
        f'({DEFAULT_CRITERION.describe()}; {len(SEEDS)} seeds, median [min-max]; a greedy '
        f'evaluation every {results[0].spec.eval_every} episodes):'
    )
    figures: dict = {}
    met = []
    for scenario in scenarios:
        runs = [r for r in results if r.spec.scenario == scenario]
        optimum = runs[0].optimum
        medians = {}
        for learner in LEARNERS:
            mine = [r for r in runs if r.spec.learner == learner]
            reached = [
                r.episodes_to_criterion for r in mine if r.episodes_to_criterion is not None
            ]
            medians[learner] = median_episodes(mine)
            final = float(np.mean([r.eval_returns[-1] for r in mine]))
            when = (
                f'{medians[learner]:.0f} [{min(reached)}-{max(reached)}]'
                if medians[learner] is not None
                else f'{len(reached)}/{len(mine)} seeds settled in {mine[0].spec.episodes}'
            )
            if medians[learner] is not None and len(reached) < len(mine):
                when += f' ({len(mine) - len(reached)} seed(s) never settled)'
            report(
                f'  {scenario:20s} {learner:11s}: {when} episodes (budget '
                f'{mine[0].spec.episodes}); final greedy return / optimum '
                f'{final / optimum:.3f}; {np.mean([r.seconds for r in mine]):.1f} s per run'
            )
            key = f'learners_{scenario}_{learner}'
            figures[f'{key}_episodes_to_criterion'] = medians[learner]
            figures[f'{key}_return_per_optimum'] = round(final / optimum, 4)
        ratios = []
        for other, target in TARGETS.items():
            mine, theirs = medians['prioritized'], medians[other]
            budget = next(r.spec.episodes for r in runs if r.spec.learner == other)
            if mine is None:
                ratios.append(f'{other} - (prioritized sweeping did not settle on most seeds)')
                met.append(False)
                continue
            if theirs is None:  # its median seed never settled: at least its budget
                ratio, shown = mine / budget, f'< {mine / budget:.2f}x'
                note = f' ({other} did not settle on most seeds in {budget})'
            else:
                ratio, shown, note = mine / theirs, f'{mine / theirs:.2f}x', ''
            figures[f'learners_{scenario}_prioritized_relative_to_{other}'] = round(ratio, 3)
            ok = ratio <= target
            met.append(ok)
            ratios.append(
                f'{shown} {other}{note} (target <= {target}x: {"met" if ok else "missed"})'
            )
        report(f'  {scenario:20s} prioritized sweeping: ' + ', '.join(ratios))
    report(f'targets met: {sum(met)} of {len(met)}')
    figures['learners_targets_met'] = sum(met)
    figures['learners_targets'] = len(met)
    return figures


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog='bench_learners', description=__doc__.split('\n\n')[0])
    parser.add_argument(
        'scenarios',
        nargs='*',
        metavar='scenario',
        help=f'scenarios to bench (default: {" ".join(SCENARIOS)})',
    )
    args = parser.parse_args(argv)
    run(scenarios=tuple(args.scenarios) or SCENARIOS)


if __name__ == '__main__':
    main()
