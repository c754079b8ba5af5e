"""Benchmark: the vectorised visibility field against the per-point reference.

A 600 x 600 cell map (0.05 m cells, 30 m x 30 m: rooms, doors, clutter, unknown patches) with
four lights of up to 9 m range. The reference over all 360,000 cells would take minutes, so it
is timed on a random sample of cells and extrapolated per cell; the output says so.

Then the one-bounce light (``stealth_core.bounce``) on lgfloor (600 x 600, its four lights,
albedo 0.3, range 3 m): the compiled bounce field against ``bounce.point_bounce`` the same way,
the reference's one-off work (finding the emitters and their received light, point by point)
counted once in its extrapolated time.

Last the lines of sight as the light model's search asks them (``visibility._occluded``): from
each of 300 lamp cells of lgfloor, 200 random cells of a 4 m box around it (what a birth or a
moved light asks of a lamp cell new to it), compiled (``sight_kernels``) against the lockstep
numpy trace it replaced (the path where numba does not import), the same answers asserted.
Run: PYTHONPATH=ros2_ws/src/stealth_core python bench/bench_visibility.py
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from stealth_core.bounce import Bounce, point_bounce, received_light, wall_emitters
from stealth_core.lighting import GridFrame, point_visibility
from stealth_core.scenario import load_scenario
from stealth_core.searchlight import Searchlight
from stealth_core.visibility import (
    _occluded,
    _occluded_in_lockstep,
    bounce_field,
    corner_maps,
    visibility_field,
)

SIZE = 600
RESOLUTION = 0.05
ORIGIN = (0.0, 0.0, 0.0)
SAMPLE_CELLS = 2000
REPEATS = 3
BOUNCE = Bounce(albedo=0.3, range=3.0)
BOUNCE_SAMPLE_CELLS = 1000
SIGHT_LAMPS = 300
SIGHT_BOX = 2.0  # m from the lamp cell to the box's sides
SIGHT_CELLS = 200  # random cells of the box a lamp cell is asked for (a new lamp's samples)


def bench_map(seed: int = 0) -> np.ndarray:
    """Blocked mask of a floor plan: outer wall, a 3 x 3 grid of rooms with doors, clutter."""
    rng = np.random.default_rng(seed)
    blocked = np.zeros((SIZE, SIZE), dtype=bool)
    blocked[:4, :] = blocked[-4:, :] = blocked[:, :4] = blocked[:, -4:] = True
    for wall in (200, 400):
        blocked[wall - 2 : wall + 2, :] = True
        blocked[:, wall - 2 : wall + 2] = True
        for door in (100, 300, 500):
            blocked[wall - 2 : wall + 2, door - 20 : door + 20] = False
            blocked[door - 20 : door + 20, wall - 2 : wall + 2] = False
    for _ in range(60):  # furniture and unknown patches
        col, row = rng.integers(10, SIZE - 40, 2)
        blocked[row : row + rng.integers(4, 30), col : col + rng.integers(4, 30)] = True
    return blocked


def bench_lights() -> list[Searchlight]:
    return [
        Searchlight('L1', 5.1, 5.1, math.radians(45), math.radians(90), 9.0),
        Searchlight('L2', 24.9, 5.1, math.radians(135), math.radians(120), 9.0, soft_edge=0.3),
        Searchlight('L3', 15.0, 25.0, math.radians(-90), math.radians(180), 8.0),
        Searchlight('L4', 15.1, 15.1, 0.0, 2 * math.pi, 9.0),
    ]


def best_of(compute):
    """(the best of REPEATS timings in seconds, the last result) of compute()."""
    seconds, result = math.inf, None
    for _ in range(REPEATS):
        started = time.perf_counter()
        result = compute()
        seconds = min(seconds, time.perf_counter() - started)
    return seconds, result


def run(report=print) -> dict:
    blocked, lights = bench_map(), bench_lights()
    field_seconds, (total, _) = best_of(
        lambda: visibility_field(blocked, RESOLUTION, ORIGIN, lights)
    )

    frame = GridFrame.of(blocked, RESOLUTION, ORIGIN)
    sample = np.random.default_rng(1).choice(blocked.size, SAMPLE_CELLS, replace=False)
    rows, cols = np.unravel_index(sample, blocked.shape)
    centres = [tuple(map(float, frame.cell_centre(c, r))) for c, r in zip(cols, rows, strict=True)]
    started = time.perf_counter()
    reference = [point_visibility(blocked, RESOLUTION, ORIGIN, lights, x, y) for x, y in centres]
    sample_seconds = time.perf_counter() - started
    if not np.array_equal(np.array(reference), total[rows, cols]):
        raise AssertionError('visibility field differs from the reference on the sample')
    reference_seconds = sample_seconds / SAMPLE_CELLS * blocked.size
    ratio = reference_seconds / field_seconds

    report(f'visibility field, {SIZE} x {SIZE} cells, {len(lights)} lights up to 9 m range:')
    report(f'  vectorised field (best of {REPEATS}): {field_seconds:.3f} s')
    report(
        f'  per-point reference: {sample_seconds:.3f} s for a random sample of {SAMPLE_CELLS}'
        f' cells, extrapolated to all {blocked.size} cells: {reference_seconds:.1f} s'
    )
    report(f'  speed-up: {ratio:.0f}x (goal >= 100x, field < 1 s)')
    figures = _figures('visibility', field_seconds, reference_seconds, SAMPLE_CELLS, 1.0)
    return {**figures, **run_bounce(report), **run_sight(report)}


def run_sight(report=print) -> dict:
    """The lines of sight of many small traces, compiled against lockstep (see the module)."""
    occupancy = load_scenario('lgfloor').map
    blocked = occupancy.blocked
    corners = corner_maps(blocked)
    height, width = blocked.shape
    reach = int(round(SIGHT_BOX / occupancy.resolution))
    rng = np.random.default_rng(3)
    traces = []
    for _ in range(SIGHT_LAMPS):
        col, row = int(rng.integers(width)), int(rng.integers(height))
        rows, cols = np.mgrid[
            max(row - reach, 0) : min(row + reach + 1, height),
            max(col - reach, 0) : min(col + reach + 1, width),
        ]
        pick = rng.choice(cols.size, min(SIGHT_CELLS, cols.size), replace=False)
        traces.append(((col, row), cols.ravel()[pick], rows.ravel()[pick]))
    _occluded(blocked, corners, *traces[0])  # compiled, or loaded from numba's cache

    def trace_all(trace):
        return [trace(blocked, corners, lamp, cols, rows) for lamp, cols, rows in traces]

    compiled_seconds, compiled = best_of(lambda: trace_all(_occluded))
    lockstep_seconds, lockstep = best_of(lambda: trace_all(_occluded_in_lockstep))
    if not all(np.array_equal(a, b) for a, b in zip(compiled, lockstep, strict=True)):
        raise AssertionError('the compiled lines of sight differ from the lockstep ones')
    lines = sum(cols.size for _, cols, _ in traces)
    ratio = lockstep_seconds / compiled_seconds
    report(
        f'lines of sight, lgfloor, {SIGHT_LAMPS} lamp cells x {SIGHT_CELLS} cells of a'
        f' {2 * SIGHT_BOX:g} m box ({lines} lines): compiled {compiled_seconds * 1e3:.1f} ms,'
        f' lockstep numpy {lockstep_seconds * 1e3:.1f} ms (best of {REPEATS}): {ratio:.0f}x'
    )
    return {
        'sight_compiled_seconds': round(compiled_seconds, 4),
        'sight_lockstep_seconds': round(lockstep_seconds, 4),
        'sight_speedup': round(ratio, 1),
    }


def _figures(name, field_seconds, reference_seconds, sample_cells, limit_seconds) -> dict:
    """The JSON figures of one field against its reference; the goal: >= 100x, < limit."""
    ratio = reference_seconds / field_seconds
    return {
        f'{name}_field_seconds': round(field_seconds, 4),
        f'{name}_reference_seconds_extrapolated': round(reference_seconds, 2),
        f'{name}_reference_sample_cells': sample_cells,
        f'{name}_speedup': round(ratio, 1),
        f'{name}_goals_met': bool(ratio >= 100 and field_seconds < limit_seconds),
    }


def run_bounce(report=print) -> dict:
    """The bounce field on lgfloor against its per-point reference (see the module)."""
    scenario = dataclasses.replace(load_scenario('lgfloor'), bounce=BOUNCE)
    occupancy, lights = scenario.map, scenario.lights
    blocked, resolution, origin = occupancy.blocked, occupancy.resolution, occupancy.origin
    frame = GridFrame.of(blocked, resolution, origin)
    direct, _ = visibility_field(blocked, resolution, origin, lights)
    small = np.zeros((4, 4), dtype=bool)
    small[0] = True
    bounce_field(GridFrame.of(small, 1.0, (0, 0)), small, np.ones((4, 4)), BOUNCE)  # compiled
    field_seconds, bounced = best_of(lambda: bounce_field(frame, blocked, direct, BOUNCE))

    started = time.perf_counter()
    emitters = wall_emitters(blocked)
    received = received_light(blocked, resolution, origin, lights, emitters)
    setup_seconds = time.perf_counter() - started
    sample = np.random.default_rng(2).choice(blocked.size, BOUNCE_SAMPLE_CELLS, replace=False)
    rows, cols = np.unravel_index(sample, blocked.shape)
    started = time.perf_counter()
    reference = [
        point_bounce(blocked, resolution, origin, emitters, received, BOUNCE, *map(float, xy))
        for xy in zip(*frame.cell_centre(cols, rows), strict=True)
    ]
    sample_seconds = time.perf_counter() - started
    if not np.array_equal(np.array(reference), bounced[rows, cols]):
        raise AssertionError('bounce field differs from the reference on the sample')
    reference_seconds = setup_seconds + sample_seconds / BOUNCE_SAMPLE_CELLS * blocked.size
    ratio = reference_seconds / field_seconds
    lit = int(np.count_nonzero(np.asarray(received) > 0.0))
    report(
        f'bounce field, lgfloor {frame.width} x {frame.height} cells, {len(lights)} lights,'
        f' albedo {BOUNCE.albedo:g}, range {BOUNCE.range:g} m ({lit} of {len(received)} wall'
        ' cells lit):'
    )
    report(f'  compiled field (best of {REPEATS}): {field_seconds:.3f} s')
    report(
        f'  per-point reference: {setup_seconds:.1f} s for the emitters and their light, then'
        f' {sample_seconds:.2f} s for a random sample of {BOUNCE_SAMPLE_CELLS} cells,'
        f' extrapolated to all {blocked.size} cells: {reference_seconds:.1f} s'
    )
    report(f'  bounce speed-up: {ratio:.0f}x (goal >= 100x, field < 2 s)')
    return _figures('bounce', field_seconds, reference_seconds, BOUNCE_SAMPLE_CELLS, 2.0)


def main() -> None:
    run()


if __name__ == '__main__':
    main()
