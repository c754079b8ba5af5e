"""make bench: every ``bench/bench_*.py`` in one process, each ratio with its raw numbers, and
``bench/results.json``.

A bench module offers ``run(report) -> dict``: it measures, calls ``report(line)`` for what a
reader should see (each ratio beside both numbers it divides) and returns the figures for the
JSON file. A module that cannot be imported (it needs something not installed, e.g. rclpy
outside the ROS environment) or that fails is reported as skipped with the reason; the others
still run, and the exit status is 0 unless ``--strict`` is given.

    python bench/run_all.py                     # all of them
    python bench/run_all.py --only gym learners # bench_gym.py and bench_learners.py
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import datetime
import importlib
import json
import os
from pathlib import Path
import platform
import sys
import time
import traceback

BENCH_DIR = Path(__file__).resolve().parent
REPOSITORY = BENCH_DIR.parent
# The pure-Python cores the benches use (stealth_experiments: the experiment harness, which
# writes its reports with stealth_bringup's run outputs; stealth_nav2: the covert planner's;
# stealth_learn: the JAX environment).
PACKAGES = (
    'stealth_core',
    'stealth_sim',
    'stealth_env',
    'stealth_agent',
    'stealth_bringup',
    'stealth_experiments',
    'stealth_node_kit',
    'stealth_nav2',
    'stealth_learn',
)
DEFAULT_OUT = BENCH_DIR / 'results.json'
RATIO_WORDS = ('ratio', 'speedup', 'per_optimum', 'relative')


def bench_modules(only: Sequence[str] = ()) -> list[str]:
    """Module names of bench/bench_*.py, sorted; only: names with or without 'bench_'."""
    names = sorted(path.stem for path in BENCH_DIR.glob('bench_*.py'))
    if only:
        wanted = {name if name.startswith('bench_') else f'bench_{name}' for name in only}
        unknown = wanted - set(names)
        if unknown:
            raise SystemExit(f'run_all: no such bench: {", ".join(sorted(unknown))}')
        names = [name for name in names if name in wanted]
    return names


def _make_importable() -> None:
    """bench/ and the workspace's source packages on sys.path, so the driver also runs without
    the ROS environment sourced (the ROS benches then report that they are skipped)."""
    for path in (BENCH_DIR, *(REPOSITORY / 'ros2_ws' / 'src' / p for p in PACKAGES)):
        if str(path) not in sys.path:
            sys.path.append(str(path))


def run_one(name: str, report) -> dict:
    """{'status': 'ok' | 'skipped', ...}: the bench's figures, or why there are none."""
    started = time.perf_counter()
    try:
        module = importlib.import_module(name)
    except ImportError as error:
        missing = getattr(error, 'name', None) or str(error)
        return {'status': 'skipped', 'reason': f'needs {missing}, which is not importable'}
    except Exception as error:  # a broken module must not stop the others
        return {'status': 'skipped', 'reason': f'import failed: {type(error).__name__}: {error}'}
    run = getattr(module, 'run', None)
    if not callable(run):
        return {'status': 'skipped', 'reason': 'the module has no run(report) function'}
    try:
        figures = run(report)
    except ImportError as error:
        missing = getattr(error, 'name', None) or str(error)
        return {'status': 'skipped', 'reason': f'needs {missing}, which is not importable'}
    except (Exception, SystemExit) as error:
        where = traceback.extract_tb(error.__traceback__)[-1]
        reason = f'{type(error).__name__}: {error} ({Path(where.filename).name}:{where.lineno})'
        return {'status': 'skipped', 'reason': f'failed: {reason}'}
    if not isinstance(figures, dict):
        return {'status': 'skipped', 'reason': f'run() returned {type(figures).__name__}'}
    return {'status': 'ok', 'seconds': round(time.perf_counter() - started, 2), **figures}


def ratio_lines(results: dict) -> list[str]:
    """One summary line per ratio-like figure of every bench that ran."""
    lines = []
    for name, figures in results.items():
        if figures['status'] != 'ok':
            lines.append(f'  {name}: skipped ({figures["reason"]})')
            continue
        for key, value in figures.items():
            if any(word in key for word in RATIO_WORDS) and isinstance(value, int | float):
                lines.append(f'  {name}: {key} = {value:g}')
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='run_all', description=__doc__.split('\n\n')[0])
    parser.add_argument('--only', nargs='+', default=(), help='run only these benches')
    parser.add_argument('--out', type=Path, default=DEFAULT_OUT, help='JSON file to write')
    parser.add_argument('--strict', action='store_true', help='exit 1 when a bench is skipped')
    args = parser.parse_args(argv)
    _make_importable()

    def report(line: str = '') -> None:
        print(line, flush=True)

    results = {}
    for name in bench_modules(args.only):
        report(f'== {name}')
        results[name] = run_one(name, report)
        if results[name]['status'] != 'ok':
            report(f'  skipped: {results[name]["reason"]}')
        report()
    report('== summary (each ratio is measured in this run; raw numbers above)')
    for line in ratio_lines(results):
        report(line)
    document = {
        'generated_at': datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds'),
        'python': platform.python_version(),
        'machine': platform.machine(),
        'cpus': os.cpu_count(),
        'benches': results,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(document, indent=2) + '\n', encoding='utf-8')
    report(f'written: {args.out}')
    skipped = any(figures['status'] != 'ok' for figures in results.values())
    return 1 if args.strict and skipped else 0


if __name__ == '__main__':
    sys.exit(main())
