"""Baselines for the robot that does not know the lights: Dark Path replanned every step on what
has been sensed so far (the Gym env's sensed track, ``stealth_core.sensing``).

Both planners read only the observation (the remembered light of nodes and moves) and the floor
plan (the move lattice: which moves exist, where the goal is), never the model's light arrays.
Each step they plan ``planners.dark_path``'s way (cost ``step_distance + weight * light`` per
move, A* with the Manhattan heuristic, moves whose light reaches the detection threshold never
taken) from the robot's node to the goal over the nodes, with each move's light estimated:

- a move sensed: its remembered value;
- else the larger of its two ends' estimates: a node sensed, its remembered value; a node never
  sensed, 0 for ``unknown='dark'`` (optimistic), and for ``unknown='lit'`` (pessimistic) the
  detection threshold when a lamp could reach it: a wall cell bordering free space lies within
  the scenario's largest light range of the node's point (lights stand beside walls; the
  nearest such cell is in the node's line of sight, the segment to it crossing free cells
  only, so no sight test is needed), else 0. A move assumed lit this way is *not* refused (it
  is unknown, not seen lit; refusing it would leave nothing to plan through at the start): it
  costs as a move at the threshold, so the plan takes as few unknown, reachable moves as it
  can and prefers ways already sensed dark.

The first step of the plan is taken. With no plan (every way seen lit) the robot waits where
the scenario has a wait action (a moving beam may pass), else takes the existing move with the
least estimated light; it never chooses a move into a wall. Moving lights are planned as if
frozen at what was last sensed (the memory's values, whatever their age).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from stealth_core.lattice_model import LatticeModel
from stealth_core.planners import DEFAULT_DARK_PATH_WEIGHT, _cheapest_path, _moves_to_goal
from stealth_core.reward import EpisodeOutcome
from stealth_core.sensing import UP, Sensing
from stealth_core.task import WAIT

UNKNOWN_RULES = ('dark', 'lit')
_CHUNK = 256  # nodes per block of the lamp-reach distances


class SensedReplanner:
    """Dark Path on the sensed field, replanned at every ``act``; see the module docstring.

    model: the scenario's lattice model, used for its floor plan only (nodes, moves, goal).
    unknown: 'dark' (unsensed nodes assumed dark) or 'lit' (assumed lit where a lamp could
    reach them).
    """

    def __init__(
        self,
        model: LatticeModel,
        unknown: str = 'dark',
        weight: float = DEFAULT_DARK_PATH_WEIGHT,
    ):
        if unknown not in UNKNOWN_RULES:
            rules = ', '.join(UNKNOWN_RULES)
            raise ValueError(f'unknown: expected one of {rules}, got {unknown!r}')
        scenario = model.task.scenario
        self.unknown = unknown
        self.weight = float(weight)
        self.threshold = float(scenario.detection_threshold)
        self.step = float(scenario.step_distance)
        self.can_wait = model.num_actions > WAIT and model.task.action_names[WAIT] == 'wait'
        self.sensing = sensing = Sensing(model, scenario.sensing_range)
        n = sensing.n
        moves = model.successors[:n, :4] % n
        # The floor plan as one layer: nodes only, the four moves.
        self.view = dataclasses.replace(
            model,
            points=model.points[:n],
            successors=moves,
            goal=model.goal[:n],
            cycle_bins=1,
            headings=1,
        )
        self.heuristic = self.step * _moves_to_goal(self.view)
        self.move_of = np.full((n, 4), -1, dtype=np.int64)  # the undirected move of each step
        back = np.where(sensing.move_direction == UP, 1, 2)  # down, left
        self.move_of[sensing.move_from, sensing.move_direction] = np.arange(sensing.moves)
        self.move_of[sensing.move_to, back] = np.arange(sensing.moves)
        self.node_at = {
            (int(r), int(c)): k
            for k, (r, c) in enumerate(zip(sensing.grid_row, sensing.grid_col, strict=True))
        }
        self.lattice = model.task.lattice
        self.assumed = np.zeros(n)
        if unknown == 'lit':
            self.assumed = np.where(lamp_reach(model), self.threshold, 0.0)

    def node_of(self, observation) -> int:
        """The robot's node from the observation's state ([x, y, ...])."""
        x, y = (float(v) for v in observation['state'][:2])
        i, j = self.lattice.point_to_node(x, y)
        return self.node_at[(j - self.lattice.j_min, i - self.lattice.i_min)]

    def estimates(self, observation, assume: bool = True) -> np.ndarray:
        """(moves,) the estimated light of every undirected move (see the module docstring);
        without ``assume``, unsensed nodes count as dark."""
        sensing = self.sensing
        light = np.asarray(observation['light'])[sensing.grid_row, sensing.grid_col]
        nodes = np.where(light >= 0, light, self.assumed if assume else 0.0)
        channel = (sensing.move_direction != UP).astype(np.int64)
        start = sensing.move_from
        moves = np.asarray(observation['moves'])[
            channel, sensing.grid_row[start], sensing.grid_col[start]
        ]
        ends = np.maximum(nodes[sensing.move_from], nodes[sensing.move_to])
        return np.where(moves >= 0, moves, ends)

    def plan(self, observation) -> list[int] | None:
        """The Dark Path (node indices) from the robot's node to the goal on the estimates."""
        here = self.node_of(observation)
        exists = self.move_of >= 0
        value = np.where(exists, self.estimates(observation)[self.move_of], 0.0)
        seen = np.where(exists, self.estimates(observation, False)[self.move_of], 0.0)
        refused = seen >= self.threshold  # seen lit, not merely assumed
        cost = self.step + self.weight * value
        view = dataclasses.replace(self.view, start=here)
        return _cheapest_path(view, cost, exists & ~refused, self.heuristic)

    def act(self, observation) -> int:
        """The action to take: the plan's first step, or the fallback."""
        here = self.node_of(observation)
        path = self.plan(observation)
        if path is not None and len(path) > 1:
            return int(np.flatnonzero(self.view.successors[here] == path[1])[0])
        if self.can_wait:
            return WAIT
        estimate = self.estimates(observation)
        exists = np.flatnonzero(self.move_of[here] >= 0)
        return int(exists[np.argmin(estimate[self.move_of[here, exists]])])


