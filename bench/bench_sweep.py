"""Benchmark: a sweep's throughput on a local Ray over every core (sweep_engine, what `stealth
sweep`, `make compare` and `stealth benchmark` run on) against the same trials one after
another in this process (sweep_trials.run_trial), in one run, on trials of a realistic length
(floorplan's hard goal, Q-learning at the harness's 1500 episodes: 9.1-11.5 s each alone on a
quiet 2-core machine; lgfloor's, 5.0-5.5 s, came too close to the 5 s that a sweep's trial is
worth timing at). The shortest and longest trial are printed beside the mean.

Start-up is given apart, in its two parts: Ray's own (``ray.init``: a local Ray's GCS, raylet
and their agents) and the workers' (sweep_pool: the actors started, their imports done and the
scenario's lattice model built, once per worker, reused for every trial); one after another
builds the same model once before its clock starts, and runs half of the trials before the
engine and half after (so that a drift in the host's load weighs on both). The speedup is of
the trials alone; a second figure counts the start-up too. Beside them, the mean time inside a
trial either way, and the share of the engine's time its workers spent inside trials (1: the
engine costs nothing of its own; on cores other work shares, two trials side by side can each
take longer than one alone, which is contention, not the engine).

Then ROS trials (mode ros: `stealth train` in its own ROS domain per trial, reserved
machine-wide by stealth_bringup.ros_domain): 4 short trials on the same engine, one at a time
(half before, half after) against as many at once as there are CPUs.

Run: source scripts/ros_env.sh && python bench/run_all.py --only sweep
     python bench/bench_sweep.py --no-ros        # the in-process trials only
"""

from __future__ import annotations

import os
import sys
import time

from stealth_core.gym_env import lattice_model
from stealth_experiments.sweep_engine import Engine
from stealth_experiments.sweep_plan import make_trial
from stealth_experiments.sweep_trials import run_trial

SCENARIO, GOAL = 'floorplan', 'hard'
LEARNER, EPISODES = 'qlearning', 1500  # the harness's budget: several s per trial
SEEDS = tuple(range(8))
ROS_SCENARIO, ROS_GOAL, ROS_LEARNER, ROS_EPISODES = 'simple-maze', 'easy', 'dyna', 10
ROS_SEEDS = (0, 1, 2, 3)


def trials() -> list[dict]:
    return [
        make_trial('gym', SCENARIO, GOAL, LEARNER, [seed], EPISODES, 10, 0.0, {}) for seed in SEEDS
    ]


def ros_trials() -> list[dict]:
    return [
        make_trial('ros', ROS_SCENARIO, ROS_GOAL, ROS_LEARNER, [seed], ROS_EPISODES, 5, 0.0, {})
        for seed in ROS_SEEDS
    ]


def _inside(records: list[dict]) -> float:
    return sum(r['wall_seconds'] for r in records) / len(records)


def _shortest_longest(records: list[dict]) -> tuple[float, float]:
    seconds = [r['wall_seconds'] for r in records]
    return round(min(seconds), 2), round(max(seconds), 2)


def _engine_run(engine: Engine, todo: list[dict], max_concurrent: int | None = None):
    """(records, workers' start-up s, trials s) of ``todo`` on a pool of their own."""
    kept: list[dict] = []
    with engine.pool(todo, max_concurrent=max_concurrent) as pool:
        ready_s = pool.ready()
        began = time.perf_counter()
        engine.run_fixed(todo, kept.extend, progress=False, pool=pool)
        trials_s = time.perf_counter() - began
    assert len(kept) == len(todo), 'a trial brought no record back'
    failed = [r['error'] for r in kept if r['status'] != 'ok']
    assert not failed, f'a trial failed on the engine: {failed[0]}'
    return kept, ready_s, trials_s


def _one_after_another(todo: list[dict]) -> tuple[list[dict], float]:
    started = time.perf_counter()
    records = [record for trial in todo for record in run_trial(trial)]
    assert all(r['status'] == 'ok' for r in records), 'a trial failed one after another'
    return records, time.perf_counter() - started


