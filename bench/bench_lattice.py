"""Benchmark: building the move lattice (``stealth_core.move_lattice.MoveLattice``: which nodes
and moves the robot's disc fits) on a 600 x 600 cell map, against the brute-force reference the
tests check it by (``lattice_reference.reference_clear``, cell by cell in Python).

The map is bench_visibility's floor plan (0.05 m cells, 30 m x 30 m: rooms, doors, clutter), the
robot's radius 0.2 m, steps of 0.25 and 0.5 m. The reference over every node would take minutes,
so it judges a random sample of nodes (each node and its moves right and up), is checked equal
to the lattice there, and is extrapolated per node; the output says so. The module docstring of
move_lattice promises "a few tens of milliseconds" for the 0.25 m lattice.

Run: PYTHONPATH=ros2_ws/src/stealth_core python bench/bench_lattice.py
"""

from __future__ import annotations

from pathlib import Path
import sys
import time

from bench_visibility import REPEATS, RESOLUTION, bench_map, best_of
import numpy as np
from stealth_core.move_lattice import MoveLattice
from stealth_core.occupancy_map import OccupancyMap

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'ros2_ws/src/stealth_core/test'))
from lattice_reference import reference_clear  # noqa: E402  (the tests' helper, beside them)

RADIUS = 0.2
STEPS = (0.25, 0.5)
SAMPLE_NODES = 200


def sampled_reference(lattice: MoveLattice, occupancy, rng) -> tuple[float, int]:
    """(seconds per node, nodes judged) of the reference on a sample of the lattice's nodes,
    each node with its moves right and up; AssertionError where it and the lattice differ."""
    rows, cols = lattice.shape
    picks = rng.integers(0, (rows - 1, cols - 1), (SAMPLE_NODES, 2))  # each with both moves
    started = time.perf_counter()
    for a, b in picks:
        node = (a + lattice.i_min, b + lattice.j_min)
        p = lattice.node_to_point(node)
        right = lattice.node_to_point((node[0] + 1, node[1]))
        up = lattice.node_to_point((node[0], node[1] + 1))
        clear = reference_clear(occupancy, p, p, RADIUS)
        judged = (
            clear,
            clear and reference_clear(occupancy, right, right, RADIUS)
            and reference_clear(occupancy, p, right, RADIUS),
            clear and reference_clear(occupancy, up, up, RADIUS)
            and reference_clear(occupancy, p, up, RADIUS),
        )  # fmt: skip
        built = (lattice.node_mask[a, b], lattice.right_moves[a, b], lattice.up_moves[a, b])
        if tuple(map(bool, built)) != judged:
            raise AssertionError(f'the lattice differs from the reference at node {node}')
    return (time.perf_counter() - started) / SAMPLE_NODES, SAMPLE_NODES


def run(report=print) -> dict:
    blocked = bench_map()
    occupancy = OccupancyMap(np.where(blocked, 100, 0).astype(np.int8), RESOLUTION, (0, 0, 0))
    rng = np.random.default_rng(4)
    report(
        f'move lattice on a {blocked.shape[1]} x {blocked.shape[0]} cell map, robot radius '
        f'{RADIUS} m (build: best of {REPEATS}):'
    )
    figures = {}
    for step in STEPS:
        seconds, lattice = best_of(
            lambda step=step: MoveLattice(occupancy, (1.0, 1.0), step, RADIUS)
        )
        per_node, sampled = sampled_reference(lattice, occupancy, rng)
        nodes = lattice.node_mask.size
        reference = per_node * nodes
        report(
            f'  step {step} m, {lattice.shape[0]} x {lattice.shape[1]} nodes: build '
            f'{seconds * 1000:.1f} ms; reference {per_node * 1000:.2f} ms a node on {sampled} '
            f'sampled, extrapolated to all {nodes}: {reference:.1f} s; speed-up '
            f'{reference / seconds:.0f}x'
        )
        key = f'lattice_step_{str(step).replace(".", "_")}'
        figures.update(
            {
                f'{key}_build_seconds': round(seconds, 4),
                f'{key}_reference_seconds_extrapolated': round(reference, 2),
                f'{key}_speedup': round(reference / seconds, 1),
            }
        )
    return figures


def main() -> None:
    run()


if __name__ == '__main__':
    main()