def lamp_reach(model: LatticeModel) -> np.ndarray:
    """(nodes,) bool: nodes within the scenario's largest light range of a wall cell (blocked)
    bordering a free cell: where a wall-mounted lamp could light them."""
    scenario = model.task.scenario
    n = len(model.nodes)
    if not scenario.lights:
        return np.zeros(n, dtype=bool)
    reach = max(light.range for light in scenario.lights)
    occupancy = scenario.map
    blocked = occupancy.blocked
    free = np.pad(~blocked, 1)
    beside_free = free[:-2, 1:-1] | free[2:, 1:-1] | free[1:-1, :-2] | free[1:-1, 2:]
    rows, cols = np.nonzero(blocked & beside_free)
    resolution = occupancy.resolution
    wall_x = occupancy.origin[0] + (cols + 0.5) * resolution
    wall_y = occupancy.origin[1] + (rows + 0.5) * resolution
    points = model.points[:n]
    near = np.zeros(n, dtype=bool)
    for first in range(0, n, _CHUNK):
        block = points[first : first + _CHUNK]
        dx = block[:, None, 0] - wall_x[None, :]
        dy = block[:, None, 1] - wall_y[None, :]
        near[first : first + _CHUNK] = ((dx * dx + dy * dy) <= reach * reach).any(axis=1)
    return near


def play(env, policy, seed: int | None = None) -> dict:
    """One episode of ``policy(observation) -> action`` on a sensed-track env: EpisodeSummary's
    figures (``env.stats``) and the poses walked, as the harness's ``RunResult.final``."""
    observation, info = env.reset(seed=seed)
    while True:
        observation, _, terminated, truncated, info = env.step(policy(observation))
        if terminated or truncated:
            break
    summary = env.stats.summary(EpisodeOutcome[info['outcome']])
    return {**summary._asdict(), 'points': env.trajectory}
