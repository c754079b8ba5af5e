"""Benchmark: the generalist's plan on the shipped scenarios, backed up to its fixed point
(the decision rule since 2026-12-06) against the file's fixed count of backups (the rule
before), and the backups each took.

A plan is every cell's move from one grid (``GeneralistPolicy.cell_logits``, what the agent
node's plugin computes once per distinct grid: once a run with static lights known, once per
belief on the sensed track). Each scenario's grid is the one the environment sends (its lights
known; the phased grid where lights move, with ``generalist-moving.npz``). Times are medians of
REPEATS plans after a compile; the ratio is fixed point over fixed count, both in this process.
Run: ``source scripts/ros_env.sh && python bench/bench_generalist_plan.py`` (needs ``make
learn``).
"""

from __future__ import annotations

import statistics
import time

from stealth_core.scenario import load_scenario
from stealth_learn import generalist_data as data
from stealth_learn import policy_file
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import GeneralistPolicy
from stealth_learn.jax_deps import jax, jnp
from stealth_learn.vin import Vin, logits_of_cells

REPEATS = 5
STATIC = ('simple-maze', 'map1', 'lgfloor', 'floorplan')
MOVING = ('simple-maze-moving', 'map1-moving', 'lgfloor-moving', 'floorplan-moving')
MOVING_WEIGHTS = policy_file.SHIPPED.with_name('generalist-moving.npz')


def _median_seconds(work) -> float:
    work()  # the compile
    times = []
    for _ in range(REPEATS):
        started = time.perf_counter()
        work()
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def _fixed_count(policy: GeneralistPolicy):
    """The plan of the rule before: the file's ``iterations`` backups, no more."""
    model = Vin(**policy.header['architecture'])
    apply = jax.jit(lambda variables, grid: logits_of_cells(model, variables, grid))
    return lambda grid: jax.device_get(apply(policy.variables, jnp.asarray(grid)[None]))


def measure(name: str, policy: GeneralistPolicy) -> dict:
    arrays = TaskArrays(load_scenario(name))
    phased = policy.model.phased
    grid = data.phased_grid(arrays) if phased else data.grid_of(arrays.tables(), 0)
    fixed_point = _median_seconds(lambda: policy.cell_logits(grid))
    fixed_count = _fixed_count(policy)
    count = _median_seconds(lambda: fixed_count(grid))
    return {
        'grid': list(grid.shape[:-1]),
        'step_limit': int(arrays.model.task.step_limit),
        'backups': policy.backups,
        'file_iterations': int(policy.header['architecture']['iterations']),
        'fixed_point_ms': 1000 * fixed_point,
        'fixed_count_ms': 1000 * count,
        'ratio': fixed_point / count,
    }


def run(report=print) -> dict:
    results = {}
    for names, path in ((STATIC, policy_file.SHIPPED), (MOVING, MOVING_WEIGHTS)):
        policy = GeneralistPolicy.load(path, None)
        for name in names:
            row = measure(name, policy)
            results[name] = row
            report(
                f'{name}: plan to the fixed point {row["fixed_point_ms"]:.1f} ms '
                f'({row["backups"]} backups; step limit {row["step_limit"]}) / '
                f'{row["file_iterations"]} backups {row["fixed_count_ms"]:.1f} ms = ratio '
                f'{row["ratio"]:.2f}, grid {"x".join(map(str, row["grid"]))}'
            )
    return results


if __name__ == '__main__':
    run()
