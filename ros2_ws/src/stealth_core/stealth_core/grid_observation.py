"""The lights-known grid observation over the move lattice, built in one place: the environment
node sends it (parameter ``observation_layout: grid``, message GridObservation) and
``stealth_learn`` trains and evaluates on it (``env_tables``, ``generalist_data``), so the
generalist sees through ROS exactly what it was trained on. Plain numpy, no rclpy.

A float32 (rows, cols, 7) grid, one cell per lattice node, ``[row, col] = [j - j_min, i -
i_min]`` (row 0 the southernmost, ``sensing.Sensing``'s layout), channels ``CHANNELS``:

- free: 1 on a valid lattice node, else 0;
- robot: 1 on the robot's node (``with_robot``; 0 everywhere in ``static``);
- goal: 1 on the nodes within the goal's radius;
- light: the light on each node (``Sensing.truth``: the lights as they stand at a layer),
  -2 (``sensing.NO_PLACE``) where no node is;
- move_up, move_right: the most light along the move up / right from each node, -2 no move;
- age: steps since the light was sensed; 0 on the lights-known track.

Every channel but the robot's depends only on the scenario, the goal and the layer (bin and
heading): with static lights and no exposure, one grid serves a whole run.

On the lights-sensed track (``track: sensed``) the environment sends the belief grid instead
(``FullTrackGrid.belief``, layout ``stealth-grid-v1/sensed/RxC``): the same free and goal, light
and moves as last sensed (the Gym env's sensed observation: -1 never sensed, -2 no node or
move), age 0; whenever what was sensed changes.

With moving lights (track 'full', no exposure) it is the phased grid (``FullTrackGrid.phased``,
layout ``stealth-phased-v1/full/<L>phases-<a>perstep/RxC``: L the cycle's bins, a the bins a
step advances), a float32 (L, rows, cols, 12) array, channels ``PHASED_CHANNELS``: at each
layer (bin) the grid above with that bin's lights, then ``STEP_CHANNELS``, the light each step
from there is judged on (the lattice model's ``step_visibility`` exactly: the four moves and the
wait), -2 where the step does not exist (no node, or a move the map blocks, which only waits).
Why not the grid's own move channels: they are the most light of a move either way at the bin's
start, and a wait's light (the node over the step's time) is in none. Every channel but the
robot's depends only on the scenario and the goal, so one phased grid serves a whole run; the
time-aware generalist (``stealth_learn``) trains on it and reads it at the robot's (layer, cell).

With moving lights on track 'sensed' it is the phased grid of what was sensed
(``FullTrackGrid.phased_sensed``, layout ``stealth-phased-v1/sensed/<L>phases-<a>perstep/RxC``):
the same channels, each layer's light, moves and wait as last sensed at that layer (-1 never).
It changes at nearly every step (a step reaches a (layer, place) not seen before), and
the state does not say whether it did (its sensed part is the light last sensed at any layer),
so the environment sends it before every state the agent decides on with the robot channel 1 at
that state's (layer, cell) (``with_robot``): the mark is how the agent matches the two.
"""

from __future__ import annotations

import numpy as np

from stealth_core.grid_cells import cell_of
from stealth_core.sensing import NO_PLACE, Sensing
from stealth_core.task import WAIT

VERSION = 'v1'
CHANNELS = ('free', 'robot', 'goal', 'light', 'move_up', 'move_right', 'age')
FREE, ROBOT, GOAL, LIGHT, MOVE_UP, MOVE_RIGHT, AGE = range(len(CHANNELS))
STEP_CHANNELS = ('step_up', 'step_down', 'step_left', 'step_right', 'step_wait')
PHASED_CHANNELS = (*CHANNELS, *STEP_CHANNELS)  # the phased grid's (moving lights)
PHASED_PREFIX = f'stealth-phased-{VERSION}/'  # every phased grid's id starts so


def layout_id(track: str, rows: int, cols: int) -> str:
    """The grid layout's id for a track and a lattice size, e.g. ``stealth-grid-v1/full/40x60``."""
    return f'stealth-grid-{VERSION}/{track}/{rows}x{cols}'


def phased_layout_id(track: str, layers: int, advance: int, rows=None, cols=None) -> str:
    """The phased grid's id for a track, its phase layers and the layers a step advances, e.g.
    ``stealth-phased-v1/full/8phases-1perstep/40x60``; without its size when ``rows`` is None."""
    base = f'{PHASED_PREFIX}{track}/{layers}phases-{advance}perstep'
    return base if rows is None else f'{base}/{rows}x{cols}'


