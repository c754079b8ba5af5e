"""Benchmark: the scenario generator's scenarios/s at 30 x 30 m, 4 static lights, medium.

Generation alone (building, lights, files: ``scenario_generator._draw``) against generation
with its proof (``generate``: files loaded back, the lattice model built, A* and value
iteration, retries included), both in this process on one core. The goal is >= 20 proven
scenarios/s; the CPU seconds of the proven run are reported too, steadier than the wall clock
on a shared machine.
Run: PYTHONPATH=ros2_ws/src/stealth_core python bench/bench_generator.py
"""

from __future__ import annotations

import time

import numpy as np
from stealth_core import scenario_generator
from stealth_core.scenario_generator import Options, generate, scenario_name

SEEDS = range(20)
OPTIONS = Options(width=30, height=30, lights=4, moving='none', difficulty='medium')


def run(report=print) -> dict:
    started = time.perf_counter()
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        scenario_generator._draw(rng, seed, scenario_name(seed), OPTIONS)
    drawn = time.perf_counter() - started
    started, cpu = time.perf_counter(), time.process_time()
    tries = sum(generate(seed, OPTIONS).proof.tries for seed in SEEDS)
    proven, cpu = time.perf_counter() - started, time.process_time() - cpu
    count = len(SEEDS)
    report(f'{count} scenarios, 30 x 30 m, 4 static lights, medium:')
    report(f'  generation alone: {count / drawn:.1f} scenarios/s ({drawn:.2f} s)')
    report(
        f'  generation + proof: {count / proven:.1f} scenarios/s ({proven:.2f} s, {tries} tries)'
    )
    report(
        f'  generation + proof: {count / cpu:.1f} scenarios per CPU second ({cpu:.2f} s of CPU)'
    )
    ratio = proven / drawn
    report(f'  proof cost ratio (proven / generation alone): {ratio:.1f}x (goal: >= 20 proven/s)')
    return {
        'drawn_per_second': round(count / drawn, 2),
        'proven_per_second': round(count / proven, 2),
        'proven_per_cpu_second': round(count / cpu, 2),
        'tries': tries,
        'proof_cost_ratio': round(ratio, 2),
    }


if __name__ == '__main__':
    run()
