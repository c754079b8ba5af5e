"""The agent's core for a policy plugin (``policy_plugins``; parameter ``agent: generalist``):
greedy decisions from the policy on the environment's grid observation, no table and no
learning. Plain Python + numpy (no rclpy).

The environment sends the grid (GridObservation on ``rl_env/observation``, latched). Track
full: once, with static lights every channel but the robot's is fixed. Track sensed (layout
``stealth-grid-v1/sensed/RxC``): the belief, whenever what was sensed changes, and each state
carries the same light and moves (its tail: ``stealth_env.sensed_track``), so a state is decided
on only with the grid it matches (``serves``): a state that comes before its grid waits for it
(``AgentLoop``), as a state before any grid does. Each state's first two features are the
robot's (x, y) in the map frame (the lattice node it stands on, the full track's state); the
core sets that cell of the robot channel and asks the policy, which caches its plan per distinct
grid (planned on as the grid arrives), so a decision is a lookup.

With moving lights (track full) the grid is phased (layout ``stealth-phased-v1/...``,
GridObservation layers > 1: one grid per bin of the lights' cycle, and each step's light): the
robot is at the layer of the state's phase, its third feature (``stealth_core.task``: x, y,
phase), as the in-process agent reads its place's layer (``stealth_learn.generalist_agent``).

With moving lights on track sensed (layout ``stealth-phased-v1/sensed/...``) the environment
sends the phased grid of what was sensed before every state it wants decided, its robot channel
1 at that state's (layer, cell): the state's sensed part (the light last sensed at any layer)
does not say which phased grid it goes with, the mark does. Consecutive states differ in layer
(a step advances the phase), so a state is decided only with the grid marked at its place; an
episode's first state also only with a grid of step 0 (every episode's first grid is the same:
what the scenario's start senses at layer 0), so the last grid of the episode before never
serves it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from stealth_core.grid_cells import cell_of

from .protocol import BadInputError, ProtocolAgent
from .state_index import StateIndex

ROBOT = 1  # GridObservation.channel_names[1]
SENSED = (3, 4, 5)  # light, move_up, move_right: a sensed state's tail, in this order


@dataclasses.dataclass(frozen=True)
class ObservedGrid:
    """A GridObservation as numpy: its layout id, the (rows, cols, channels) float32 grid and
    the geometry (resolution, origin x, origin y; m, map frame)."""

    layout: str
    grid: np.ndarray  # (layers, rows, cols, channels) for a phased grid
    geometry: tuple[float, float, float]
    step: int = 0  # track sensed: the step of the state it goes with (GridObservation.step)

    @property
    def layers(self) -> int:
        """Phase layers: 1, or the phased grid's (one per bin of the lights' cycle)."""
        return self.grid.shape[0] if self.grid.ndim == 4 else 1

    @property
    def sensed(self) -> bool:
        """Whether it is the sensed track's belief (layout ``stealth-grid-v1/sensed/RxC``)."""
        return self.layout.split('/')[1:2] == ['sensed']

    @property
    def marked(self) -> bool:
        """Whether it is the phased grid of what was sensed, sent per state with the robot
        marked at that state's (layer, cell) (layout ``stealth-phased-v1/sensed/...``)."""
        return self.sensed and self.grid.ndim == 4

    def mark(self) -> tuple[int, ...] | None:
        """The (layer, row, col) the robot channel marks (None: no mark)."""
        robot = self.grid[..., ROBOT]
        index = np.unravel_index(int(np.argmax(robot)), robot.shape)
        return tuple(int(i) for i in index) if robot[index] > 0 else None

    def sensed_part(self) -> np.ndarray:
        """The light and moves as a sensed state carries them: (3 x rows x cols,) float32."""
        return np.concatenate([self.grid[..., channel].ravel() for channel in SENSED])

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of map point (x, y); BadInputError outside the grid."""
        row, col = cell_of(self.geometry, x, y)
        rows, cols = self.grid.shape[-3:-1]
        if not (0 <= row < rows and 0 <= col < cols):
            resolution, x0, y0 = self.geometry
            raise BadInputError(
                f'state ({x:g}, {y:g}) lies outside the observation grid ({rows} x {cols} '
                f'cells of {resolution:g} m from ({x0:g}, {y0:g}))'
            )
        return row, col

    def robot_at(self, vector) -> tuple[int, ...]:
        """The index of the robot's cell for a state: (row, col) of its (x, y), and on a phased
        grid (layer, row, col), the layer its phase (third feature); BadInputError for a state
        outside the grid or without a phase the grid has."""
        cell = self.cell_of(float(vector[0]), float(vector[1]))
        layers = self.layers
        if self.grid.ndim != 4:
            return cell
        phase = float(vector[2]) if len(vector) > 2 else math.nan
        if not (math.isfinite(phase) and phase == int(phase) and 0 <= phase < layers):
            raise BadInputError(
                f'state {[float(v) for v in vector]}: expected its phase (third feature) an '
                f'integer 0..{layers - 1}, the layers of the phased grid {self.layout}'
            )
        return (int(phase), *cell)


@dataclasses.dataclass
class PolicyStats:
    """What the agent's reports read of a learner, for a policy that does not learn."""

    name: str
    episodes: int = 0
    updates: int = 0
    alpha: float = 0.0
    epsilon: float = 0.0


