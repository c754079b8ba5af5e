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
"""

from __future__ import annotations

import numpy as np
from stealth_core.grid_observation import LIGHT, MOVE_RIGHT, MOVE_UP

UNKNOWN = -1.0  # never sensed (the Gym env's sensed observation, GridObservation's sensed layout)


def believed(light, moves, assumed=0.0) -> tuple[np.ndarray, np.ndarray]:
    """((R, C) node light, (2, R, C) move light, up and right) with every unknown (-1) replaced
    (module docstring); ``assumed``: a node's assumed light, a scalar or (R, C)."""
    light = np.asarray(light, np.float32)
    moves = np.asarray(moves, np.float32)
    light = np.where(light == UNKNOWN, np.asarray(assumed, np.float32), light)
    ends = np.maximum(light, _shifted(light))  # a move's estimate: the larger end's
    return light, np.where(moves == UNKNOWN, ends, moves)


def believed_grid(grid) -> np.ndarray:
    """A (R, C, 7) grid (``stealth_core.grid_observation``) with its light channels believed
    (``believed``, unknown nodes dark); a new array, the other channels as they are."""
    grid = np.array(grid, dtype=np.float32)
    light, moves = believed(grid[..., LIGHT], np.moveaxis(grid[..., [MOVE_UP, MOVE_RIGHT]], -1, 0))
    grid[..., LIGHT] = light
    grid[..., MOVE_UP], grid[..., MOVE_RIGHT] = moves
    return grid


def _shifted(light: np.ndarray) -> np.ndarray:
    """(2, R, C): the node a move up ([0]) and right ([1]) leads to, its light (-2 beyond)."""
    up = np.full_like(light, -2.0)
    right = np.full_like(light, -2.0)
    up[:-1] = light[1:]
    right[:, :-1] = light[:, 1:]
    return np.stack([up, right])
