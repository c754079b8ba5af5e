"""Benchmark: what saving the agent's checkpoint after every episode costs (`save_every: 1`, so
a respawned agent loses at most the episode in progress).

A Dyna-Q learner (n 200, the run's settings) is filled on a random walk over a lattice the size
of lgfloor's (STATES states, every action tried: a full table and a full model, the largest
checkpoint a hard run writes); then, in the same process, the time of one atomic save
(`save_policy`: npz, fsync, rename) against the learner's own work in one episode of EPISODE_STEPS
steps (update + 200 planning updates per step). The ratio is the share of the learner's time the
checkpoint adds; the ROS loop adds messaging and simulation on top, so a run loses less.

Run: PYTHONPATH=ros2_ws/src/stealth_agent python bench/bench_checkpoint.py
"""

from __future__ import annotations

from pathlib import Path
import statistics
import tempfile
import time

import numpy as np
from stealth_agent.learners import LearnerConfig, make_learner
from stealth_agent.policy_store import save_policy
from stealth_agent.state_index import StateIndex

STATES = 1_500  # lgfloor's lattice has about this many free nodes
EPISODE_STEPS = 200  # a typical training episode of a hard goal
SAVES = 15


def filled_learner(rng: np.random.Generator):
    config = LearnerConfig.constant(gamma=0.99, alpha=0.3, epsilon=0.2, n_planning=200)
    learner = make_learner('dyna', 4, config)
    index = StateIndex()
    for s in range(STATES):
        index.row((float(s % 40), float(s // 40)))
    learner.ensure_rows(STATES)
    for s in range(STATES):
        for a in range(4):
            learner.update(s, a, -1.0, int(rng.integers(STATES)), False, rng=rng)
    return learner, index


def run(report=print) -> dict:
    rng = np.random.default_rng(0)
    learner, index = filled_learner(rng)
    started = time.perf_counter()
    for _ in range(EPISODE_STEPS):
        s, s_next = (int(v) for v in rng.integers(STATES, size=2))
        learner.update(s, 0, -1.0, s_next, False, rng=rng)
    episode = time.perf_counter() - started
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / 'policy.npz'
        times = []
        for _ in range(SAVES):
            started = time.perf_counter()
            save_policy(path, learner, index, rng=rng)
            times.append(time.perf_counter() - started)
        size = path.stat().st_size
    save = statistics.median(times)
    ratio = save / episode
    report(
        f'checkpoint every episode: one save {save * 1e3:.1f} ms ({size / 1024:.0f} KiB, '
        f'{STATES} states, Dyna model {learner.model_size}) against {episode * 1e3:.0f} ms of '
        f"the learner's own work in a {EPISODE_STEPS}-step episode: ratio {ratio:.3f}"
    )
    return {
        'checkpoint_save_ms': round(save * 1e3, 2),
        'checkpoint_bytes': size,
        'checkpoint_learner_episode_ms': round(episode * 1e3, 1),
        'checkpoint_save_per_episode_ratio': round(ratio, 4),
    }


def main() -> None:
    run()


if __name__ == '__main__':
    main()
