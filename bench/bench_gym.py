"""Benchmark: in-process environment steps per second, StealthNav-v0 against Gymnasium's
CliffWalking-v1, both made by ``gymnasium.make`` (so both carry the same default wrappers:
PassiveEnvChecker and OrderEnforcing) and both stepped with the same uniformly random actions,
resetting whenever an episode ends. Target: at least half CliffWalking's rate.

Run: PYTHONPATH=ros2_ws/src/stealth_core python bench/bench_gym.py
"""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import stealth_core.gym_env  # noqa: F401  (registers StealthNav-v0)

SCENARIO = 'map1'
STEPS = 100_000
REPEATS = 5  # interleaved; the best of each is kept
TARGET = 0.5


def steps_per_second(env: gym.Env, actions: list[int]) -> float:
    env.reset(seed=0)
    started = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return len(actions) / (time.perf_counter() - started)


def run(report=print) -> dict:
    ours = gym.make('StealthNav-v0', scenario=SCENARIO)
    theirs = gym.make('CliffWalking-v1')
    actions = np.random.default_rng(0).integers(4, size=STEPS).tolist()
    best = {'ours': 0.0, 'theirs': 0.0}
    for _ in range(REPEATS):
        best['theirs'] = max(best['theirs'], steps_per_second(theirs, actions))
        best['ours'] = max(best['ours'], steps_per_second(ours, actions))
    ratio = best['ours'] / best['theirs']
    report(f'in-process env steps, {STEPS} random actions, best of {REPEATS}, via gymnasium.make:')
    report(f'  StealthNav-v0 ({SCENARIO}): {best["ours"]:,.0f} steps/s')
    report(f'  CliffWalking-v1:        {best["theirs"]:,.0f} steps/s')
    report(f'  ratio: {ratio:.2f} (target >= {TARGET})')
    return {
        'gym_scenario': SCENARIO,
        'gym_stealthnav_steps_per_second': round(best['ours']),
        'gym_cliffwalking_steps_per_second': round(best['theirs']),
        'gym_steps_ratio': round(ratio, 3),
        'gym_target_met': bool(ratio >= TARGET),
    }


def main() -> None:
    run()


if __name__ == '__main__':
    main()
