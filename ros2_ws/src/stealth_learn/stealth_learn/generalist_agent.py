"""The lights-known generalist as an agent of the Gym env (``stealth_core.gym_env.StealthNavEnv``)
on either track: every decision comes from the trained parameters (the value map of the grid,
read at the robot's cell); no planner runs.

    policy = load_policy(path)                       # default: the shipped generalist-full.npz
    agent = GeneralistAgent(policy, env)             # env: a StealthNavEnv, track full or sensed
    action = agent.act(observation)                  # 0-3 the moves, 4 the wait (time-aware)

The grid is ``generalist_data.grid_of`` (the channels the network trained on: free, goal, the
light on each node and along each move; robot and age 0, the decision being read at the robot's
cell), with the light of what the agent knows:

- Track 'full': the lights known, as they stand (the layer of the robot's place: its heading
  where the scenario weighs exposure), one map per layer.
- Track 'sensed': the Gym env's sensed observation, what was sensed so far (its last value),
  believed as ``belief.believed`` (the agent node's plugin does the same): a node never sensed
  (-1) enters as ``unknown``: 'dark' (0: the optimistic rule of ``replan (unknown dark)``) or
  'lit' (the detection threshold where a lamp could reach it, ``replanning.lamp_reach``, as
  ``replan (unknown lit)``), a move never sensed as the larger of its two ends. The value map
  is recomputed whenever the sensed light changes: the network replanning on its belief.

Moving lights: a time-aware network (``vin.Vin`` with phase layers) reads a phased grid and
decides at the robot's layer and cell, the wait among its actions:

- track 'full': the phased grid of the lights (``generalist_data.phased_grid``: every layer's
  lights and each step's light, one value map a run);
- track 'sensed': the phased belief (``belief.believed_phased``) of what the robot sensed at
  each phase layer (the env's ``sensor.phased``, ``stealth_core.sensing.PhasedMemory``: the
  robot's own memory, as ``env.node`` is its own place), unknown as ``unknown`` says; the
  value map recomputed whenever that memory changes.

A static network given moving lights, or a time-aware one given static lights or another cycle,
is refused (``GeneralistPolicy.check_scenario``, one line naming the weights and the scenario).

The cycle rule (``brightest``): a static network given moving lights reads the cycle's
brightest light field instead (on each node and move, the most light over the cycle's phase
layers) and never waits: the naive stand-in for time a time-aware network must beat.

The policy file is the full track's (layout ``stealth-grid-v1/full``): on the sensed track the
same network reads the belief grid, so no other file is needed (nor accepted).
"""

from __future__ import annotations

import numpy as np
from stealth_core.grid_observation import AGE, FullTrackGrid
from stealth_core.replanning import lamp_reach

from stealth_learn import policy_file
from stealth_learn.belief import UNKNOWN, believed, believed_phased
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import DEFAULT_POLICY, GeneralistPolicy, PlanCache
from stealth_learn.generalist_data import grid_of, phased_grid

UNKNOWN_RULES = ('dark', 'lit')
_KEPT = 64  # plans kept per agent (the layers of exposure's headings; the sensed track's latest)


def load_policy(path=None, iterations: int | None = None) -> GeneralistPolicy:
    """The lights-known generalist of ``path`` (default: the shipped weights), static or
    time-aware (the scenario's cycle checked when an agent is made), its Bellman backups at
    decision time at least ``iterations`` (default: the file's), then on to the values' fixed
    point (``vin.Vin.q_and_backups``). PolicyFileError or LayoutError, one line naming the
    path."""
    path = DEFAULT_POLICY if path is None else path
    policy = GeneralistPolicy.load(path, None)
    if iterations is None:
        return policy
    if not 1 <= iterations <= policy_file.MAX_ITERATIONS:
        raise ValueError(
            f"iterations: expected 1..{policy_file.MAX_ITERATIONS} (the weights file's range), "
            f'got {iterations}'
        )
    architecture = {**policy.header['architecture'], 'iterations': int(iterations)}
    params = policy.variables['params']
    header = {**policy.header, 'architecture': architecture}
    return GeneralistPolicy(params, architecture, header, source=policy.source)


class GeneralistAgent:
    """``act(observation) -> action`` on ``env`` (module docstring). ``env`` is read for its
    robot's place (``env.node``); its scenario and goal give the floor plan's grid.
    ``horizon``: at most max(iterations, horizon) backups a plan (``vin.Vin.q_and_backups``;
    None: to the fixed point), for weights whose reward pays for a cycle (the untrained twin's),
    whose values never settle."""

    def __init__(
        self,
        policy: GeneralistPolicy,
        env,
        unknown: str = 'dark',
        brightest: bool = False,
        horizon: int | None = None,
    ):
        if unknown not in UNKNOWN_RULES:
            raise ValueError(
                f'unknown: expected one of {", ".join(UNKNOWN_RULES)}, got {unknown!r}'
            )
        self.phased = policy.model.phased
        if brightest and (self.phased or env.track != 'full'):
            raise ValueError(
                f'{policy.source}: the cycle rule is a static network on the lights known '
                f"(track 'full'), not a time-aware one or track {env.track!r}"
            )
        self.brightest = brightest
        if not brightest:
            policy.check_scenario(env.scenario, env.model)
        self.policy, self.env, self.unknown = policy, env, unknown
        arrays = TaskArrays(env.scenario, model=env.model)
        self.tables = arrays.tables()
        sensing = arrays.sensing
        self._phased_grid = None
        if self.phased and env.track == 'full':
            self._phased_grid = phased_grid(arrays)
        elif self.phased:
            self._sensed = FullTrackGrid(env.model, sensing, track='sensed')
            self._advance = env.model.task.timing.bins_per_step
        self.nodes = sensing.n
        self.row, self.col = sensing.grid_row, sensing.grid_col
        self.assumed = np.zeros(self.tables.free.shape, np.float32)
        if env.track == 'sensed' and unknown == 'lit':
            reach = lamp_reach(env.model)
            threshold = env.scenario.detection_threshold
            self.assumed[self.row, self.col] = np.where(reach, threshold, 0.0)
        self.plans = PlanCache(policy, keep=_KEPT, horizon=horizon)

    def grid(self, observation) -> np.ndarray:
        """(R, C, 7) the grid the network reads for this observation (module docstring); the
        phased grid (L, R, C, 12) of a time-aware network."""
        if self._phased_grid is not None:
            return self._phased_grid
        if self.phased:
            sensed = self._sensed.phased_sensed(self.env.sensor.phased)
            return believed_phased(sensed, self._advance, self.assumed)
        if self.brightest:
            tables = self.tables
            return grid_of(tables, 0, tables.node_light.max(0), tables.move_light.max(0))
        if self.env.track == 'full':
            return grid_of(self.tables, int(self.env.node) // self.nodes)
        light, moves = believed(observation['light'], observation['moves'], self.assumed)
        grid = grid_of(self.tables, 0, light, moves)
        if self.policy.model.uncertain:  # trained for this track: it reads what was never sensed
            grid[..., AGE] = np.asarray(observation['light']) == UNKNOWN
        return grid

    def act(self, observation) -> int:
        """The action with the highest logit at the robot's cell (and layer: time-aware; a
        static network never waits or turns)."""
        moves = self.plans.moves(self.grid(observation))
        layer, node = divmod(int(self.env.node), self.nodes)
        cell = (self.row[node], self.col[node])
        return int(moves[(layer, *cell) if self.phased else cell])

    @property
    def value_maps(self) -> int:
        """Value maps computed (each a full pass of the network)."""
        return self.plans.computed
