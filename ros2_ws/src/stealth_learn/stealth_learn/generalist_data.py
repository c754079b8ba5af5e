"""The generalist's data: generated scenarios of one seed range, each as the grid the network
reads and value iteration's optimal moves on every cell (dense imitation targets: one scenario
teaches every valid cell at once, not one trajectory). With moving lights, the phased grid
(``stealth_core.grid_observation``'s, what the environment node sends: every phase layer's
grid and the light of each step from there) and the layered value iteration's optimal actions
(the four moves and the wait) at every cell of every layer.

Computed in numpy: ``stealth_core``'s generator, lattice model and ``value_iteration``;
``env_tables`` for the grid channels the JAX environment observes, so the network trains on
exactly what it sees when it acts. Its action numbering comes from ``vin``, so importing it
needs the learning extra (jax).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from stealth_core.grid_observation import FullTrackGrid, stack
from stealth_core.planners import value_iteration
from stealth_core.scenario import load_scenario
from stealth_core.scenario_generator import SEED_RANGES, GenerationError, Options, generate

from stealth_learn.env_tables import TaskArrays
from stealth_learn.obs_layout import CHANNELS
from stealth_learn.vin import NO_MOVE, NUM_MOVES

TIE = 1e-3  # actions within this of the best q are all optimal (ties are common in the dark)


class DataError(ValueError):
    """A seed outside its range, or a scenario the lights-known generalist cannot take."""


@dataclasses.dataclass(frozen=True)
class Sample:
    """One scenario: ``grid`` (R, C, 7) float32 as ``jax_env`` observes it (robot channel 0),
    ``optimal`` (R, C, 4) bool value iteration's optimal moves, ``weight`` (R, C) float32: 1 on
    cells the imitation loss reads (free, not goal, the goal reachable undetected). Moving
    lights: a layer axis first, ``grid`` the phased grid (L, R, C, 12) and five actions."""

    seed: int
    name: str
    grid: np.ndarray
    optimal: np.ndarray
    weight: np.ndarray
    optimal_return: float
    advance: int = 0  # moving lights: the phase layers a step advances (``Vin.advance``)


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
    """The grid and value iteration's optimal actions of one scenario: static lights without
    exposure (one layer, four moves), or moving lights without exposure (the phased grid, the
    four moves and the wait)."""
    arrays = TaskArrays(scenario)
    model = arrays.model
    moving = model.task.scenario.has_moving_lights
    actions = NUM_MOVES + int(moving)
    if model.headings != 1 or model.num_actions != actions or (model.layers != 1) != moving:
        raise DataError(
            f'scenario {scenario.name!r}: the lights-known generalist takes static or moving '
            f'lights without exposure (1 layer and 4 moves, or phase layers and 5 actions), '
            f'this one has {model.layers} layers and {model.num_actions} actions'
        )
    tables = arrays.tables()
    grid = phased_grid(arrays) if moving else grid_of(tables)[None]
    optimum = value_iteration(model)
    n, layers = len(model.nodes), model.layers
    q = optimum.q.reshape(layers, n, actions)
    best = q.max(axis=-1, keepdims=True)
    rows, cols = arrays.sensing.grid_row, arrays.sensing.grid_col
    optimal = np.zeros((layers, *tables.free.shape, actions), bool)
    optimal[:, rows, cols] = q >= best - TIE
    if moving:  # a blocked move only waits: the network masks it, the wait is its twin
        optimal &= grid[..., len(CHANNELS) :] > NO_MOVE + 0.5
    weight = np.zeros((layers, *tables.free.shape), np.float32)
    values = optimum.values.reshape(layers, n)
    weight[:, rows, cols] = (values > 0) & ~model.goal[:n]
    if not moving:
        grid, optimal, weight = grid[0], optimal[0], weight[0]
    advance = model.task.timing.bins_per_step if moving else 0
    return Sample(seed, scenario.name, grid, optimal, weight, optimum.optimal_return, advance)


def phased_grid(arrays: TaskArrays) -> np.ndarray:
    """(L, R, C, 12) the phased grid of one scenario (robot channel 0), the environment node's:
    ``stealth_core.grid_observation.FullTrackGrid.phased`` on its lattice model (each layer's
    grid, then the light each step from there is judged on, -2 where the step does not
    exist)."""
    return FullTrackGrid(arrays.model, arrays.sensing).phased()


def grid_of(tables, layer: int = 0, light=None, moves=None) -> np.ndarray:
    """(R, C, 7) the grid observation without the robot (``jax_env.observe``;
    ``stealth_core.grid_observation``'s, what the environment node sends): the light of
    ``layer`` (bin and heading), or the given ``light`` (R, C) and ``moves`` (2, R, C), a
    sensed belief; age 0."""
    if light is None:
        light, moves = tables.node_light[layer], tables.move_light[layer]
    return stack(tables.free, tables.goal_cells, light, moves)


def scenarios_of(seeds, options: Options, directory: Path, log=None) -> list:
    """[(seed, scenario)] of ``seeds`` (a seed the generator cannot prove is skipped, and
    said through ``log``)."""
    out = []
    for seed in seeds:
        try:
            out.append((seed, scenario_of(seed, options, directory)))
        except GenerationError as error:
            if log:
                log(f'seed {seed}: skipped ({error})')
    return out


def load_samples(seeds, options: Options, directory: Path, log=None) -> list[Sample]:
    """The samples of ``seeds`` (a seed the generator cannot prove is skipped, and said)."""
    return [
        sample_of(seed, scenario)
        for seed, scenario in scenarios_of(seeds, options, directory, log)
    ]


def batch(samples, dims: tuple[int, int] | None = None):
    """(grid (B, [L,] R, C, channels), optimal (B, [L,] R, C, A), weight (B, [L,] R, C)) padded
    up and right to ``dims`` (default: the largest), walls there as ``env_tables`` pads (lights
    and steps -2)."""
    rows = max(s.grid.shape[-3] for s in samples) if dims is None else dims[0]
    cols = max(s.grid.shape[-2] for s in samples) if dims is None else dims[1]
    first = samples[0]
    layers = first.grid.shape[:-3]  # () static, (L,) phased
    grid = np.zeros((len(samples), *layers, rows, cols, first.grid.shape[-1]), np.float32)
    grid[..., 3:6] = NO_MOVE  # obs_layout: no node, no move
    grid[..., len(CHANNELS) :] = NO_MOVE  # no step
    optimal = np.zeros((len(samples), *layers, rows, cols, first.optimal.shape[-1]), bool)
    weight = np.zeros((len(samples), *layers, rows, cols), np.float32)
    for k, s in enumerate(samples):
        r, c = s.grid.shape[-3:-1]
        grid[k, ..., :r, :c, :] = s.grid
        optimal[k, ..., :r, :c, :] = s.optimal
        weight[k, ..., :r, :c] = s.weight
    return grid, optimal, weight
