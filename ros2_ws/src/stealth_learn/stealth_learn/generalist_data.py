"""The generalist's data: generated scenarios of one seed range, each as the grid the network
reads and value iteration's optimal moves on every cell (dense imitation targets: one scenario
teaches every valid cell at once, not one trajectory).

Plain numpy (no jax): ``stealth_core``'s generator, lattice model and ``value_iteration``;
``env_tables`` for the grid channels the JAX environment observes, so the network trains on
exactly what it sees when it acts.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from stealth_core.grid_observation import stack
from stealth_core.planners import value_iteration
from stealth_core.scenario import load_scenario
from stealth_core.scenario_generator import SEED_RANGES, GenerationError, Options, generate

from stealth_learn.env_tables import TaskArrays
from stealth_learn.obs_layout import CHANNELS
from stealth_learn.vin import NUM_MOVES

TIE = 1e-3  # actions within this of the best q are all optimal (ties are common in the dark)


class DataError(ValueError):
    """A seed outside its range, or a scenario the lights-known generalist cannot take."""


@dataclasses.dataclass(frozen=True)
class Sample:
    """One scenario: ``grid`` (R, C, 7) float32 as ``jax_env`` observes it (robot channel 0),
    ``optimal`` (R, C, 4) bool value iteration's optimal moves, ``weight`` (R, C) float32: 1 on
    cells the imitation loss reads (free, not goal, the goal reachable undetected)."""

    seed: int
    name: str
    grid: np.ndarray
    optimal: np.ndarray
    weight: np.ndarray
    optimal_return: float


def seeds_of(range_name: str, count: int, offset: int = 0) -> list[int]:
    """``count`` seeds from the start of a ``SEED_RANGES`` range (after ``offset``)."""
    if range_name not in SEED_RANGES:
        raise DataError(
            f'seed range: expected one of {", ".join(SEED_RANGES)}, got {range_name!r}'
        )
    low, high = SEED_RANGES[range_name]
    seeds = list(range(low + offset, low + offset + count))
    if high is not None and seeds and seeds[-1] > high:
        raise DataError(f'{range_name}: {count} seeds from offset {offset} pass its end {high}')
    return seeds


def scenario_of(seed: int, options: Options, directory: Path):
    """The generated scenario of ``seed`` written under ``directory`` and loaded back."""
    return load_scenario(generate(seed, options).write(directory))


def sample_of(seed: int, scenario) -> Sample:
    """The grid and value iteration's optimal moves of one scenario (static lights, no
    exposure: one layer, four moves)."""
    arrays = TaskArrays(scenario)
    model = arrays.model
    if model.layers != 1 or model.num_actions != NUM_MOVES:
        raise DataError(
            f'scenario {scenario.name!r}: the lights-known generalist takes static lights '
            f'without exposure (1 layer, 4 moves), this one has {model.layers} layers and '
            f'{model.num_actions} actions'
        )
    tables = arrays.tables()
    grid = grid_of(tables)
    optimum = value_iteration(model)
    q = optimum.q[: len(model.nodes)]
    best = q.max(axis=1, keepdims=True)
    rows, cols = arrays.sensing.grid_row, arrays.sensing.grid_col
    optimal = np.zeros((*tables.free.shape, NUM_MOVES), bool)
    optimal[rows, cols] = q >= best - TIE
    weight = np.zeros(tables.free.shape, np.float32)
    reachable = (optimum.values[: len(model.nodes)] > 0) & ~model.goal[: len(model.nodes)]
    weight[rows, cols] = reachable
    return Sample(seed, scenario.name, grid, optimal, weight, optimum.optimal_return)


def grid_of(tables, layer: int = 0, light=None, moves=None) -> np.ndarray:
    """(R, C, 7) the grid observation without the robot (``jax_env.observe``;
    ``stealth_core.grid_observation``'s, what the environment node sends): the light of
    ``layer`` (bin and heading), or the given ``light`` (R, C) and ``moves`` (2, R, C), a
    sensed belief; age 0."""
    if light is None:
        light, moves = tables.node_light[layer], tables.move_light[layer]
    return stack(tables.free, tables.goal_cells, light, moves)


def load_samples(seeds, options: Options, directory: Path, log=None) -> list[Sample]:
    """The samples of ``seeds`` (a seed the generator cannot prove is skipped, and said)."""
    samples = []
    for seed in seeds:
        try:
            samples.append(sample_of(seed, scenario_of(seed, options, directory)))
        except GenerationError as error:
            if log:
                log(f'seed {seed}: skipped ({error})')
    return samples


def batch(samples, dims: tuple[int, int] | None = None):
    """(grid (B, R, C, 7), optimal (B, R, C, 4), weight (B, R, C)) padded up and right to
    ``dims`` (default: the largest), walls there as ``env_tables`` pads."""
    rows = max(s.grid.shape[0] for s in samples) if dims is None else dims[0]
    cols = max(s.grid.shape[1] for s in samples) if dims is None else dims[1]
    grid = np.zeros((len(samples), rows, cols, len(CHANNELS)), np.float32)
    grid[..., 3:6] = -2.0  # obs_layout: no node, no move
    optimal = np.zeros((len(samples), rows, cols, NUM_MOVES), bool)
    weight = np.zeros((len(samples), rows, cols), np.float32)
    for k, s in enumerate(samples):
        r, c = s.grid.shape[:2]
        grid[k, :r, :c], optimal[k, :r, :c], weight[k, :r, :c] = s.grid, s.optimal, s.weight
    return grid, optimal, weight
