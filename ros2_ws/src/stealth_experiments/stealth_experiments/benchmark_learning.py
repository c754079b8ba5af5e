"""The learning track: how much experience a learner needs before its greedy policy meets the
success criterion, and what it pays on the way. Used by `stealth benchmark --tracks learning`
and bench/bench_learners.py. No Ray, no rclpy.

Each learner is trained in-process (``harness.run``) with a greedy evaluation after every
episode, on LEARNING_SEEDS seeds (``seed``, ``seed + 1``, ...). Per seed
(``harness.LearningCost``): **episodes to the criterion**, the training episodes until the first
of ``harness.STREAK`` (3) greedy evaluations in a row that meet it (issue 41's measure, not
``harness.settled``'s); the **detections** before it (training episodes that ended DETECTED, up
to and including that one), the environment **steps** and the **wall time** (the greedy
evaluations up to it included). A row gives each as the median over its seeds (``median_of``:
a seed that never met the criterion in its budget counts as more than any, so the median is
none when most seeds never met it) and how many seeds met it. The regret curve, the field's
(Qi, Bindel and Vladimirsky report observed captures per episode): the cumulative count of
training episodes that ended DETECTED against episodes, kept per seed (``curves``).
"""

from __future__ import annotations

import math

import numpy as np

from stealth_experiments.harness import RunResult, RunSpec, default_budget, run

LEARNING_SEEDS = 3
# The learning track's figures in a row (results.csv columns; benchmark_methods.COLUMNS).
LEARNING_COLUMNS = (
    'seeds_met', 'episodes_to_criterion', 'detections_to_criterion', 'steps_to_criterion',
    'seconds_to_criterion', 'training_detections',
)  # fmt: skip


def learning_spec(
    scenario: str,
    learner: str,
    seed: int,
    *,
    goal: str | None = None,
    episodes: int | None = None,
    stop_at_streak: bool = False,
) -> RunSpec:
    """A run of the learning track: the harness's budget (or ``episodes``), a greedy evaluation
    after every episode; ``stop_at_streak``: stop once the measure is known."""
    budget = episodes or default_budget(learner, scenario)
    return RunSpec(scenario, learner, seed, budget, 1, goal=goal, stop_at_streak=stop_at_streak)


def seed_figures(result: RunResult) -> dict:
    """One run's learning figures (JSON-able): the seed, its LearningCost, the episodes it
    trained and its budget, the detections over all of them, the final greedy return over the
    optimum, and its regret curve (cumulative detections per episode)."""
    cost = result.cost
    curve = result.detections
    return {
        'seed': result.spec.seed,
        'episodes_to_criterion': cost.episodes,
        'detections_to_criterion': cost.detections,
        'steps_to_criterion': cost.steps,
        'seconds_to_criterion': cost.seconds,
        'episodes': len(result.train_outcomes),
        'budget': result.spec.episodes,
        'training_detections': int(curve[-1]) if curve.size else 0,
        'return_per_optimum': float(result.eval_returns[-1]) / result.optimum,
        'curve': [int(v) for v in curve],
    }


def median_of(values) -> float | None:
    """The median over seeds, a seed without a value (it never met the criterion) counting as
    more than any; None when the median is such a seed (or there are no seeds)."""
    values = list(values)
    if not values:
        return None
    median = float(np.median([math.inf if v is None else v for v in values]))
    return None if math.isinf(median) else median


def summarise_seeds(seeds: list[dict]) -> dict:
    """A row's learning figures (LEARNING_COLUMNS) from its seeds' ``seed_figures``."""
    met = sum(s['episodes_to_criterion'] is not None for s in seeds)
    row = {'seeds_met': f'{met}/{len(seeds)}'}
    for key in LEARNING_COLUMNS[1:-1]:
        row[key] = median_of(s[key] for s in seeds)
    row['training_detections'] = float(np.median([s['training_detections'] for s in seeds]))
    return row


def learning_row(trial: dict) -> dict:
    """The learning track's row of a benchmark trial (a learner on a scenario goal): each seed
    trained for the budget (the regret curve runs over all of it), the row's figures
    (LEARNING_COLUMNS), its budget, and ``seeds``: every seed's ``seed_figures`` (the curves
    learning.csv and learning.png are drawn from)."""
    seeds = [
        seed_figures(
            run(
                learning_spec(
                    trial['scenario'],
                    trial['method'],
                    trial['seed'] + k,
                    goal=trial['goal'],
                    episodes=trial['episodes'],
                )  # fmt: skip
            )
        )
        for k in range(trial.get('learning_seeds') or LEARNING_SEEDS)
    ]
    return {**summarise_seeds(seeds), 'budget': seeds[0]['budget'], 'seeds': seeds}


def seed_case(trial: dict) -> list[dict]:
    """A run of bench_learners on the sweep engine (``Engine.run_fixed``'s runner): ``trial``
    holds id, scenario, learner, seed, episodes (None: the harness's budget); one record, its
    seed_figures, the run stopped once the measure is known (its curve ends there)."""
    spec = learning_spec(
        trial['scenario'], trial['learner'], trial['seed'], episodes=trial.get('episodes'),
        stop_at_streak=True,
    )  # fmt: skip
    figures = seed_figures(run(spec))
    return [{'trial': trial['id'], 'status': 'ok', **trial, **figures}]
