"""The generalist as the agent node's policy plugin: ``setup.py`` registers
``generalist = stealth_learn.ros_policy:load`` in the entry-point group
``stealth_agent.policies`` (the protocol: ``stealth_agent.policy_plugins``), so the agent node
runs it with ``agent: generalist`` without importing this package.

With static lights the value map depends only on the grid's static channels (every channel but
the robot's), so the policy plans once per distinct grid (``generalist.PlanCache``: every
cell's move from ``GeneralistPolicy.cell_logits``, the same as ``act`` at each cell: tested)
and each decision is a lookup at the robot's cell.

On the lights-sensed track (layout ``stealth-grid-v1/sensed/RxC``: the light last sensed, -1
never) the same full-track weights read the belief grid (``belief.believed_grid``: the
benchmark's ``GeneralistAgent`` rule, one function for both), planned once per belief the
environment sends (it sends one whenever what was sensed changes).

Time-aware weights (``generalist-moving.npz``: layout ``stealth-phased-v1/full/8phases-1perstep``)
read the phased grid the environment sends once where lights move (``stealth_core.
grid_observation.FullTrackGrid.phased``, the grid ``GeneralistAgent`` reads in-process): one
plan of every (layer, cell), the decision at the robot's (layer, cell), the wait among the
actions. On the lights-sensed track they read the phased grid of what was sensed at each layer
(layout ``stealth-phased-v1/sensed/8phases-1perstep/RxC``, sent before every state) as
``GeneralistAgent`` does: believed with ``belief.believed_phased`` (a layer never sensed reads
the brightest known at the others, else dark), the plan cached per distinct belief. The two
phased grids tell themselves apart: the sensed one has light never sensed (-1), the
lights-known one none (a sensed grid with nothing unknown left is its own belief). Weights of
another kind or cycle than the grid are refused naming both layouts (static weights and a
phased grid, time-aware ones and the static sensed belief included).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
from stealth_core.grid_observation import PHASED_CHANNELS
from stealth_core.scenario import load_scenario

from stealth_learn import policy_file
from stealth_learn.belief import UNKNOWN, believed_grid, believed_phased
from stealth_learn.generalist import DEFAULT_POLICY, GeneralistPolicy, PlanCache, robot_cell
from stealth_learn.obs_layout import check_layout

KEEP_PLANS = 8  # distinct grids kept (one per building, or the latest beliefs: sensed)
LIGHT = PHASED_CHANNELS.index('light')  # then the moves, the age (0 as sent) and the steps


class CachedGeneralist:
    """``policy(grid) -> action`` over GridObservation grids, the plan cached per grid."""

    def __init__(self, policy: GeneralistPolicy, path: Path):
        self.policy = policy
        self.path = path
        self.layout = policy.layout  # the full track's grid, or a time-aware network's phased
        model = policy.model
        # either network also reads the sensed track's grid: the belief, or the phased one
        architecture = policy.header['architecture'] if model.phased else None
        self.reads = (self.layout, policy_file.policy_layout('sensed', architecture))
        self.advance = model.advance
        uncertain = functools.partial(believed_grid, uncertain=bool(model.uncertain))
        prepare = self._believed_phased if model.phased else uncertain
        self.plans = PlanCache(policy, keep=KEEP_PLANS, prepare=prepare)

    def _believed_phased(self, grid: np.ndarray) -> np.ndarray:
        """A phased sensed grid (light never sensed, -1, in a light, move or step channel)
        believed as ``GeneralistAgent`` believes it (unknown dark); the lights-known phased grid
        as it is."""
        if (grid[..., LIGHT:] == UNKNOWN).any():
            return believed_phased(grid, self.advance, 0.0)
        return grid

    def check(self, layout: str) -> None:
        """ValueError (obs_layout.LayoutError), one line naming both, unless this policy reads
        the environment's layout (any grid size): the full track's, or the sensed track's
        belief, for the static network; its phased grid (phase layers and step), lights known
        or sensed, for the time-aware one."""
        env_layout = policy_file.without_size(layout)
        if env_layout not in self.reads:
            check_layout(self.layout, env_layout, str(self.path))

    def check_scenario(self, path: str) -> None:
        """ValueError, one line naming the weights and the scenario at ``path``, unless the
        network can play it (``GeneralistPolicy.check_scenario``: static weights static
        lights, time-aware ones moving lights of their cycle); `stealth rollout --learner` asks
        before anything starts."""
        self.policy.check_scenario(load_scenario(path))

    def plan(self, grid: np.ndarray) -> np.ndarray:
        """(R, C) int8: the move at every cell of ``grid`` (its robot channel ignored; light
        never sensed, -1, believed: ``belief.believed_grid``, the identity on a full grid);
        (L, R, C) the action at every layer and cell of a phased grid (sensed: believed with
        ``belief.believed_phased``). ValueError, one line, for
        a grid of another shape than the network reads (the layout's layers, the channels)."""
        expected = self.policy.model.grid_shape(*grid.shape[-3:-1])
        if grid.shape != expected:
            raise ValueError(
                f'{self.path}: a grid of shape {grid.shape}, expected {expected} for the '
                f"policy's layout {self.layout!r} (layers, rows, cols, channels)"
            )
        return self.plans.moves(grid)

    def __call__(self, grid: np.ndarray) -> int:
        """The action at the robot's cell (the robot channel's maximum; its layer and cell on a
        phased grid)."""
        return int(self.plan(grid)[robot_cell(grid)])


def load(path: str = '') -> CachedGeneralist:
    """The plugin's ``load``: the weights at ``path`` ('' the shipped ones), static or
    time-aware; a missing, corrupt or other-track file refused in one line naming the path
    (``policy_file.load``)."""
    path = Path(path) if path else DEFAULT_POLICY
    return CachedGeneralist(GeneralistPolicy.load(path, None), path)
