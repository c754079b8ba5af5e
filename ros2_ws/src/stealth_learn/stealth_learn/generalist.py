"""The lights-known generalist as a policy, and its evaluation on generated test scenarios in
the JAX environment against value iteration's optimum and the same network untrained.

    policy = GeneralistPolicy.load(path, env.layout_id)     # refused for another layout
    action = policy.act(observation.grid)                   # the grid of jax_env's 'grid' layout

    python -m stealth_learn.generalist --test 30            # the report's figures

The light field is static on this track, so the value map depends only on the grid's static
channels: ``rollout`` computes it once per episode and attends at the robot's cell each step,
which is exactly what ``act`` gives step by step (``test_generalist`` checks they agree).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import os
from pathlib import Path
import sys
import tempfile
import time

import numpy as np
from stealth_core.planners import follow, value_iteration
from stealth_core.scenario_generator import GenerationError, Options

from stealth_learn import generalist_data as data
from stealth_learn import policy_file
from stealth_learn.env_tables import TaskArrays
from stealth_learn.interruptible import interruptible
from stealth_learn.jax_deps import jax, jnp
from stealth_learn.jax_env import build
from stealth_learn.vin import ROBOT, Vin, logits_of_cells

DEFAULT_POLICY = policy_file.SHIPPED


class GeneralistPolicy:
    """The network and its parameters; decisions come from the parameters alone."""

    def __init__(self, params, architecture: dict, header: dict | None = None):
        self.model = Vin(**architecture)
        self.variables = {'params': jax.tree_util.tree_map(jnp.asarray, params)}
        self.header = header or {}
        self._logits = jax.jit(lambda v, g: logits_of_cells(self.model, v, g))

    @classmethod
    def load(cls, path, env_layout: str) -> GeneralistPolicy:
        params, header = policy_file.load(path, env_layout)
        return cls(params, header['architecture'], header)

    @classmethod
    def untrained(cls, architecture: dict, seed: int = 0) -> GeneralistPolicy:
        """The same architecture at its initialisation (the issue's untrained comparison)."""
        model = Vin(**architecture)
        grid = jnp.zeros((1, 4, 4, 7), jnp.float32)
        return cls(model.init(jax.random.PRNGKey(seed), grid)['params'], architecture)

    def cell_logits(self, grid) -> np.ndarray:
        """(R, C, 4) the logits of every cell of one grid (R, C, 7); Ctrl-C stops it at once,
        compile or run (``interruptible``)."""
        batch = jnp.asarray(grid)[None]
        return interruptible(lambda: np.asarray(self._logits(self.variables, batch)))[0]

    def act(self, grid) -> int:
        """The move (0 up, 1 down, 2 left, 3 right) at the robot's cell of one grid."""
        return int(np.argmax(self.cell_logits(grid)[robot_cell(grid)]))


def robot_cell(grid) -> tuple[int, int]:
    """(row, col) of the robot in one grid (R, C, 7): its robot channel's maximum."""
    robot = np.asarray(grid)[..., ROBOT]
    row, col = np.unravel_index(int(np.argmax(robot)), robot.shape)
    return int(row), int(col)


class PlanCache:
    """Every cell's move (``GeneralistPolicy.act`` at each cell) for a grid, computed by the
    network once per distinct grid and then looked up: with static lights a whole episode (or
    run) reads one plan, and a decision costs a lookup. The robot channel is ignored (the
    decision is read at the robot's cell); the last grid is compared in place (a decision's
    common case, about 10x cheaper than hashing a copy), another looked up by the hash of its
    static channels; the ``keep`` latest distinct plans are kept. ``prepare``: the grid the
    network reads for a grid (e.g. ``belief.believed_grid``; default the grid itself), applied
    once per plan computed."""

    def __init__(self, policy: GeneralistPolicy, keep: int = 64, prepare=None):
        self.policy = policy
        self.keep = keep
        self.prepare = prepare
        self.computed = 0  # plans computed (each a full pass of the network)
        self._plans: dict[bytes, np.ndarray] = {}
        self._last: tuple[np.ndarray, np.ndarray] | None = None  # (static grid, its moves)

    def __len__(self) -> int:
        return len(self._plans)

    def moves(self, grid) -> np.ndarray:
        """(R, C) int8: the move at every cell of ``grid`` (R, C, 7)."""
        grid = np.asarray(grid)
        last = self._last
        if (
            last is not None
            and last[0].shape == grid.shape
            and np.array_equal(grid[..., :ROBOT], last[0][..., :ROBOT])
            and np.array_equal(grid[..., ROBOT + 1 :], last[0][..., ROBOT + 1 :])
        ):
            return last[1]
        static = np.array(grid, dtype=np.float32)
        static[..., ROBOT] = 0.0
        key = hashlib.blake2b(static.tobytes(), digest_size=16).digest() + bytes(
            str(static.shape), 'ascii'
        )
        moves = self._plans.get(key)
        if moves is None:
            read = static if self.prepare is None else self.prepare(static)
            moves = self.policy.cell_logits(read).argmax(axis=-1).astype(np.int8)
            self.computed += 1
            if len(self._plans) >= self.keep:
                self._plans.pop(next(iter(self._plans)))
            self._plans[key] = moves
        self._last = (static, moves)
        return moves


@dataclasses.dataclass(frozen=True)
class Episode:
    name: str
    outcome: int  # reward.EpisodeOutcome: 0 success, 1 detected, 2 timeout
    episode_return: float
    steps: int
    optimal_return: float
    optimal_steps: int


def rollout(policy: GeneralistPolicy, scenario) -> Episode:
    """One greedy episode of ``policy`` on ``scenario`` in the JAX environment, and value
    iteration's return and path length on the same scenario."""
    env, params = build([scenario], track='full', layout='grid')
    one = env.scenario(params, 0)
    obs, state = env.reset(jax.random.PRNGKey(0), one)
    logits = policy.cell_logits(np.asarray(obs.grid))
    actions = jnp.asarray(logits.argmax(-1).reshape(-1))  # per cell of the padded grid
    cells = env.dims.cells

    def body(carry, _):
        state, done, info = carry
        action = actions[state.place % cells]
        _, after, _, step_done, step_info = env.step_env(None, state, action, one)
        keep = lambda new, old: jax.tree_util.tree_map(  # noqa: E731
            lambda a, b: jnp.where(done, b, a), new, old
        )
        return (keep(after, state), done | step_done, keep(step_info, info)), None

    _, _, _, _, info0 = env.step_env(None, state, 0, one)
    limit = int(one.step_limit)
    carry, _ = jax.lax.scan(body, (state, jnp.asarray(False), info0), None, length=limit)
    info = carry[2]
    model = TaskArrays(scenario).model
    optimum = value_iteration(model)
    path = follow(model, lambda i: int(optimum.policy[i]))
    return Episode(
        getattr(scenario, 'name', str(scenario)),
        int(info['outcome']),
        float(info['episode_return']),
        int(info['steps']),
        optimum.optimal_return,
        len(path) - 1,
    )


def summary(episodes) -> dict:
    """Undetected success rate, return relative to value iteration's, path length ratio."""
    success = [e.outcome == 0 for e in episodes]
    both = [e for e in episodes if e.outcome == 0]
    return {
        'scenarios': len(episodes),
        'success_rate': float(np.mean(success)),
        'detected': int(sum(e.outcome == 1 for e in episodes)),
        'timeouts': int(sum(e.outcome == 2 for e in episodes)),
        'return_ratio': float(
            sum(e.episode_return for e in episodes) / sum(e.optimal_return for e in episodes)
        )
        if episodes
        else float('nan'),
        'path_length_ratio': float(np.mean([e.steps / e.optimal_steps for e in both]))
        if both
        else float('nan'),
    }


def unseen_scenarios(count: int, options: Options, directory: Path, offset: int = 0):
    """``count`` generated scenarios of the test seed range (a seed not proven is skipped)."""
    out = []
    for seed in data.seeds_of('test', count, offset):
        try:
            out.append(data.scenario_of(seed, options, directory))
        except GenerationError:
            continue
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog='python -m stealth_learn.generalist',
        description='Evaluate the lights-known generalist and the same network untrained on '
        'generated test scenarios (test seed range), against value iteration.',
    )
    parser.add_argument(
        '--policy', type=Path, default=DEFAULT_POLICY, help='the weights file (default: shipped)'
    )
    parser.add_argument('--test', type=int, default=30, help='generated test scenarios, >= 1 (30)')
    parser.add_argument('--width', type=int, default=30, help='building width, m (30)')
    parser.add_argument('--height', type=int, default=30, help='building height, m (30)')
    parser.add_argument('--lights', type=int, default=4, help='searchlights per building (4)')
    args = parser.parse_args(argv)
    if args.test < 1:
        parser.error(f'--test: expected a whole number >= 1, got {args.test}')
    try:
        try:
            options = Options(width=args.width, height=args.height, lights=args.lights)
            options.check()
            policy = GeneralistPolicy.load(args.policy, policy_file.policy_layout('full'))
        except (GenerationError, ValueError) as error:  # PolicyFileError, LayoutError
            print(f'generalist: {error}', file=sys.stderr)
            return 2
        evaluate(policy, options, args.test)
    except KeyboardInterrupt:
        print('generalist: interrupted', file=sys.stderr)
        return 130
    return 0


def evaluate(policy: GeneralistPolicy, options: Options, count: int) -> None:
    """Print the trained and the untrained network's figures on ``count`` test scenarios."""
    started = time.monotonic()
    scenarios = unseen_scenarios(count, options, Path(tempfile.mkdtemp(prefix='test-')))
    untrained = GeneralistPolicy.untrained(policy.header['architecture'])
    for name, who in (('generalist', policy), ('untrained', untrained)):
        episodes = [interruptible(lambda w=who, s=s: rollout(w, s)) for s in scenarios]
        figures = summary(episodes)
        print(
            f'{name}: '
            + ', '.join(
                f'{k} {v:.3f}' if isinstance(v, float) else f'{k} {v}' for k, v in figures.items()
            )
        )
    print(f'{time.monotonic() - started:.0f} s, load {os.getloadavg()[0]:.1f}')


if __name__ == '__main__':
    sys.exit(main())