def stack(free, goal, light, moves, robot=None, age=None) -> np.ndarray:
    """(R, C, 7) float32 from the (R, C) channels and (2, R, C) moves (robot, age: zero)."""
    free = np.asarray(free, dtype=np.float32)
    zero = np.zeros_like(free)
    return np.stack(
        [
            free,
            zero if robot is None else np.asarray(robot, np.float32),
            np.asarray(goal, dtype=np.float32),
            np.asarray(light, dtype=np.float32),
            np.asarray(moves[0], dtype=np.float32),
            np.asarray(moves[1], dtype=np.float32),
            zero if age is None else np.asarray(age, np.float32),
        ],
        axis=-1,
    )


def step_grids(moves: np.ndarray, free: np.ndarray, wait: np.ndarray) -> np.ndarray:
    """(R, C, 5) the step channels (``STEP_CHANNELS``) of a layer's (2, R, C) move light (up
    and right from each node): up and right the node's own moves, down the move up from the
    node below, left the move right from the node to the left (-2 beyond the grid); the wait
    ``wait`` (R, C), -2 off the ``free`` nodes."""
    up, right = np.asarray(moves, np.float32)
    down = np.full_like(up, NO_PLACE)
    left = np.full_like(right, NO_PLACE)
    down[1:] = up[:-1]
    left[:, 1:] = right[:, :-1]
    wait = np.where(free, wait, NO_PLACE)
    down, left = (np.where(free, channel, NO_PLACE) for channel in (down, left))
    return np.stack([up, down, left, right, wait], -1).astype(np.float32)


def light_grids(sensing: Sensing, place: int) -> tuple[np.ndarray, np.ndarray]:
    """((R, C) node light, (2, R, C) move light) at the layer of model place ``place``, -2
    where no node or move is."""
    nodes, moves = sensing.truth(place)
    return sensing.grid(nodes), sensing.move_grid(moves)


def lattice_geometry(task) -> tuple[float, float, float]:
    """(resolution, origin x, origin y) of a grid with one cell centred on each lattice node
    (row 0 southernmost), in the map frame: cell side = the step distance (m), origin = the
    south-west corner of cell (0, 0) (m)."""
    lattice = task.lattice
    step = float(task.scenario.step_distance)
    x, y = lattice.node_to_point((lattice.i_min, lattice.j_min))
    return step, x - step / 2, y - step / 2


