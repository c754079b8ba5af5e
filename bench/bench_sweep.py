"""Benchmark: a sweep's throughput (trials per minute) on a local Ray over every core
(sweep_engine, what `stealth sweep` and `make compare` run on) against the same trials run one
after another in this process (sweep_trials.run_trial), in one run.

The engine's figure is given twice: the trials alone (from the first trial submitted to the last
result) and with Ray's start-up, which a sweep pays once. Beside them, the mean time inside a
trial either way: on a machine whose cores other work shares, two trials side by side each take
longer than one alone, which is what separates contention from the engine's own overhead.

Run: source scripts/ros_env.sh && python bench/run_all.py --only sweep
"""

from __future__ import annotations

import os
from pathlib import Path
import tempfile
import time

from stealth_experiments.sweep_engine import Engine
from stealth_experiments.sweep_plan import make_trial
from stealth_experiments.sweep_trials import run_trial

SCENARIO = 'simple-maze'
LEARNERS = {'qlearning': 400, 'dyna': 150}  # episodes: tens of s per trial, as make compare's
SEEDS = (0, 1, 2, 3)


def trials() -> list[dict]:
    return [
        make_trial('gym', SCENARIO, 'easy', learner, [seed], episodes, 10, 0.0, {})
        for learner, episodes in LEARNERS.items()
        for seed in SEEDS
    ]


def run(report=print) -> dict:
    todo = trials()
    started = time.perf_counter()
    sequential = [record for trial in todo for record in run_trial(trial)]
    sequential_s = time.perf_counter() - started
    assert all(r['status'] == 'ok' for r in sequential), 'a trial failed one after another'

    kept: list[dict] = []
    cpus = os.cpu_count() or 1
    started = time.perf_counter()
    with (
        tempfile.TemporaryDirectory(prefix='bench-sweep-') as storage,
        Engine(None, cpus, say=lambda line: None) as engine,
    ):
        startup_s = time.perf_counter() - started
        began = time.perf_counter()
        engine.run_fixed(todo, kept.extend, Path(storage), progress=False)
        engine_s = time.perf_counter() - began
    total_s = time.perf_counter() - started
    assert len(kept) == len(todo) and all(r['status'] == 'ok' for r in kept), 'a trial failed'

    def per_minute(seconds: float) -> float:
        return len(todo) * 60.0 / seconds

    def inside(records: list[dict]) -> float:
        return sum(r['wall_seconds'] for r in records) / len(records)

    figures = {
        'sweep_trials': len(todo),
        'sweep_cpus': cpus,
        'sweep_sequential_s': round(sequential_s, 2),
        'sweep_ray_startup_s': round(startup_s, 2),
        'sweep_ray_trials_s': round(engine_s, 2),
        'sweep_sequential_trials_per_min': round(per_minute(sequential_s), 2),
        'sweep_ray_trials_per_min': round(per_minute(engine_s), 2),
        'sweep_ray_with_startup_trials_per_min': round(per_minute(total_s), 2),
        'sweep_sequential_mean_trial_s': round(inside(sequential), 2),
        'sweep_ray_mean_trial_s': round(inside(kept), 2),
        'sweep_speedup': round(sequential_s / engine_s, 3),
        'sweep_speedup_with_startup': round(sequential_s / total_s, 3),
    }
    report(
        f'{len(todo)} trials ({SCENARIO}, {", ".join(f"{k} {v} episodes" for k, v in LEARNERS.items())}, '  # noqa: E501
        f'seeds {len(SEEDS)}):'
    )
    report(
        f'  one after another: {sequential_s:.1f} s = '
        f'{figures["sweep_sequential_trials_per_min"]:.1f} trials/min'
    )
    report(
        f'  local Ray, {cpus} CPUs: {engine_s:.1f} s = {figures["sweep_ray_trials_per_min"]:.1f} '
        f'trials/min (+ {startup_s:.1f} s start-up: '
        f'{figures["sweep_ray_with_startup_trials_per_min"]:.1f} trials/min)'
    )
    report(
        f'  mean time inside a trial: {figures["sweep_sequential_mean_trial_s"]:.1f} s alone, '
        f'{figures["sweep_ray_mean_trial_s"]:.1f} s on Ray ({cpus} side by side)'
    )
    report(
        f'  speedup {figures["sweep_speedup"]:.2f}x ({sequential_s:.1f} s / {engine_s:.1f} s); '
        f'with start-up {figures["sweep_speedup_with_startup"]:.2f}x '
        f'({sequential_s:.1f} s / {total_s:.1f} s)'
    )
    return figures


if __name__ == '__main__':
    run()
