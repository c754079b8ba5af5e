"""A scenario's task as padded tables: everything the JAX environment's step reads, computed
once with the numpy core (plain numpy, no jax), so the step itself is a few gathers.

The tables come from ``stealth_core.gym_env.lattice_model`` (``LatticeModel``: the exact
MDP the Gymnasium environment steps through, every step judged by ``StealthTask``'s light model,
occlusion and step sampling) and ``stealth_core.sensing.Sensing`` (what is in sight from each
node), so the JAX environment inherits their rules rather than copying them:

- **Places** are laid on a padded grid: place ``layer * rows * cols + row * cols + col`` is the
  lattice node ``[row, col] = [j - j_min, i - i_min]`` (row 0 the southernmost, the Gym sensed
  observation's layout) at ``layer`` = heading * cycle_bins + bin (the lattice model's layers).
  A smaller scenario is padded with walls (cells with no node) up and right to the batch's
  common ``Dims``, and with unused layers, so scenarios of different sizes stack and vmap.
- **Rewards and outcomes** of every (place, action) are computed here in float64, by
  ``stealth_core.reward``'s own functions on the distances ``StealthTask.judge`` computes
  (``math.hypot``), then stored as float32: the JAX step returns exactly float32 of the Gym
  env's reward. Detection: the probability of each step (1 or 0 in 'threshold' mode, so a
  uniform draw in [0, 1) decides exactly; ``reward.detection_probability`` in 'probabilistic'
  mode).
- **Actions** are padded to the batch's count: an action beyond a scenario's ``num_actions``
  stays in place as a blocked move does (it waits where lights move); ``action_mask`` says which
  are the scenario's own. Slip picks one of ``planners.PERPENDICULAR``'s two moves.
- **Sensing** (track 'sensed'): for each node, the nodes and moves in sight (``Sensing.visible``)
  as a bit mask over the whole grid ([0] nodes, [1] moves up, [2] moves right), packed with
  ``np.packbits``: ``R * C * 3 * R * C / 8`` bytes (0.96 MB for map1's 40 x 40 lattice), so the
  step's memory update is one elementwise pass, which vmaps without gathers or scatters (a mask
  over the sensing window around the robot made a smaller table (0.65 MB) but a window slice
  per environment, which vmap makes a gather and a scatter: about 4x slower). A grid smaller
  than the sensing window (``2 * window + 1`` nodes a side, ``window`` = sensing range / step
  distance, rounded up) is still padded to it on track 'sensed', so layout ids stay those of
  the window mask's tables. Tracing every node costs about 10 ms a node, so only the sensed
  track does it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from stealth_core.grid_observation import light_grids
from stealth_core.gym_env import TRACKS, lattice_model
from stealth_core.lattice_model import PERPENDICULAR
from stealth_core.reward import detection_probability
from stealth_core.scenario import Scenario
from stealth_core.sensing import NO_PLACE, UNKNOWN, Sensing
from stealth_core.task import WAIT

NO_ACTION = -1  # PERPENDICULAR's padding: no sideways move


class TableError(ValueError):
    """A scenario that does not fit the asked dimensions, or a bad argument."""


@dataclasses.dataclass(frozen=True)
class Dims:
    """The padded sizes a batch of scenarios shares: lattice rows and cols, layers (bins x
    headings), actions and the sensing window's half-width (in nodes)."""

    rows: int
    cols: int
    layers: int
    actions: int
    window: int

    @property
    def cells(self) -> int:
        return self.rows * self.cols

    @property
    def places(self) -> int:
        return self.layers * self.cells

    @property
    def side(self) -> int:
        """The sensing window's side (nodes)."""
        return 2 * self.window + 1

    def covers(self, other: Dims) -> bool:
        return all(
            getattr(self, f.name) >= getattr(other, f.name) for f in dataclasses.fields(self)
        )

    @staticmethod
    def union(dims) -> Dims:
        """The least Dims covering all of ``dims``."""
        dims = list(dims)
        return Dims(*(max(getattr(d, f.name) for d in dims) for f in dataclasses.fields(Dims)))


