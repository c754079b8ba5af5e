"""The generalist's belief on the lights-sensed track: what it assumes of light never sensed,
in one place for the benchmark's agent (``generalist_agent.GeneralistAgent``, from the Gym env's
sensed observation) and the agent node's plugin (``ros_policy``, from the environment node's
sensed GridObservation). Plain numpy.

The sensed light is the last value sensed at each node and along each move, -1 never sensed
(``UNKNOWN``) and -2 no node or no move (``sensing.NO_PLACE``). The network, trained on the
lights-known grid, reads the belief: a node never sensed as ``assumed`` (0, dark: the
optimistic rule of ``replan (unknown dark)``; or any per-node estimate), a move never sensed as
the larger of its two ends' (believed) light. On a lights-known grid (no -1) it is the grid
itself.

With moving lights the time-aware network reads the phased belief (``believed_phased``): the
phased grid of what was sensed at each phase layer (``FullTrackGrid.phased_sensed``). A node,
move or wait never sensed at a layer but sensed at others reads the most light sensed there (a
beam seen once may be back then); never sensed at any, each layer is believed as above, and a
wait as the more light of the node at this layer and at the layer it arrives at. The four step
channels are the believed moves' light. The age channel is 1 on a node never sensed at that
layer (what a network trained for the sensed track reads: ``vin.Vin``'s ``uncertain``), else 0.
"""

from __future__ import annotations

import numpy as np
from stealth_core.grid_observation import (
    AGE,
    CHANNELS,
    LIGHT,
    MOVE_RIGHT,
    MOVE_UP,
    PHASED_CHANNELS,
    step_grids,
)

WAIT_CHANNEL = PHASED_CHANNELS.index('step_wait')
UNKNOWN = -1.0  # never sensed (the Gym env's sensed observation, GridObservation's sensed layout)


def believed(light, moves, assumed=0.0) -> tuple[np.ndarray, np.ndarray]:
    """((R, C) node light, (2, R, C) move light, up and right) with every unknown (-1) replaced
    (module docstring); ``assumed``: a node's assumed light, a scalar or (R, C)."""
    light = np.asarray(light, np.float32)
    moves = np.asarray(moves, np.float32)
    light = np.where(light == UNKNOWN, np.asarray(assumed, np.float32), light)
    ends = np.maximum(light, _shifted(light))  # a move's estimate: the larger end's
    return light, np.where(moves == UNKNOWN, ends, moves)


def believed_grid(grid, assumed=0.0, uncertain: bool = False) -> np.ndarray:
    """A (R, C, 7) grid (``stealth_core.grid_observation``) with its light channels believed
    (``believed``; unknown nodes ``assumed``, default dark); a new array, the other channels as
    they are, except with ``uncertain`` (a network reading the never-sensed input): the age
    channel then 1 on a node never sensed, else 0 (``ppo.believe`` is the JAX twin)."""
    grid = np.array(grid, dtype=np.float32)
    if uncertain:
        grid[..., AGE] = grid[..., LIGHT] == UNKNOWN
    moves = np.moveaxis(grid[..., [MOVE_UP, MOVE_RIGHT]], -1, 0)
    light, moves = believed(grid[..., LIGHT], moves, assumed)
    grid[..., LIGHT] = light
    grid[..., MOVE_UP], grid[..., MOVE_RIGHT] = moves
    return grid


def believed_phased(grid, advance: int, assumed=0.0) -> np.ndarray:
    """A phased grid (L, R, C, 12) of what was sensed with every unknown believed (module
    docstring); ``advance``: the layers a step advances; ``assumed`` as ``believed``'s. A new
    array; on a fully known grid the light, move and wait channels are as they are."""
    grid = np.array(grid, dtype=np.float32)
    grid[..., AGE] = grid[..., LIGHT] == UNKNOWN  # the never-sensed input (vin's uncertain)
    for channel in (LIGHT, MOVE_UP, MOVE_RIGHT, WAIT_CHANNEL):
        values = grid[..., channel]
        brightest = values.max(axis=0)  # over the layers: -1 never sensed at any
        values[:] = np.where(values == UNKNOWN, brightest, values)
    layers = np.stack([believed_grid(layer, assumed) for layer in grid[..., : len(CHANNELS)]])
    light = layers[..., LIGHT]
    free = grid[0, ..., 0] > 0
    steps = []
    for index, layer in enumerate(layers):
        ends = np.maximum(light[index], light[(index + advance) % len(layers)])
        wait = grid[index, ..., WAIT_CHANNEL]
        moves = np.moveaxis(layer[..., [MOVE_UP, MOVE_RIGHT]], -1, 0)
        steps.append(step_grids(moves, free, np.where(wait == UNKNOWN, ends, wait)))
    return np.concatenate([layers, np.stack(steps)], -1)


def _shifted(light: np.ndarray) -> np.ndarray:
    """(2, R, C): the node a move up ([0]) and right ([1]) leads to, its light (-2 beyond)."""
    up = np.full_like(light, -2.0)
    right = np.full_like(light, -2.0)
    up[:-1] = light[1:]
    right[:, :-1] = light[:, 1:]
    return np.stack([up, right])
