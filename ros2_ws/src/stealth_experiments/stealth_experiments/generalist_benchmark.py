"""`stealth generalist`: the generalist's evaluation, every figure beside its baselines. It is
`stealth benchmark` (``benchmark.main``) with other defaults, so the methods, the generated
set, the checks, the report and Ctrl-C are the benchmark's own:

    stealth generalist --seeds 1500000 --count 50 --width 50 --height 40 --lights 8 --jobs 1

- methods ``METHODS``: value iteration (the oracle), the generalist, its hand-set twins (the
  environment's reward written into the same network; -1 a move and -1e4 a lit one) and its
  untrained twin, the cycle rule (the static network, hand-set, on the cycle's brightest
  light field: moving lights' naive baseline), and the replanners (``replan (unknown dark)``,
  ``replan (unknown lit)``);
  each on the tracks it runs on (``benchmark_methods.METHODS``: the replanners on the sensed
  track only);
- the set: generated test buildings only (``--set generated``), of the development part of the
  test range by default; the final test range (seeds 2,000,000 and up) only with
  ``--final-test-range``;
- written to ``runs/generalist-eval`` (results.csv, summary.md, benchmark.png), the summary's
  tables printed.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
import sys

from stealth_experiments.benchmark import Preset
from stealth_experiments.benchmark import main as benchmark_main

METHODS = (
    'value iteration',
    'generalist',
    'generalist (hand-set)',
    'generalist (dark steps)',
    'generalist (untrained)',
    'generalist (cycle rule)',
    'replan (unknown dark)',
    'replan (unknown lit)',
)
GENERALIST = Preset(
    'stealth generalist',
    'Evaluate the generalist (stealth_learn) on generated test buildings it never saw, every '
    "figure beside value iteration (the oracle), the same network with the environment's "
    'reward written in (hand-set; and -1 a move, -1e4 a lit one: dark steps), the same '
    "network untrained, the cycle rule (the static network, hand-set, on the cycle's brightest "
    'light, no wait), and the replanners (unknown dark, unknown lit), on the lights-known '
    '(full) and the lights-sensed track: undetected and success rates, regret against the '
    "oracle, mean return, path and exposure over the optimum's. It is stealth benchmark with "
    'these defaults (--set generated, these --methods, --out runs/generalist-eval); every '
    'benchmark option applies.',
    lambda: list(METHODS),
    'vi, generalist, generalist-hand-set, generalist-dark-steps, generalist-untrained, '
    'generalist-cycle-rule, replan-dark, replan-lit',
    'generated',
    Path('runs/generalist-eval'),
    prints_summary=True,
)


def main(argv: Sequence[str] | None = None) -> int:
    return benchmark_main(argv, GENERALIST)


if __name__ == '__main__':
    sys.exit(main())