@dataclasses.dataclass(frozen=True)
class Tables:
    """One scenario's padded tables (numpy); ``jax_env.EnvParams`` holds them as jax arrays.
    Shapes: P places, A actions, R x C grid, L layers."""

    successors: np.ndarray  # (P, A) int32: the place a step leads to
    step_visibility: np.ndarray  # (P, A) float32: the light the step is judged on
    detect_p: np.ndarray  # (P, A) float32: probability the step is detected
    free_reward: np.ndarray  # (P, A) float32: its reward when undetected (goal or step)
    lit: np.ndarray  # (P, A) bool: its light reaches the detection threshold
    caught_reward: np.ndarray  # (P,) float32: the reward for being detected arriving there
    goal: np.ndarray  # (P,) bool: within the goal's radius
    position: np.ndarray  # (P, 4) float32: x, y (state grid, m), phase, heading (0 if none)
    node_light: np.ndarray  # (L, R, C) float32: the light on each node; -2 no node
    move_light: np.ndarray  # (L, 2, R, C) float32: up [0] and right [1] moves; -2 none
    free: np.ndarray  # (R, C) bool: a valid lattice node
    goal_cells: np.ndarray  # (R, C) bool
    sense_bits: np.ndarray  # (R * C, bytes) uint8: packed (3, R, C) masks; (R * C, 0) on 'full'
    perpendicular: np.ndarray  # (A, 2) int32: the slip's sideways moves, -1 none
    action_mask: np.ndarray  # (A,) bool: the scenario's own actions
    start: int
    start_lit: bool
    step_limit: int
    slip: float
    goal_xy: tuple[float, float]
    state_length: int  # the Gym env's full-track state length (2, 3 or 4)
    has_phase: bool
    has_heading: bool
    shape: tuple[int, int]  # the scenario's own (rows, cols)
    title: str


class TaskArrays:
    """One scenario and goal on its lattice model, before padding (``dims`` its own sizes)."""

    def __init__(
        self, scenario: str | Scenario, goal: str | None = None, track: str = 'full', model=None
    ):
        """``model``: the scenario and goal's lattice model when the caller has it (a Gym env's
        ``model``), instead of building it again."""
        if track not in TRACKS:
            raise TableError(f'track: expected one of {", ".join(TRACKS)}, got {track!r}')
        self.track = track
        self.model = lattice_model(scenario, goal) if model is None else model
        self.task = self.model.task
        self.sensing = Sensing(self.model)
        rows, cols = self.sensing.shape
        scenario = self.task.scenario
        window = math.ceil(self.sensing.range / scenario.step_distance - 1e-9)
        if track == 'sensed':  # padded to the window (see "Sensing")
            rows, cols = max(rows, 2 * window + 1), max(cols, 2 * window + 1)
        self.dims = Dims(rows, cols, self.model.layers, self.model.num_actions, window)

    def tables(self, dims: Dims | None = None, slip: float = 0.0) -> Tables:
        """The tables padded to ``dims`` (default: the scenario's own)."""
        dims = self.dims if dims is None else dims
        if not dims.covers(self.dims):
            raise TableError(
                f'scenario {self.task.scenario.name!r} needs {self.dims}, more than the batch '
                f'dims {dims}: build the batch dims with Dims.union'
            )
        if not 0.0 <= slip <= 1.0:
            raise TableError(f'slip: expected a probability in [0, 1], got {slip!r}')
        return _pad(self, dims, float(slip))


def _pad(arrays: TaskArrays, dims: Dims, slip: float) -> Tables:
    model, task, sensing = arrays.model, arrays.task, arrays.sensing
    scenario = task.scenario
    n, own_actions = len(model.nodes), model.num_actions
    cell = sensing.grid_row * dims.cols + sensing.grid_col  # (n,) each node's cell
    place_of = (np.arange(model.size) // n) * dims.cells + cell[
        model.node_of(np.arange(model.size))
    ]
    # The model's steps, the padded actions staying in place (waiting where lights move).
    successors = np.empty((model.size, dims.actions), dtype=np.int64)
    visibility = np.empty((model.size, dims.actions))
    successors[:, :own_actions] = model.successors
    visibility[:, :own_actions] = model.step_visibility
    if own_actions > WAIT and scenario.has_moving_lights:
        successors[:, own_actions:] = model.successors[:, WAIT : WAIT + 1]
        visibility[:, own_actions:] = model.step_visibility[:, WAIT : WAIT + 1]
    else:
        successors[:, own_actions:] = np.arange(model.size)[:, None]
        visibility[:, own_actions:] = model.visibility[:, None]
    judged = _judgements(task, model, successors, visibility)
    places, actions = dims.places, dims.actions
    out = {
        'successors': np.repeat(np.arange(places, dtype=np.int32)[:, None], actions, axis=1),
        'step_visibility': np.zeros((places, actions), np.float32),
        'detect_p': np.zeros((places, actions), np.float32),
        'free_reward': np.zeros((places, actions), np.float32),
        'lit': np.zeros((places, actions), bool),
    }
    out['successors'][place_of] = place_of[successors]
    out['step_visibility'][place_of] = visibility
    for name in ('detect_p', 'free_reward', 'lit'):
        out[name][place_of] = judged[name]
    caught_reward = np.zeros(places, np.float32)
    caught_reward[place_of] = judged['caught_reward']
    goal = np.zeros(places, bool)
    goal[place_of] = judged['goal']
    position = np.zeros((places, 4), np.float32)
    states = model.states
    position[place_of, :2] = states[:, :2]
    if task.timing is not None:
        position[place_of, 2] = states[:, 2]
    if task.footprint is not None:
        position[place_of, 3] = states[:, -1]
    node_light, move_light = _light_grids(arrays, dims)
    free = np.zeros((dims.rows, dims.cols), bool)
    free[sensing.grid_row, sensing.grid_col] = True
    goal_cells = np.zeros((dims.rows, dims.cols), bool)
    goal_cells[sensing.grid_row, sensing.grid_col] = model.goal[:n]
    perpendicular = np.full((actions, 2), NO_ACTION, np.int32)
    for action in range(own_actions):
        if PERPENDICULAR[action]:
            perpendicular[action] = PERPENDICULAR[action]
    x, y = model.points[model.start]
    start_visibility = float(model.visibility[model.start])
    return Tables(
        **out,
        caught_reward=caught_reward,
        goal=goal,
        position=position,
        node_light=node_light,
        move_light=move_light,
        free=free,
        goal_cells=goal_cells,
        sense_bits=_sense_bits(arrays, dims) if arrays.track == 'sensed' else _no_bits(dims),
        perpendicular=perpendicular,
        action_mask=np.arange(actions) < own_actions,
        start=int(place_of[model.start]),
        start_lit=start_visibility >= scenario.detection_threshold,
        step_limit=int(task.step_limit),
        slip=slip,
        goal_xy=(float(task.goal.x), float(task.goal.y)),
        state_length=len(task.state_features),
        has_phase=task.timing is not None,
        has_heading=task.footprint is not None,
        shape=sensing.shape,
        title=task.title,
    )


