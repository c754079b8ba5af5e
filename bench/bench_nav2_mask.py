"""Benchmark: exposure mask updates per second with moving lights (stealth_nav2.exposure_mask),
against the from-scratch way in the same run: ``visibility.visibility_field`` at the time, all
lights traced afresh (what the environment's visibility grid does for moving lights), then the
same mask values.

On lgfloor-moving (a sweeping lamp, 600 x 600 cells) and map1-moving (a patrolling lamp, 400 x
400): the mask at 10 Hz of light time over the lights' 24 s cycle twice, the first lap filling
the per-lamp sight memos (a cold start), the second from them (the steady state the node runs
in); the from-scratch way on a few of the same times. The node needs >= 5 updates/s.

Run: PYTHONPATH=ros2_ws/src/stealth_core:ros2_ws/src/stealth_nav2 \
    python bench/bench_nav2_mask.py
"""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np
from stealth_core.scenario import load_scenario
from stealth_core.visibility import visibility_field
from stealth_nav2.exposure_mask import ExposureMask, mask_levels

SCENARIOS = ('lgfloor-moving', 'map1-moving')
RATE = 10.0  # updates per second of light time, the node's default update_rate
CYCLE = 24.0  # s: both scenarios' moving lamp repeats every 24 s
BASELINE_UPDATES = 5
GOAL = 5.0  # updates/s the node must sustain


def _rate(compute, times) -> float:
    """Updates per second of wall time of compute(t) over the times."""
    started = time.perf_counter()
    for t in times:
        compute(float(t))
    return len(times) / (time.perf_counter() - started)


def run(report=print) -> dict:
    figures = {'load_average_1min': round(os.getloadavg()[0], 2)}
    report(
        f'exposure mask updates per second at {RATE:g} Hz of light time (load average '
        f'{figures["load_average_1min"]:g} on {os.cpu_count()} CPUs):'
    )
    for name in SCENARIOS:
        scenario = load_scenario(name)
        occupancy = scenario.map
        with tempfile.TemporaryDirectory() as cache:  # the static lights' field, not timed
            mask = ExposureMask.of_scenario(scenario, cache_dir=cache)
        times = np.arange(0.0, CYCLE, 1.0 / RATE)
        cold = _rate(mask.at, times)
        warm = _rate(mask.at, times + CYCLE)

        def from_scratch(t, scenario=scenario, occupancy=occupancy, mask=mask):
            total, _ = visibility_field(
                occupancy.blocked, occupancy.resolution, occupancy.origin, scenario.lights, t
            )
            return mask_levels(total, occupancy.blocked, mask.threshold, mask.band_start)

        step = len(times) // BASELINE_UPDATES
        baseline = _rate(from_scratch, times[::step][:BASELINE_UPDATES] + CYCLE)
        ratio = warm / baseline
        report(
            f'  {name} ({occupancy.width} x {occupancy.height} cells, {len(scenario.lights)} '
            f'lights): first lap {cold:.1f}/s, then {warm:.1f}/s; from scratch {baseline:.2f}/s;'
            f' speed-up {ratio:.0f}x (goal >= {GOAL:g}/s)'
        )
        key = f'nav2_mask_{name.replace("-", "_")}'
        figures[f'{key}_first_lap_updates_per_second'] = round(cold, 2)
        figures[f'{key}_updates_per_second'] = round(warm, 2)
        figures[f'{key}_from_scratch_updates_per_second'] = round(baseline, 3)
        figures[f'{key}_speedup'] = round(ratio, 1)
        figures[f'{key}_goal_met'] = bool(warm >= GOAL and cold >= GOAL)
    return figures


def main() -> None:
    run()


if __name__ == '__main__':
    main()
