"""Benchmark: episodes until Q-learning, SARSA and Dyna-Q converge, against value iteration's
optimum, on one scenario, with the experiment harness's settings and budgets.

"Converged" is the harness's criterion: the first greedy evaluation from which every later one
returns at least 95 % of the optimal (undiscounted) return. Printed per learner: the median over
seeds of those episodes, its final greedy return over the optimum, and its episodes relative to
Q-learning's.

Run: PYTHONPATH=ros2_ws/src/stealth_sim:ros2_ws/src/stealth_env:ros2_ws/src/stealth_agent:\
ros2_ws/src/stealth_experiments python bench/bench_learners.py
"""

from __future__ import annotations

import os

import numpy as np
from stealth_agent.learners import LEARNER_NAMES
from stealth_experiments.sweep_engine import run_grid

SCENARIO = 'map1'
SEEDS = (0, 1, 2)


def run(report=print) -> dict:
    results = run_grid(
        [SCENARIO], LEARNER_NAMES, SEEDS, jobs=min(os.cpu_count() or 1, 2), progress=False
    )
    optimum = results[0].optimum
    report(
        f'episodes until the greedy policy stays within 5 % of the optimum ({SCENARIO}, '
        f'optimal return {optimum:.1f}; {len(SEEDS)} seeds, median [min-max]):'
    )
    figures: dict = {'learners_scenario': SCENARIO, 'learners_optimal_return': round(optimum, 2)}
    medians = {}
    for learner in LEARNER_NAMES:
        runs = [r for r in results if r.spec.learner == learner]
        reached = [r.episodes_to_within for r in runs if r.episodes_to_within is not None]
        final = float(np.mean([r.eval_returns[-1] for r in runs]))
        budget = runs[0].spec.episodes
        medians[learner] = float(np.median(reached)) if len(reached) == len(runs) else None
        when = (
            f'{medians[learner]:.0f} [{min(reached)}-{max(reached)}] episodes'
            if medians[learner] is not None
            else f'{len(reached)}/{len(runs)} seeds within 5 % in {budget} episodes'
        )
        report(
            f'  {learner:9s}: {when} (budget {budget}); final greedy return {final:.1f} / '
            f'optimum {optimum:.1f} = {final / optimum:.3f}; '
            f'{np.mean([r.seconds for r in runs]):.1f} s per run'
        )
        figures[f'learners_{learner}_episodes_to_5pct'] = medians[learner]
        figures[f'learners_{learner}_return_per_optimum'] = round(final / optimum, 4)
    if medians['qlearning']:
        relative = {
            learner: medians[learner] / medians['qlearning']
            for learner in LEARNER_NAMES
            if medians[learner] is not None
        }
        report(
            '  episodes relative to Q-learning: '
            + ', '.join(f'{learner} {value:.2f}x' for learner, value in relative.items())
        )
        for learner, value in relative.items():
            figures[f'learners_{learner}_episodes_relative_to_qlearning'] = round(value, 3)
    return figures


def main() -> None:
    run()


if __name__ == '__main__':
    main()