class GridPolicyAgent(ProtocolAgent):
    """ProtocolAgent whose greedy action comes from a plugin policy on the grid observation."""

    def __init__(self, name: str, policy, index: StateIndex, rng: np.random.Generator):
        super().__init__(PolicyStats(name), index, rng, learning=False)
        self.policy = policy
        self.observed: ObservedGrid | None = None
        self._work: np.ndarray | None = None  # the grid, the robot's cell set per decision
        self._sensed: np.ndarray | None = None  # a sensed grid's light and moves (serves)
        self._mark: tuple[int, ...] | None = None  # a marked grid's robot (layer, row, col)

    @property
    def ready(self) -> bool:
        """Whether a grid arrived (a state before it must wait)."""
        return self.observed is not None

    def set_grid(self, observed: ObservedGrid) -> None:
        """A (new) grid from the environment: checked against the policy's layout (ValueError,
        one line naming both), then planned on once, so the first decision is a lookup too."""
        self.policy.check(observed.layout)
        work = np.array(observed.grid, dtype=np.float32)
        work[..., ROBOT] = 0.0
        self.policy(work)  # the plan of this grid, cached by the policy
        self.observed, self._work = observed, work
        marked = observed.marked
        self._sensed = observed.sensed_part() if observed.sensed and not marked else None
        self._mark = observed.mark() if marked else None

    def serves(self, state) -> bool:
        """Whether the grid is the one to decide on ``state`` (the full, unkeyed state): any
        state with a full-track grid; on the sensed track the state whose light and moves (its
        tail) are the grid's; with moving lights there, the state at the (layer, cell) the grid
        marks (an episode's first state: a grid of step 0)."""
        observed = self.observed
        if observed is None:
            return False
        if observed.marked:
            if not self.in_episode and observed.step != 0:
                return False
            try:
                place = observed.robot_at(np.asarray(state, dtype=np.float32))
            except BadInputError:
                return True  # deciding on it says what is wrong with the state
            return place == self._mark
        expected = self._sensed
        if expected is None:
            return True
        tail = np.asarray(state[len(state) - expected.size :], dtype=np.float32)
        return len(state) > expected.size and np.array_equal(tail, expected)

    def set_learning(self, learning: bool) -> None:
        if learning:
            raise RuntimeError(f'policy {self.learner.name} does not learn')
        super().set_learning(False)

    def _greedy(self, row: int, vector: np.ndarray) -> int:
        if self.observed is None:
            raise BadInputError('no grid observation (rl_env/observation) yet')
        robot = (*self.observed.robot_at(vector), ROBOT)
        work = self._work
        work[robot] = 1.0
        try:
            return int(self.policy(work))
        finally:
            work[robot] = 0.0
