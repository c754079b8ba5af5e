"""Benchmark: the lights-known generalist's decision time through ROS (issue 30's target: at
most 2 ms per step).

`stealth rollout --learner generalist` on simple-maze's easy goal: simulator, environment
(observation_layout grid: the grid is sent once, latched) and the agent node with ``agent:
generalist`` (the stealth_learn plugin), EPISODES greedy episodes, no recorder. The agent node
times every answered state from its callback to its action published and logs the summary at
exit (``progress.totals_line``); this bench reads it from the run's agent log, with the plan's
time (the value map of the one grid, computed once when the grid arrives) and the episodes'
outcomes from summary.json. The decision includes the state's conversion, the robot's cell and
the lookup in the cached plan; the plan itself is not per step (static lights). The target is
judged on the mean per step; the tail (p95, max) is wall time on a shared machine, and the
thread's CPU time beside it shows how much of it was waiting for a core.
Run: ``source scripts/ros_env.sh && python bench/bench_generalist_ros.py`` (needs ``make
setup`` and ``make learn``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import re
import shutil
import subprocess
import tempfile

import stealth_learn.jax_deps  # noqa: F401 - the learning extra (make learn), or skipped

EPISODES = 10
TIMEOUT = 600.0  # s for the run
TARGET_MS = 2.0
ROLLOUT = ('rollout', '--learner', 'generalist', '--scenario', 'simple-maze', '--goal', 'easy',
           '--episodes', str(EPISODES), '--no-record')  # fmt: skip
DECISION = re.compile(
    r'decision time per action: mean (?P<mean>[\d.]+) ms, median (?P<median>[\d.]+) ms, '
    r'p95 (?P<p95>[\d.]+) ms, max (?P<max>[\d.]+) ms \(CPU mean (?P<cpu_mean>[\d.]+) ms, '
    r'p95 (?P<cpu_p95>[\d.]+) ms\)'
)
PLAN = re.compile(r'planned on in (?P<s>[\d.]+) s')
ACTIONS = re.compile(r'totals: (?P<states>\d+) states received, (?P<actions>\d+) actions sent')


def rollout(runs: Path) -> tuple[dict, str]:
    """(summary.json, the agent's log) of one rollout."""
    stealth = shutil.which('stealth')
    if stealth is None:
        raise RuntimeError('stealth is not on PATH: source scripts/ros_env.sh (after make setup)')
    command = [stealth, *ROLLOUT, '--runs-dir', str(runs), '--name', 'generalist']
    done = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT, check=False)
    run = runs / 'generalist'
    if done.returncode != 0:
        raise RuntimeError(f'{" ".join(command)} failed:\n{done.stderr[-2000:]}')
    return json.loads((run / 'summary.json').read_text()), (run / 'logs' / 'agent.log').read_text()


def run(report=print) -> dict:
    with tempfile.TemporaryDirectory(prefix='bench_generalist_') as directory:
        summary, log = rollout(Path(directory))
    load = os.getloadavg()[0]
    decision, totals, plan = DECISION.search(log), ACTIONS.search(log), PLAN.search(log)
    if decision is None or totals is None:
        raise RuntimeError(f'the agent logged no decision times:\n{log[-2000:]}')
    figures = {name: float(value) for name, value in decision.groupdict().items()}
    outcomes = summary.get('outcomes', {})
    report(
        f'generalist through ROS, simple-maze easy, {EPISODES} greedy episodes '
        f'({totals["actions"]} actions; outcomes {outcomes}), load {load:.1f}:'
    )
    report(
        f'  decision per step (state in -> action out, agent node): mean {figures["mean"]:.3f} '
        f'ms, median {figures["median"]:.3f} ms, p95 {figures["p95"]:.3f} ms, max '
        f'{figures["max"]:.3f} ms (target <= {TARGET_MS:g} ms: '
        f"{'met' if figures['mean'] <= TARGET_MS else 'NOT met'} by the mean); the thread's CPU "
        f'time of the same: mean {figures["cpu_mean"]:.3f} ms, p95 {figures["cpu_p95"]:.3f} ms '
        '(wall minus CPU: waiting for a core)'
    )
    if plan is not None:
        report(f'  the plan of the one grid (once, when it arrives): {float(plan["s"]):.2f} s')
    return {
        'generalist_ros_decision_mean_ms': figures['mean'],
        'generalist_ros_decision_median_ms': figures['median'],
        'generalist_ros_decision_p95_ms': figures['p95'],
        'generalist_ros_decision_max_ms': figures['max'],
        'generalist_ros_decision_cpu_mean_ms': figures['cpu_mean'],
        'generalist_ros_decision_cpu_p95_ms': figures['cpu_p95'],
        'generalist_ros_decision_per_target_ratio': round(figures['mean'] / TARGET_MS, 3),
        'generalist_ros_plan_s': float(plan['s']) if plan else None,
        'generalist_ros_actions': int(totals['actions']),
        'generalist_ros_load': round(load, 2),
    }


if __name__ == '__main__':
    run()
