"""Benchmark: the JAX environment's steps per second (``stealth_learn.jax_env``, jit and vmap
over 1024 environments, 64 on the sensed track, a ``lax.scan`` of steps) against the Gym env's
(``StealthNav-v0`` via ``gymnasium.make``, one environment, as bench_gym), in the same process,
same scenario, random actions, resetting whenever an episode ends. Target (issue 30): at least
100x, on the full track (vector layout) and on the sensed track.

Every observation feeds a checksum the scan returns, so XLA cannot drop the observation's work
(a learner reads every observation). The sensed track is measured too, with its grid
observation (``obs_layout``: 7 channels over the lattice), against the Gym sensed track, and
the full track with the grid observation (the map and the light field each step).

Run: PYTHONPATH=ros2_ws/src/stealth_core:ros2_ws/src/stealth_learn \
    python bench/bench_jax_env.py
"""

from __future__ import annotations

import time

from bench_gym import steps_per_second
import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
import stealth_core.gym_env  # noqa: F401  (registers StealthNav-v0)
from stealth_learn.jax_env import build

SCENARIO = 'map1'
GYM_STEPS = 50_000
ENVS = 1024
SENSED_ENVS = (
    64  # a sensed env carries its memory and a 7-channel grid: more stop fitting in cache
)
SCAN_STEPS = 500  # per environment, per timed call
REPEATS = 3  # interleaved; the best of each is kept
TARGET = 100.0


def jax_runner(track: str, layout: str, envs: int, steps: int):
    """A jitted call stepping ``envs`` environments ``steps`` times; returns a timer."""
    env, params = build([SCENARIO], track=track, layout=layout)
    one = env.scenario(params, 0)
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def checksum(obs):
        return sum(jnp.sum(leaf) for leaf in jax.tree.leaves(obs))

    @jax.jit
    def run(key, state, actions):
        def body(carry, action):
            key, state, total = carry
            key, sub = jax.random.split(key)
            obs, state, reward, _, _ = step(jax.random.split(sub, envs), state, action, one)
            return (key, state, total + jnp.sum(reward) + checksum(obs)), None

        (_, state, total), _ = jax.lax.scan(body, (key, state, jnp.float32(0.0)), actions)
        return state, total

    keys = jax.random.split(jax.random.key(0), envs)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, one)
    rng = np.random.default_rng(0)
    actions = jnp.asarray(rng.integers(env.num_actions, size=(steps, envs)), jnp.int32)
    jax.block_until_ready(run(jax.random.key(1), state, actions))  # compile, untimed

    def timed() -> float:
        started = time.perf_counter()
        jax.block_until_ready(run(jax.random.key(2), state, actions))
        return steps * envs / (time.perf_counter() - started)

    return timed


def measure(track: str, layout: str, envs: int, gym_steps: int) -> dict:
    ours = jax_runner(track, layout, envs, SCAN_STEPS)
    theirs = gym.make('StealthNav-v0', scenario=SCENARIO, track=track)
    actions = np.random.default_rng(0).integers(theirs.action_space.n, size=gym_steps).tolist()
    best = {'jax': 0.0, 'gym': 0.0}
    for _ in range(REPEATS):
        best['gym'] = max(best['gym'], steps_per_second(theirs, actions))
        best['jax'] = max(best['jax'], ours())
    return best


def run(report=print) -> dict:
    figures = {
        'jax_env_scenario': SCENARIO,
        'jax_env_envs': ENVS,
        'jax_env_sensed_envs': SENSED_ENVS,
    }
    report(
        f'environment steps, {SCENARIO}, random actions, best of {REPEATS}; JAX: jit + vmap, '
        f'scans of {SCAN_STEPS} steps; Gym: one env via gymnasium.make:'
    )
    for track, layout, envs, gym_steps in (
        ('full', 'vector', ENVS, GYM_STEPS),
        ('full', 'grid', SENSED_ENVS, GYM_STEPS),
        ('sensed', 'grid', SENSED_ENVS, GYM_STEPS // 10),
    ):
        best = measure(track, layout, envs, gym_steps)
        ratio = best['jax'] / best['gym']
        target = f' (target >= {TARGET:g})' if layout == 'vector' or track == 'sensed' else ''
        report(f'  track {track}, layout {layout}, {envs} envs:')
        report(f'    JAX: {best["jax"]:,.0f} steps/s')
        report(f'    Gym: {best["gym"]:,.0f} steps/s')
        report(f'    ratio: {ratio:,.1f}{target}')
        name = track if layout == 'vector' or track == 'sensed' else f'{track}_{layout}'
        figures.update({
            f'jax_env_{name}_steps_per_second': round(best['jax']),
            f'jax_env_gym_{name}_steps_per_second': round(best['gym']),
            f'jax_env_{name}_ratio': round(ratio, 2),
        })  # fmt: skip
    figures['jax_env_target_met'] = bool(figures['jax_env_full_ratio'] >= TARGET)
    figures['jax_env_sensed_target_met'] = bool(figures['jax_env_sensed_ratio'] >= TARGET)
    return figures


def main() -> None:
    run()


if __name__ == '__main__':
    main()
