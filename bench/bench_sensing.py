"""Benchmark: what the robot that does not know the lights senses (``stealth_core.sensing``).

On lgfloor (600 x 600 cells at 0.05 m, a 60 x 60 move lattice, 8 m sensing range), from a
sample of lattice nodes: the vectorised sight of one node (every node and move sample cell in
range traced at once, no cache) against the per-line reference ``lighting.line_of_sight`` over
the same cells, one Python line at a time; then the cached sight a robot revisiting a node
gets; then a step of the Gym env on the sensed track (sense, remember, lay out the observation)
against a step of the full track, both over the same random actions.
Run: PYTHONPATH=ros2_ws/src/stealth_core python bench/bench_sensing.py
"""

from __future__ import annotations

import time

from bench_gym import steps_per_second
import numpy as np
from stealth_core.gym_env import StealthNavEnv
from stealth_core.lighting import line_of_sight
from stealth_core.sensing import Sensing

SCENARIO = 'lgfloor'
NODES = 20
REFERENCE_NODES = 3
STEPS = 3000


def _targets(sensing: Sensing, node: int) -> np.ndarray:
    """The cells the vectorised sight traces from ``node`` (flat indices)."""
    gaps = sensing.points - sensing.points[node]
    near = np.einsum('ij,ij->i', gaps, gaps) <= sensing.range * sensing.range
    moves = near[sensing.move_from] & near[sensing.move_to]
    wanted = np.zeros(len(sensing.cells), dtype=bool)
    wanted[sensing.node_cell[near]] = True
    wanted[sensing.move_cell[moves].ravel()] = True
    return sensing.cells[wanted]


def run(report=print) -> dict:
    model = StealthNavEnv(SCENARIO).model
    sensing = Sensing(model)
    nodes = np.random.default_rng(0).choice(sensing.n, NODES, replace=False).tolist()
    started = time.perf_counter()
    for node in nodes:
        sensing.trace(node)
    traced = (time.perf_counter() - started) / NODES

    width, blocked = sensing.frame.width, sensing.blocked
    cells = 0
    started = time.perf_counter()
    for node in nodes[:REFERENCE_NODES]:
        robot = divmod(int(sensing.cells[sensing.node_cell[node]]), width)[::-1]
        targets = _targets(sensing, node)
        cells += len(targets)
        for flat in targets.tolist():
            line_of_sight(blocked, robot, (flat % width, flat // width))
    reference = (time.perf_counter() - started) / REFERENCE_NODES

    for node in nodes:
        sensing.visible(node)
    started = time.perf_counter()
    for _ in range(10):
        for node in nodes:
            sensing.visible(node)
    cached = (time.perf_counter() - started) / (10 * NODES)

    actions = np.random.default_rng(1).integers(4, size=STEPS).tolist()
    # Seconds a step (reset at each episode end): bench_gym's rate, inverted.
    full = 1 / steps_per_second(StealthNavEnv(SCENARIO), actions)
    sensed = 1 / steps_per_second(StealthNavEnv(SCENARIO, track='sensed'), actions)

    ratio = reference / traced
    report(
        f'sensing on {SCENARIO} ({sensing.shape[1]} x {sensing.shape[0]} lattice, '
        f'{sensing.range:g} m range, ~{cells // REFERENCE_NODES} cells in range a node):'
    )
    report(f'  vectorised sight of a node: {traced * 1e3:.2f} ms (mean of {NODES} nodes)')
    report(f'  per-line reference (line_of_sight): {reference * 1e3:.1f} ms a node')
    report(f'  speed-up: {ratio:.0f}x; cached sight: {cached * 1e6:.1f} us')
    report(
        f'  Gym step: sensed track {sensed * 1e6:.0f} us, full track {full * 1e6:.1f} us '
        f'({sensed / full:.0f}x), {STEPS} random steps'
    )
    return {
        'sight_seconds': traced,
        'sight_reference_seconds': reference,
        'sight_speedup_ratio': ratio,
        'sight_cached_seconds': cached,
        'sensed_step_seconds': sensed,
        'full_step_seconds': full,
        'sensed_over_full_step_ratio': sensed / full,
    }


if __name__ == '__main__':
    run()
