"""The command-line options `experiments` (make compare) and `stealth benchmark` share: the
learners' training budget, the local Ray's CPUs, the output directory and the pictures
(argparse only; each command checks the values it is given)."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from stealth_experiments.harness import DEFAULT_EPISODES, MOVING_EPISODES


def _budgets(table: dict[str, int]) -> str:
    return ', '.join(f'{name} {budget}' for name, budget in table.items())


def add_episodes_option(parser: argparse.ArgumentParser, lead: str) -> None:
    """--episodes: the learners' training budget; its help is ``lead`` and the harness's
    defaults (``harness.default_budget``), lead opening the parenthesis they close."""
    parser.add_argument(
        '--episodes',
        type=int,
        help=f'{lead}{_budgets(DEFAULT_EPISODES)}; where lights move: '
        f'{_budgets(MOVING_EPISODES)})',
    )


def add_output_options(
    parser: argparse.ArgumentParser, units: str, out: Path, pictures: str
) -> None:
    """--jobs (CPUs of the local Ray ``units`` go to), --out (default ``out``), --no-plots
    (skips ``pictures``)."""
    parser.add_argument(
        '--jobs',
        type=int,
        default=os.cpu_count() or 1,
        help=f'CPUs of the local Ray the {units} go to; 1: one after another in this process, '
        'no Ray (default: the CPU count, %(default)s)',
    )
    parser.add_argument(
        '--out', type=Path, default=out, help='output directory (default: %(default)s)'
    )
    parser.add_argument('--no-plots', action='store_true', help=f'skip {pictures}')