def _judgements(task, model, successors, visibility) -> dict:
    """Every step's outcome and rewards in float64, as ``StealthTask.judge`` computes them (its
    distance is ``math.hypot`` of the arrival's point; ``reward``'s formulas, term for term)."""
    scenario, weights, radius = task.scenario, task.scenario.rewards, task.goal.radius
    gx, gy = task.goal.x, task.goal.y
    distance = np.array([math.hypot(x - gx, y - gy) for x, y in model.points.tolist()])
    d = distance[successors]
    threshold = scenario.detection_threshold
    if scenario.detection_mode == 'threshold':
        detect_p = (visibility >= threshold).astype(np.float64)
    else:
        detect_p = detection_probability(visibility, threshold)
    goal = distance <= radius
    success = weights.goal_reward + weights.goal_distance_weight * (radius - d)
    step = -(
        weights.visibility_weight * visibility + weights.distance_weight * d + weights.time_cost
    )
    caught = -(weights.detection_penalty + weights.detection_distance_weight * distance)
    return {
        'detect_p': detect_p.astype(np.float32),
        'free_reward': np.where(goal[successors], success, step).astype(np.float32),
        'lit': visibility >= threshold,
        'caught_reward': caught.astype(np.float32),
        'goal': goal,
    }


def _light_grids(arrays: TaskArrays, dims: Dims) -> tuple[np.ndarray, np.ndarray]:
    """(L, R, C) node light and (L, 2, R, C) move light of every layer (the truth the robot
    senses: ``Sensing.truth``), -2 where no node or move is."""
    model, sensing = arrays.model, arrays.sensing
    rows, cols = sensing.shape
    node_light = np.full((dims.layers, dims.rows, dims.cols), NO_PLACE, np.float32)
    move_light = np.full((dims.layers, 2, *node_light.shape[1:]), NO_PLACE, np.float32)
    for layer in range(model.layers):
        node, moves = light_grids(sensing, layer * sensing.n)
        node_light[layer, :rows, :cols], move_light[layer, :, :rows, :cols] = node, moves
    return node_light, move_light


def unknown_grids(tables: Tables) -> tuple[np.ndarray, np.ndarray]:
    """The sensed memory at an episode's start: -1 (never sensed) on every node and move, -2
    where none is."""
    return (
        np.where(tables.node_light[0] != NO_PLACE, UNKNOWN, NO_PLACE).astype(np.float32),
        np.where(tables.move_light[0] != NO_PLACE, UNKNOWN, NO_PLACE).astype(np.float32),
    )


def _sense_bits(arrays: TaskArrays, dims: Dims) -> np.ndarray:
    """(R * C, bytes) uint8: per cell, the (3, R, C) mask of what is in sight from its node over
    the whole grid ([0] nodes, [1] moves up, [2] moves right), bit-packed."""
    sensing = arrays.sensing
    masks = np.zeros((dims.cells, 3, dims.rows, dims.cols), bool)
    rows, cols = sensing.grid_row, sensing.grid_col
    move_rows, move_cols = rows[sensing.move_from], cols[sensing.move_from]
    channel = 1 + (sensing.move_direction == 3).astype(np.int64)  # 3: RIGHT
    for node in range(sensing.n):
        nodes, moves = sensing.visible(node)
        here = rows[node] * dims.cols + cols[node]
        masks[here, 0, rows[nodes], cols[nodes]] = True
        masks[here, channel[moves], move_rows[moves], move_cols[moves]] = True
    return np.packbits(masks.reshape(dims.cells, -1), axis=1)


def _no_bits(dims: Dims) -> np.ndarray:
    return np.zeros((dims.cells, 0), np.uint8)
