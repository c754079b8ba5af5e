"""Benchmark: `stealth benchmark`'s throughput (scenarios per minute) on a local Ray over every
core (sweep_engine, the engine of the sweeps) against the same trials one after another in this
process (benchmark_methods.run_case, what `--jobs 1` runs), in one run.

The scenarios are the first COUNT generated test scenarios (generated into a temporary cache
first, not timed), every default method on both tracks, the learners trained EPISODES episodes
each (the real benchmark's budget is larger: this keeps the bench to a minute or two). The
engine's figure is given twice: the trials alone, and with Ray's start-up, which a benchmark
pays once.

Run: source scripts/ros_env.sh && python bench/run_all.py --only benchmark
"""

from __future__ import annotations

import os
from pathlib import Path
import tempfile
import time

from stealth_experiments.benchmark import DEFAULT_METHODS
from stealth_experiments.benchmark_methods import DEFAULT_TRACKS, run_case
from stealth_experiments.benchmark_plan import generated_cases, trials
from stealth_experiments.sweep_engine import Engine

COUNT = 6
EPISODES = 200


def run(report=print) -> dict:
    with tempfile.TemporaryDirectory(prefix='bench-benchmark-') as work:
        cases = generated_cases(COUNT, Path(work) / 'scenarios', report)
        todo = trials(cases, list(DEFAULT_METHODS), list(DEFAULT_TRACKS), episodes=EPISODES)

        started = time.perf_counter()
        sequential = [row for trial in todo for row in run_case(trial)]
        sequential_s = time.perf_counter() - started
        assert all(r['status'] == 'ok' for r in sequential), 'a row failed one after another'

        kept: list[dict] = []
        cpus = os.cpu_count() or 1
        started = time.perf_counter()
        with Engine(None, cpus, say=lambda line: None) as engine:
            startup_s = time.perf_counter() - started
            began = time.perf_counter()
            engine.run_fixed(todo, kept.extend, progress=False, runner=run_case)
            engine_s = time.perf_counter() - began
        total_s = time.perf_counter() - started
    assert len(kept) == len(sequential) and all(r['status'] == 'ok' for r in kept), 'a row failed'

    def per_minute(seconds: float) -> float:
        return len(cases) * 60.0 / seconds

    figures = {
        'benchmark_scenarios': len(cases),
        'benchmark_trials': len(todo),
        'benchmark_rows': len(sequential),
        'benchmark_cpus': cpus,
        'benchmark_sequential_s': round(sequential_s, 2),
        'benchmark_ray_startup_s': round(startup_s, 2),
        'benchmark_ray_trials_s': round(engine_s, 2),
        'benchmark_sequential_scenarios_per_min': round(per_minute(sequential_s), 2),
        'benchmark_ray_scenarios_per_min': round(per_minute(engine_s), 2),
        'benchmark_ray_with_startup_scenarios_per_min': round(per_minute(total_s), 2),
        'benchmark_speedup': round(sequential_s / engine_s, 3),
        'benchmark_speedup_with_startup': round(sequential_s / total_s, 3),
    }
    report(
        f'{len(cases)} generated test scenarios x {len(DEFAULT_METHODS)} methods x both tracks '
        f'({len(todo)} trials, {len(sequential)} rows; learners {EPISODES} episodes):'
    )
    report(
        f'  one after another: {sequential_s:.1f} s = '
        f'{figures["benchmark_sequential_scenarios_per_min"]:.1f} scenarios/min'
    )
    report(
        f'  local Ray, {cpus} CPUs: {engine_s:.1f} s = '
        f'{figures["benchmark_ray_scenarios_per_min"]:.1f} scenarios/min (+ {startup_s:.1f} s '
        f'start-up: {figures["benchmark_ray_with_startup_scenarios_per_min"]:.1f} scenarios/min)'
    )
    report(
        f'  speedup {figures["benchmark_speedup"]:.2f}x ({sequential_s:.1f} s / {engine_s:.1f} '
        f's); with start-up {figures["benchmark_speedup_with_startup"]:.2f}x '
        f'({sequential_s:.1f} s / {total_s:.1f} s)'
    )
    return figures


if __name__ == '__main__':
    run()
