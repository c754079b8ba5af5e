"""Benchmark: how much experience Q-learning, Dyna-Q, prioritized sweeping and light-model need on
the shipped scenarios, with the experiment harness's settings and budgets and a greedy
evaluation after every training episode.

Per scenario and learner, over seeds 0-2 (median [min-max]): episodes to the criterion, the
training episodes until the first of 3 greedy evaluations in a row that meet the success
criterion (issue 41's measure: stealth_experiments.benchmark_learning; each run stops there),
the training episodes that ended DETECTED before it, the environment steps and the wall time
(its greedy evaluations included); a learner whose median seed never met it in its budget is
reported as such. Then
prioritized sweeping's episodes relative to Q-learning's (target <= 0.1x) and Dyna-Q's (target
<= 0.5x), and light-model's against prioritized sweeping's (issue 41's targets: on the static
scenarios episodes <= 5 and detections <= 0.25x, on the moving ones episodes <= 0.2x). SARSA is
left out: it is no faster than Q-learning and doubles the bench.

The default (and `make bench`'s) is the 8 static shipped scenarios; --moving runs the 4 moving
ones (their budgets are 5-10x larger: Q-learning needs thousands of episodes there, so give
--learners to leave it out), --all both, or name scenarios.

Run: source scripts/ros_env.sh && python bench/bench_learners.py [--moving | --all]
[--learners ...] [scenario ...]; also part of `make bench` (python bench/run_all.py --only
learners).
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np
from stealth_agent.learners import LEARNER_NAMES
from stealth_core.light_world import UnmodelledLawError, check_modelled
from stealth_core.path_scores import DEFAULT_CRITERION
from stealth_core.scenario import load_scenario
from stealth_experiments.benchmark_learning import median_of, seed_case
from stealth_experiments.harness import STREAK, default_budget

# Every shipped scenario whose lights stand still, and the four whose lights move.
STATIC = (
    'simple-maze',
    'map1',
    'lgfloor',
    'floorplan',
    'simple-maze-exposure',
    'map1-exposure',
    'map1-bounce',
    'lgfloor-bounce',
)
MOVING = ('simple-maze-moving', 'map1-moving', 'lgfloor-moving', 'floorplan-moving')
SCENARIOS = STATIC  # the default run (make bench)
MODEL = 'light-model'  # issue 41's learner, judged against its targets
LEARNERS = ('qlearning', 'dyna', 'prioritized') + ((MODEL,) if MODEL in LEARNER_NAMES else ())
SEEDS = (0, 1, 2)
TARGETS = {'qlearning': 0.1, 'dyna': 0.5}  # prioritized sweeping's episodes at most this x
# light-model against prioritized sweeping (issue 41): static scenarios, at most this many
# episodes and this fraction of its detections; moving ones, this fraction of its episodes.
MODEL_EPISODES = 5
MODEL_DETECTIONS = 0.25
MODEL_MOVING_EPISODES = 0.2
FIGURES = ('episodes_to_criterion', 'detections_to_criterion', 'steps_to_criterion',
           'seconds_to_criterion')  # fmt: skip


def moving(scenario: str) -> bool:
    return scenario in MOVING or scenario.endswith('-moving')


def refusal(scenario: str, learner: str) -> str | None:
    """Why a learner cannot learn a scenario at all (light-model: a law it does not model,
    ``light_world.check_modelled``), or None."""
    if learner != MODEL:
        return None
    try:
        check_modelled(load_scenario(scenario))
    except UnmodelledLawError as error:
        return str(error)
    return None


def measure(
    scenarios, learners, seeds=SEEDS, jobs: int | None = None, progress=None
) -> list[dict]:
    """Every scenario x learner x seed: benchmark_learning.seed_case's records, on the sweep
    engine's local Ray (or one after another with jobs 1); ``progress(line)``, if given, gets a
    line as each run ends."""
    trials = [
        {'id': f'{scenario}-{learner}-seed{seed}', 'scenario': scenario, 'learner': learner,
         'seed': seed, 'episodes': None}
        for scenario in scenarios for learner in learners for seed in seeds
        if refusal(scenario, learner) is None
    ]  # fmt: skip
    jobs = jobs or min(os.cpu_count() or 1, 2)
    found: dict[str, dict] = {}

    def keep(records: list[dict]) -> None:
        for record in records:
            found[record['trial']] = record
            if progress is not None:
                reached = record.get('episodes_to_criterion')
                progress(
                    f'bench_learners: {len(found)}/{len(trials)} {record["trial"]}: '
                    + ('not met' if reached is None else f'{reached} episodes')
                    + f' ({record.get("episodes", "-")} trained)'
                )

    if jobs <= 1:
        for trial in trials:
            keep(seed_case(trial))
        return [found[t['id']] for t in trials]
    from stealth_experiments.sweep_engine import Engine

    with Engine(None, jobs, say=lambda line: None) as engine:
        engine.run_fixed(trials, keep, progress=False, runner=seed_case, label='bench')
    failed = [found.get(t['id'], {'error': 'no result came back'}) for t in trials]
    failed = [r for r in failed if r.get('status') != 'ok']
    if failed:
        raise RuntimeError(f'a run failed: {failed[0].get("error")}')
    return [found[t['id']] for t in trials]


def spread(records: list[dict], key: str, digits: int = 0) -> str:
    """'median [min-max]' over the seeds that met the criterion, with how many did not."""
    values = [r[key] for r in records if r[key] is not None]
    median = median_of(r[key] for r in records)
    if median is None:
        return f'never ({len(values)}/{len(records)} seeds met it)'
    shown = f'{median:.{digits}f} [{min(values):.{digits}f}-{max(values):.{digits}f}]'
    missing = len(records) - len(values)
    return shown + (f' ({missing} seed(s) never met it)' if missing else '')


def ratio_line(mine, theirs, budget: int, target: float, what: str) -> tuple[str, bool, float]:
    """('<ratio>x <what> (target <= tx: met|missed)', met, ratio) for two medians (None: the
    median seed never met the criterion, at least its ``budget`` for the other learner)."""
    if mine is None:
        return f'- {what} (it never met the criterion on most seeds: missed)', False, math.nan
    if theirs is None:
        ratio, shown = mine / budget, f'< {mine / budget:.2f}x'
        note = f' (it never met the criterion on most seeds in {budget})'
    elif theirs == 0:
        ratio, shown, note = (0.0 if mine == 0 else math.inf), '-', f' ({what} is 0)'
    else:
        ratio, shown, note = mine / theirs, f'{mine / theirs:.2f}x', ''
    ok = ratio <= target
    return f'{shown} {what}{note} (target <= {target}x: {"met" if ok else "missed"})', ok, ratio


def run(
    report=print, scenarios=SCENARIOS, learners=LEARNERS, jobs: int | None = None, progress=None
) -> dict:
    records = measure(scenarios, learners, SEEDS, jobs, progress)
    report(
        f'episodes to the criterion: training episodes until the first of {STREAK} greedy '
        f'evaluations in a row that meet it ({DEFAULT_CRITERION.describe()}), a greedy evaluation '
        'after every episode; detections, steps and seconds (evaluations included) before it; '
        f'{len(SEEDS)} seeds, median [min-max]:'
    )
    if MODEL not in learners:
        report(f'  ({MODEL} is not among the learners benched: its targets are not judged)')
    figures: dict = {}
    met: list[bool] = []
    for scenario in scenarios:
        medians: dict[str, dict] = {}
        for learner in learners:
            reason = refusal(scenario, learner)
            if reason is not None:  # its targets count as missed
                report(f'  {scenario:20s} {learner:11s}: refused: {reason}')
                medians[learner] = dict.fromkeys(FIGURES)
                continue
            mine = [r for r in records if r['scenario'] == scenario and r['learner'] == learner]
            medians[learner] = {key: median_of(r[key] for r in mine) for key in FIGURES}
            final = float(np.median([r['return_per_optimum'] for r in mine]))
            if medians[learner][FIGURES[0]] is None:
                reached = sum(r[FIGURES[0]] is not None for r in mine)
                shown = (
                    f'never on most seeds ({reached}/{len(mine)} met the criterion in its budget '
                    f'{mine[0]["budget"]})'
                )
            else:
                shown = (
                    f'episodes {spread(mine, FIGURES[0])} (budget {mine[0]["budget"]}), '
                    f'detections {spread(mine, FIGURES[1])}, steps {spread(mine, FIGURES[2])}, '
                    f'{spread(mine, FIGURES[3], 2)} s'
                )
            report(
                f'  {scenario:20s} {learner:11s}: {shown}; last greedy return / optimum '
                f'{final:.3f}'
            )
            key = f'learners_{scenario}_{learner}'
            for name in FIGURES:
                figures[f'{key}_{name}'] = medians[learner][name]
        if 'prioritized' not in learners:
            continue
        ours = medians['prioritized']['episodes_to_criterion']
        ratios = []
        for other, target in TARGETS.items():
            if other not in learners:
                continue
            budget = default_budget(other, scenario)
            theirs = medians[other]['episodes_to_criterion']
            line, ok, ratio = ratio_line(ours, theirs, budget, target, other)
            figures[f'learners_{scenario}_prioritized_relative_to_{other}'] = _rounded(ratio)
            met.append(ok)
            ratios.append(line)
        if ratios:
            report(f'  {scenario:20s} prioritized sweeping: ' + ', '.join(ratios))
        if MODEL in learners:
            met += model_targets(scenario, medians, report, figures)
    report(f'targets met: {sum(met)} of {len(met)}')
    figures['learners_targets_met'] = sum(met)
    figures['learners_targets'] = len(met)
    return figures


def model_targets(scenario: str, medians: dict, report, figures: dict) -> list[bool]:
    """light-model against prioritized sweeping on one scenario (issue 41's targets)."""
    model, swept = medians[MODEL], medians['prioritized']
    budget = default_budget('prioritized', scenario)
    key = f'learners_{scenario}_{MODEL}_relative_to_prioritized'
    lines, met = [], []
    if moving(scenario):
        line, ok, ratio = ratio_line(
            model['episodes_to_criterion'], swept['episodes_to_criterion'], budget,
            MODEL_MOVING_EPISODES, "prioritized's episodes",
        )  # fmt: skip
        figures[f'{key}_episodes'] = _rounded(ratio)
        lines.append(line)
        met.append(ok)
    else:
        episodes = model['episodes_to_criterion']
        ok = episodes is not None and episodes <= MODEL_EPISODES
        shown = 'never on most seeds' if episodes is None else f'{episodes:.0f}'
        lines.append(f'episodes {shown} (target <= {MODEL_EPISODES}: {"met" if ok else "missed"})')
        met.append(ok)
        line, ok, ratio = ratio_line(
            model['detections_to_criterion'], swept['detections_to_criterion'], budget,
            MODEL_DETECTIONS, "prioritized's detections",
        )  # fmt: skip
        figures[f'{key}_detections'] = _rounded(ratio)
        lines.append(line)
        met.append(ok)
        ratio = (
            math.nan
            if model['episodes_to_criterion'] is None or not swept['episodes_to_criterion']
            else model['episodes_to_criterion'] / swept['episodes_to_criterion']
        )
        figures[f'{key}_episodes'] = _rounded(ratio)
    report(f'  {scenario:20s} {MODEL}: ' + ', '.join(lines))
    return met


def _rounded(ratio: float) -> float | None:
    return round(ratio, 3) if math.isfinite(ratio) else None


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog='bench_learners', description=__doc__.split('\n\n')[0])
    parser.add_argument(
        'scenarios', nargs='*', metavar='scenario',
        help=f'scenarios to bench (default: the static ones, {" ".join(STATIC)})',
    )  # fmt: skip
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        '--moving', action='store_true', help=f'the moving ones: {" ".join(MOVING)}'
    )
    which.add_argument('--all', action='store_true', help='the static and the moving ones')
    parser.add_argument(
        '--learners', nargs='+', choices=LEARNERS, default=list(LEARNERS),
        help='learners to bench (default: %(default)s)',
    )  # fmt: skip
    parser.add_argument(
        '--jobs', type=int, default=min(os.cpu_count() or 1, 2),
        help='CPUs of the local Ray the runs go to; 1: one after another (default: %(default)s)',
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.scenarios and (args.moving or args.all):
        parser.error('give scenarios or --moving/--all, not both')
    scenarios = tuple(args.scenarios) or (
        MOVING if args.moving else STATIC + MOVING if args.all else STATIC
    )
    learners = tuple(name for name in LEARNERS if name in args.learners)
    run(
        report=lambda line: print(line, flush=True),
        scenarios=scenarios,
        learners=learners,
        jobs=max(1, args.jobs),
        progress=lambda line: print(line, file=sys.stderr, flush=True),
    )


if __name__ == '__main__':
    main()
