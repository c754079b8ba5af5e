"""Benchmark: `stealth train` through the topics interface (cmd_vel/odom on simulated time, the
simulator in lockstep) against the simulator's move service, in the same run (issue 28: within
3x of the service's wall time).

Each pair is the same command, simple-maze's easy goal, seed 1, EPISODES episodes, no stop on
success, the recorder on, once with ``--set environment.robot_interface=topics`` and once
without, one after the other (never side by side); PAIRS pairs, interleaved, so a change in the
machine's load hits both. The figure is each pair's ratio of training wall time (the summary's
``run_s``, startup excluded), and of wall time per RL step (a topics run is not deterministic:
its episodes may take other steps than the service run's), their median over the pairs. The
absolute times and the load (1-minute average) are printed with them: the machine is shared.
Run: ``source scripts/ros_env.sh && python bench/bench_topics.py`` (needs ``make setup``).
"""

from __future__ import annotations

import os
from pathlib import Path
import statistics
import tempfile

from bench_train import train

EPISODES = 10
PAIRS = 3
TARGET_RATIO = 3.0
TOPICS = ('--set', 'environment.robot_interface=topics')


def run(report=print) -> dict:
    pairs = []
    with tempfile.TemporaryDirectory(prefix='bench_topics_') as directory:
        for pair in range(PAIRS):
            runs = {}
            for mode, extra in (('topics', TOPICS), ('service', ())):
                load = os.getloadavg()[0]
                summary = train(
                    Path(directory), f'{mode}-{pair}', '--episodes', str(EPISODES), *extra
                )
                runs[mode] = summary
                report(
                    f'  pair {pair + 1} {mode}: {summary["run_s"]:.1f} s of training, '
                    f'{summary["steps"]} steps, {summary["steps_per_s"]:.0f} steps/s '
                    f'(load {load:.1f} -> {os.getloadavg()[0]:.1f})'
                )
            pairs.append(runs)
    wall = [p['topics']['run_s'] / p['service']['run_s'] for p in pairs]
    per_step = [
        (p['topics']['run_s'] / p['topics']['steps'])
        / (p['service']['run_s'] / p['service']['steps'])
        for p in pairs
    ]
    ratio, step_ratio = statistics.median(wall), statistics.median(per_step)
    report(
        f'stealth train, simple-maze easy, seed 1, {EPISODES} episodes, recorder on, '
        f'{PAIRS} interleaved pairs:'
    )
    report(
        f'  topics / service: {ratio:.2f}x the training wall time (pairs '
        f'{", ".join(f"{r:.2f}" for r in wall)}), {step_ratio:.2f}x per step; '
        f'target <= {TARGET_RATIO:g}x'
    )
    return {
        'train_topics_seconds': round(statistics.median(p['topics']['run_s'] for p in pairs), 2),
        'train_service_seconds': round(statistics.median(p['service']['run_s'] for p in pairs), 2),
        'train_topics_over_service_ratio': round(ratio, 3),
        'train_topics_over_service_per_step_ratio': round(step_ratio, 3),
    }


if __name__ == '__main__':
    run()
