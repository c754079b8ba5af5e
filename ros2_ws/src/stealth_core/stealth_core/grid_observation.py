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
"""

from __future__ import annotations

import numpy as np

from stealth_core.grid_cells import cell_of
from stealth_core.sensing import Sensing

VERSION = 'v1'
CHANNELS = ('free', 'robot', 'goal', 'light', 'move_up', 'move_right', 'age')
FREE, ROBOT, GOAL, LIGHT, MOVE_UP, MOVE_RIGHT, AGE = range(len(CHANNELS))


def layout_id(track: str, rows: int, cols: int) -> str:
    """The grid layout's id for a track and a lattice size, e.g. ``stealth-grid-v1/full/40x60``."""
    return f'stealth-grid-{VERSION}/{track}/{rows}x{cols}'


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
    (``static``) and, for ``track`` 'sensed', the belief (``belief``)."""

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

    def layout(self) -> str:
        return layout_id(self.track, *self.shape)

    def static(self, layer: int = 0) -> np.ndarray:
        """(R, C, 7) the grid at ``layer`` (bin and heading) with the robot channel 0."""
        light, moves = light_grids(self.sensing, layer * self.sensing.n)
        return stack(self.free, self.goal, light, moves)

    def belief(self, light, moves) -> np.ndarray:
        """(R, C, 7) the sensed track's grid of (R, C) node light and (2, R, C) move light as
        last sensed (-1 never, -2 none: ``sensing.Sensing.grid``, ``move_grid``), robot 0."""
        return stack(self.free, self.goal, light, moves)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell a map point (m) falls in (may lie outside the grid)."""
        return cell_of(self.geometry, x, y)


def observed_grid(task, track: str, layout: str, model=None) -> FullTrackGrid | None:
    """The grids the environment node sends for parameters ``track`` and ``observation_layout``
    (None: 'off'); ValueError, one line, where it has none to send: static lights without
    exposure (one layer) only, the lights-known grid on track 'full', the belief on 'sensed'."""
    if layout == 'off':
        return None
    if layout != 'grid':
        raise ValueError(f"expected 'off' or 'grid', got {layout!r}")
    if track not in ('full', 'sensed'):
        raise ValueError(f"'grid' is sent on track 'full' or 'sensed', not {track!r}")
    if model is None:
        from stealth_core.lattice_model import LatticeModel

        model = LatticeModel.build(task)
    if model.layers != 1:
        raise ValueError(
            f"'grid' is for static lights without exposure (1 layer); scenario "
            f'{task.scenario.name!r} has {model.layers} layers (moving lights or exposure)'
        )
    return FullTrackGrid(model, track=track)
