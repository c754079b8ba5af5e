"""The command-line options `experiments` (make compare) and `stealth benchmark` share: the
learners' training budget, the local Ray's CPUs, the output directory and the pictures
(argparse; each command checks the values it is given), and the CPUs a local Ray may have."""

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


def usable_cpus() -> int:
    """The CPUs this process may run on: its affinity (a container's or taskset's limit) where
    the OS tells it, else the machine's CPU count."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):  # no affinity on this OS
        return os.cpu_count() or 1


def capped_jobs(jobs: int) -> tuple[int, str]:
    """(--jobs at most the usable CPUs, the note saying so when it was more): a local Ray of
    more CPUs than the machine lets this process use only queues the trials on the same cores
    (and starts a worker process for each)."""
    cpus = usable_cpus()
    if jobs <= cpus:
        return jobs, ''
    return cpus, f'--jobs {jobs}: this process may use {cpus} CPU(s); running on {cpus}'


def add_output_options(
    parser: argparse.ArgumentParser, units: str, out: Path, pictures: str
) -> None:
    """--jobs (CPUs of the local Ray ``units`` go to), --out (default ``out``), --no-plots
    (skips ``pictures``)."""
    parser.add_argument(
        '--jobs',
        type=int,
        default=usable_cpus(),
        help=f'CPUs of the local Ray the {units} go to; 1: one after another in this process, '
        'no Ray (default: the CPUs this process may use, %(default)s)',
    )
    parser.add_argument(
        '--out', type=Path, default=out, help='output directory (default: %(default)s)'
    )
    parser.add_argument('--no-plots', action='store_true', help=f'skip {pictures}')
