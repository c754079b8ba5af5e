"""Benchmark: light-model against prioritized sweeping on generated buildings it never saw.

Generates ``--count`` proven buildings (``stealth_core.scenario_generator``, static lights, the
generator's defaults: 30 x 30 m, 4 lights, medium) from ``--first-seed`` on, trains each learner
once per building in-process (``stealth_experiments.harness.run``, a greedy evaluation after every
episode) and prints, per building and learner, the episodes to the criterion (the first of 3
greedy evaluations in a row that meet it, issue 41's measure) and the training detections before
it; then how many buildings light-model settled within 5 episodes (20 with ``--moving``), and
its detections against prioritized sweeping's. ``--moving mixed`` (or sweeping, patrolling)
generates moving lights instead: issue 41's 10 moving buildings, light-model trained 30 episodes
and prioritized sweeping 1500. Seeds of the generator's test range (1,000,000 on) are for a final
evaluation, run once; develop on the validation range (100,000-109,999).

Run: source scripts/ros_env.sh && python bench/bench_generated_learners.py --first-seed 100000
"""

from __future__ import annotations

import argparse
from pathlib import Path
import tempfile
import time

import numpy as np
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario_generator import Options, generate
from stealth_experiments.harness import RunSpec, run

LEARNERS = {'light-model': 8, 'prioritized': 300}  # learner: training episodes
MOVING_LEARNERS = {'light-model': 30, 'prioritized': 1500}  # where lights move
STREAK = 3
WITHIN = 5  # issue 41: light-model meets the criterion within 5 episodes (static lights)
MOVING_WITHIN = 20  # and within 20 where they move


def to_criterion(met) -> int | None:
    """Training episodes before the first of STREAK greedy evaluations in a row that meet it."""
    met = list(met)
    for start in range(len(met) - STREAK + 1):
        if all(met[start : start + STREAK]):
            return start + 1
    return None


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog='bench_generated_learners', description=__doc__)
    parser.add_argument('--first-seed', type=int, default=100_000, help='default: 100000')
    parser.add_argument('--count', type=int, default=5, help='buildings (default 5)')
    parser.add_argument('--seed', type=int, default=0, help="the learners' seed (default 0)")
    parser.add_argument(
        '--moving',
        choices=('none', 'sweeping', 'patrolling', 'mixed'),
        default='none',
        help="the buildings' lights' motion (the generator's --moving; default none)",
    )
    args = parser.parse_args(argv)
    learners = LEARNERS if args.moving == 'none' else MOVING_LEARNERS
    within = WITHIN if args.moving == 'none' else MOVING_WITHIN
    rows = []
    with tempfile.TemporaryDirectory(prefix='stealth-bench-generated-') as work:
        for seed in range(args.first_seed, args.first_seed + args.count):
            path = generate(seed, Options(moving=args.moving)).write(Path(work) / str(seed))
            row = {'building': seed}
            for learner, episodes in learners.items():
                started = time.perf_counter()
                result = run(RunSpec(str(path), learner, args.seed, episodes, eval_every=1))
                when = to_criterion(result.eval_met)
                upto = len(result.train_outcomes) if when is None else when
                detected = int(
                    np.sum(result.train_outcomes[:upto] == EpisodeOutcome.DETECTED.value)
                )
                row[learner] = (when, detected, time.perf_counter() - started)
                print(
                    f'  building {seed} {learner:11s}: criterion at '
                    f'{"never" if when is None else when} (of {episodes}), {detected} detections '
                    f'before it, {row[learner][2]:.0f} s',
                    flush=True,
                )
            rows.append(row)
    settled = [
        r for r in rows if r['light-model'][0] is not None and r['light-model'][0] <= within
    ]
    ratios = [
        r['light-model'][1] / r['prioritized'][1]
        for r in rows
        if r['prioritized'][1] > 0 and r['light-model'][0] is not None
    ]
    print(
        f'light-model met the criterion within {within} episodes on {len(settled)} of '
        f"{len(rows)} buildings; detections before it / prioritized sweeping's: median "
        f'{np.median(ratios) if ratios else float("nan"):.2f} over {len(ratios)} buildings'
    )


if __name__ == '__main__':
    main()