def run(report=print, ros: bool = True) -> dict:
    todo = trials()
    half = len(todo) // 2
    lattice_model(SCENARIO, GOAL)  # built once, outside the clock, as each worker does
    # Half of the trials one after another before the engine runs them all, half after: on a
    # host whose other work comes and goes, a drift in its load then weighs on both sides.
    before, before_s = _one_after_another(todo[:half])

    cpus = os.cpu_count() or 1
    started = time.perf_counter()
    with Engine(None, cpus, say=lambda line: None) as engine:
        ray_s = time.perf_counter() - started
        kept, workers_s, engine_s = _engine_run(engine, todo)
        ros_figures = _ros(engine, cpus, report) if ros else {}
    after, after_s = _one_after_another(todo[half:])
    sequential, sequential_s = before + after, before_s + after_s
    startup_s = ray_s + workers_s
    slots = min(cpus, len(todo))
    busy = sum(r['wall_seconds'] for r in kept) / (slots * engine_s)
    total_s = startup_s + engine_s

    def per_minute(seconds: float) -> float:
        return len(todo) * 60.0 / seconds

    figures = {
        'sweep_trials': len(todo),
        'sweep_cpus': cpus,
        'sweep_sequential_s': round(sequential_s, 2),
        'sweep_ray_startup_s': round(ray_s, 2),
        'sweep_workers_startup_s': round(workers_s, 2),
        'sweep_startup_s': round(startup_s, 2),
        'sweep_ray_trials_s': round(engine_s, 2),
        'sweep_sequential_trials_per_min': round(per_minute(sequential_s), 2),
        'sweep_ray_trials_per_min': round(per_minute(engine_s), 2),
        'sweep_ray_with_startup_trials_per_min': round(per_minute(total_s), 2),
        'sweep_sequential_mean_trial_s': round(_inside(sequential), 2),
        'sweep_ray_mean_trial_s': round(_inside(kept), 2),
        'sweep_sequential_shortest_longest_trial_s': _shortest_longest(sequential),
        'sweep_ray_shortest_longest_trial_s': _shortest_longest(kept),
        # The share of the engine's wall time its workers spent inside trials: 1 means no cost
        # of its own (what is left of a speedup short of the CPUs is contention for the cores).
        'sweep_ray_busy_fraction': round(busy, 3),
        'sweep_speedup': round(sequential_s / engine_s, 3),
        'sweep_speedup_with_startup': round(sequential_s / total_s, 3),
        **ros_figures,
    }
    report(
        f'{len(todo)} trials ({SCENARIO} {GOAL}, {LEARNER} {EPISODES} episodes, seeds '
        f'{SEEDS[0]}-{SEEDS[-1]}):'
    )
    report(
        f'  one after another: {sequential_s:.1f} s = '
        f'{figures["sweep_sequential_trials_per_min"]:.1f} trials/min'
    )
    report(
        f'  start-up: {startup_s:.1f} s = Ray {ray_s:.1f} s + {slots} '
        f'workers {workers_s:.1f} s (imports and the lattice model, once per worker)'
    )
    report(
        f'  local Ray, {cpus} CPUs: {engine_s:.1f} s = {figures["sweep_ray_trials_per_min"]:.1f} '
        f'trials/min (with start-up: {figures["sweep_ray_with_startup_trials_per_min"]:.1f} '
        'trials/min)'
    )
    alone = '{:.1f}-{:.1f} s'.format(*figures['sweep_sequential_shortest_longest_trial_s'])
    on_ray = '{:.1f}-{:.1f} s'.format(*figures['sweep_ray_shortest_longest_trial_s'])
    report(
        f'  mean time inside a trial: {figures["sweep_sequential_mean_trial_s"]:.1f} s alone, '
        f'{figures["sweep_ray_mean_trial_s"]:.1f} s on Ray ({cpus} side by side); shortest and '
        f'longest {alone} alone, {on_ray} on Ray'
    )
    report(
        f"  workers busy inside trials {busy:.1%} of the engine's {engine_s:.1f} s x {slots} "
        f"(the rest is the engine's own cost)"
    )
    report(
        f'  speedup {figures["sweep_speedup"]:.2f}x ({sequential_s:.1f} s / {engine_s:.1f} s); '
        f'with start-up {figures["sweep_speedup_with_startup"]:.2f}x '
        f'({sequential_s:.1f} s / {total_s:.1f} s)'
    )
    if ros_figures:
        report(
            f'{len(ROS_SEEDS)} ROS trials ({ROS_SCENARIO} {ROS_GOAL}, {ROS_LEARNER} '
            f'{ROS_EPISODES} episodes, `stealth train` each in its own ROS domain): one at a '
            f'time {ros_figures["sweep_ros_one_s"]:.1f} s, {cpus} at once '
            f'{ros_figures["sweep_ros_parallel_s"]:.1f} s, speedup '
            f'{ros_figures["sweep_ros_speedup"]:.2f}x (mean inside a trial '
            f'{ros_figures["sweep_ros_one_mean_trial_s"]:.1f} s alone, '
            f'{ros_figures["sweep_ros_parallel_mean_trial_s"]:.1f} s side by side)'
        )
    return figures


def _ros(engine: Engine, cpus: int, report) -> dict:
    """The ROS trials ``cpus`` at once on the same engine, and one at a time: half of them
    before, half after (as the in-process trials)."""
    todo = ros_trials()
    half = len(todo) // 2
    first, _, first_s = _engine_run(engine, todo[:half], max_concurrent=1)
    both, _, both_s = _engine_run(engine, todo)
    second, _, second_s = _engine_run(engine, todo[half:], max_concurrent=1)
    one, one_s = first + second, first_s + second_s
    return {
        'sweep_ros_trials': len(todo),
        'sweep_ros_one_s': round(one_s, 2),
        'sweep_ros_parallel_s': round(both_s, 2),
        'sweep_ros_one_mean_trial_s': round(_inside(one), 2),
        'sweep_ros_parallel_mean_trial_s': round(_inside(both), 2),
        'sweep_ros_speedup': round(one_s / both_s, 3),
    }


if __name__ == '__main__':
    run(ros='--no-ros' not in sys.argv[1:])
