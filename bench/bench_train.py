"""Benchmark: a recorded `stealth train` with the simulator in the environment's process
(`--compose`) against separate processes, in the same run.

Each is `make run`'s job cut to a fixed budget: simple-maze's easy goal, seed 1, EPISODES
episodes, no stop on success, the recorder on, one after the other (never side by side), each
REPEATS times, the best counting (other load only slows a run down). The figure is the training
part's steps per second from the run's summary.json (startup excluded). The two must run the
same episodes, step for step (the same seed): the bench refuses a pair that differs.
Run: ``source scripts/ros_env.sh && python bench/bench_train.py`` (needs ``make setup``).
"""

from __future__ import annotations

import json
from pathlib import Path
import shutil
import subprocess
import tempfile

REPO_ROOT = Path(__file__).resolve().parent.parent
EPISODES = 20
REPEATS = 2
TIMEOUT = 600.0  # s for one run
TRAIN = ('train', '--scenario', 'simple-maze', '--goal', 'easy', '--seed', '1',
         '--episodes', str(EPISODES), '--success-streak', '0')  # fmt: skip


def train(runs: Path, name: str, *extra: str) -> dict:
    """One run's summary.json."""
    stealth = shutil.which('stealth')
    if stealth is None:
        raise RuntimeError('stealth is not on PATH: source scripts/ros_env.sh (after make setup)')
    command = [stealth, *TRAIN, *extra, '--runs-dir', str(runs), '--name', name]
    done = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT, check=False)
    if done.returncode != 0:
        raise RuntimeError(f'{" ".join(command)} failed:\n{done.stderr[-2000:]}')
    return json.loads((runs / name / 'summary.json').read_text())


def run(report=print) -> dict:
    best: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix='bench_train_') as directory:
        for repeat in range(REPEATS):
            for mode, extra in (('separate', ()), ('composed', ('--compose',))):
                summary = train(Path(directory), f'{mode}-{repeat}', *extra)
                if mode not in best or summary['steps_per_s'] > best[mode]['steps_per_s']:
                    best[mode] = summary
    separate, composed = best['separate'], best['composed']
    steps = {mode: summary['steps'] for mode, summary in best.items()}
    if steps['separate'] != steps['composed']:
        raise RuntimeError(f'the two ran different episodes (steps {steps}): not comparable')
    ratio = composed['steps_per_s'] / separate['steps_per_s']
    report(
        f'stealth train, simple-maze easy, seed 1, {EPISODES} episodes ({steps["separate"]} '
        f'steps), recorder on, best of {REPEATS}:'
    )
    for mode, summary in best.items():
        report(
            f'  {mode}: {summary["steps_per_s"]:.0f} steps/s ({summary["run_s"]:.1f} s of '
            f'training, {summary["startup_s"]:.1f} s to start)'
        )
    report(f'  --compose / separate processes: {ratio:.2f}x the steps per second')
    return {
        'train_separate_steps_per_second': separate['steps_per_s'],
        'train_composed_steps_per_second': composed['steps_per_s'],
        'train_compose_speedup': round(ratio, 3),
        'train_steps': steps['separate'],
    }


if __name__ == '__main__':
    run()