class FullTrackGrid:
    """The grids of one lattice model (``lattice_model.LatticeModel``): the lights-known grid
    (``static``), the phased grid where lights move (``phased``) and, for ``track`` 'sensed',
    the belief (``belief``)."""

    def __init__(self, model, sensing: Sensing | None = None, track: str = 'full'):
        self.model = model
        self.track = track
        self.sensing = Sensing(model) if sensing is None else sensing
        rows, cols = self.sensing.grid_row, self.sensing.grid_col
        n = self.sensing.n
        self.shape = self.sensing.shape
        self.free = np.zeros(self.shape, bool)
        self.free[rows, cols] = True
        self.goal = np.zeros(self.shape, bool)
        self.goal[rows, cols] = model.goal[:n]
        self.geometry = lattice_geometry(model.task)
        # Where lights move the environment sends a phased grid: the lights' (track 'full') or
        # what was sensed at each layer (track 'sensed').
        self.timed = model.task.scenario.has_moving_lights

    def layout(self) -> str:
        if self.timed:
            timing = self.model.task.timing
            return phased_layout_id(
                self.track, self.model.layers, timing.bins_per_step, *self.shape
            )
        return layout_id(self.track, *self.shape)

    @property
    def channels(self) -> tuple[str, ...]:
        """The channel names of the grids sent (GridObservation.channel_names)."""
        return PHASED_CHANNELS if self.timed else CHANNELS

    def full(self) -> np.ndarray:
        """The lights-known grid sent once a run: the phased grid where lights move, else the
        static one."""
        return self.phased() if self.timed else self.static()

    def static(self, layer: int = 0) -> np.ndarray:
        """(R, C, 7) the grid at ``layer`` (bin and heading) with the robot channel 0."""
        light, moves = light_grids(self.sensing, layer * self.sensing.n)
        return stack(self.free, self.goal, light, moves)

    def phased(self) -> np.ndarray:
        """(L, R, C, 12) the phased grid (module docstring) with the robot channel 0: each
        layer's ``static`` grid, then the light of each step from there (-2 where the step does
        not exist)."""
        model, sensing = self.model, self.sensing
        layers, n = model.layers, sensing.n
        grids = np.stack([self.static(layer) for layer in range(layers)])
        actions = WAIT + 1
        after = model.node_of(model.successors[:, :WAIT]).reshape(layers, n, WAIT)
        moved = after != np.arange(n)[:, None]
        exists = np.concatenate([moved, np.ones((layers, n, 1), bool)], -1)
        light = model.step_visibility[:, :actions].astype(np.float32).reshape(layers, n, actions)
        steps = np.full((layers, *self.shape, actions), NO_PLACE, np.float32)
        steps[:, sensing.grid_row, sensing.grid_col] = np.where(exists, light, NO_PLACE)
        return np.concatenate([grids, steps], -1)

    def phased_sensed(self, memory) -> np.ndarray:
        """(L, R, C, 12) the phased grid of what was sensed (``sensing.PhasedMemory``): at each
        layer its node and move light as last sensed there (-1 never, -2 none), the four step
        channels the move's value at that layer (what was sensed of the segment, either way, at
        the layer's start: the same -1 and -2), the wait's as sensed (the node watched over the
        step: ``sensing``). Robot 0. The phased belief (``stealth_learn.belief``) fills the
        unknowns."""
        sensing = self.sensing
        layers = []
        for node_light, move_light, wait_light in zip(
            memory.node_light, memory.move_light, memory.wait_light, strict=True
        ):
            light, moves = sensing.grid(node_light), sensing.move_grid(move_light)
            steps = step_grids(moves, self.free, sensing.grid(wait_light))
            layers.append(np.concatenate([stack(self.free, self.goal, light, moves), steps], -1))
        return np.stack(layers)

    def with_robot(self, grid: np.ndarray, state) -> np.ndarray:
        """``grid`` (the phased sensed grid of a state) with the robot channel 1 at the state's
        (layer, cell): its phase (third feature) and the cell of its (x, y), as the agent reads
        them (a new array; no mark where the state lies outside the grid or has no phase layer
        the grid has)."""
        grid = np.array(grid, dtype=np.float32)
        grid[..., ROBOT] = 0.0
        row, col = self.cell_of(float(state[0]), float(state[1]))
        layer = float(state[2]) if len(state) > 2 else -1.0
        rows, cols = self.shape
        if 0 <= row < rows and 0 <= col < cols and layer == int(layer) and 0 <= layer < len(grid):
            grid[int(layer), row, col, ROBOT] = 1.0
        return grid

    def belief(self, light, moves) -> np.ndarray:
        """(R, C, 7) the sensed track's grid of (R, C) node light and (2, R, C) move light as
        last sensed (-1 never, -2 none: ``sensing.Sensing.grid``, ``move_grid``), robot 0."""
        return stack(self.free, self.goal, light, moves)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell a map point (m) falls in (may lie outside the grid)."""
        return cell_of(self.geometry, x, y)


def observed_grid(task, track: str, layout: str, model=None) -> FullTrackGrid | None:
    """The grids the environment node sends for parameters ``track`` and ``observation_layout``
    (None: 'off'); ValueError, one line, where it has none to send (``check_grid``)."""
    if layout == 'off':
        return None
    if layout != 'grid':
        raise ValueError(f"expected 'off' or 'grid', got {layout!r}")
    check_grid(task, track)
    if model is None:
        from stealth_core.lattice_model import LatticeModel

        model = LatticeModel.build(task)
    return FullTrackGrid(model, track=track)


def check_grid(task, track: str) -> None:
    """ValueError, one line, unless there is a grid to send for ``task`` (a
    ``task.StealthTask``) on ``track``: track 'full', the static grid, or the phased grid where
    lights move; track 'sensed', the belief, or the phased grid of what was sensed where lights
    move; exposure (headings) in none. Read from the task alone (no lattice model), so a run
    checks it before anything starts."""
    if track not in ('full', 'sensed'):
        raise ValueError(f"'grid' is sent on track 'full' or 'sensed', not {track!r}")
    name = task.scenario.name
    if task.headings != 1:
        raise ValueError(
            f"'grid' is for lights without exposure; scenario {name!r} weighs exposure by "
            'heading: no grid carries the heading'
        )
    moving = task.scenario.has_moving_lights
    if task.cycle_bins != 1 and not moving:
        raise ValueError(
            f"'grid' is for static or moving lights; scenario {name!r} has {task.cycle_bins} "
            'phase bins and no moving lights'
        )
