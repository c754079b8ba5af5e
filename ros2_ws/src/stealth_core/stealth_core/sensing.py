"""What a robot that knows the floor plan but not the lights can sense, and what it remembers.

The robot carries a camera: from its lattice node it sees the light falling on the places in
its line of sight within ``sensing_range`` (m, the scenario's; default 8 m). Line of sight is
the rule the lights obey (``stealth_core.visibility``'s Bresenham lines, corners included), from
the robot's cell to the target's cell. What can be sensed is what the planners need, on the
move lattice (``lattice_model.LatticeModel``), so a sensed value is exactly a value the judge uses:

- a **node**'s light: ``model.visibility`` of the node at the robot's layer (the lights as they
  stand at the current bin, weighed for the robot's heading where the scenario says so); sensed
  when the node's point is within range and its cell in sight;
- a **move**'s light, for each pair of lattice neighbours (an undirected move, up or right from
  its lower node): the most light along the segment, the larger of the two directions'
  ``model.step_visibility`` (each samples the move at the map's resolution, the arrival
  included, so together they cover the closed segment); sensed when both ends are within range
  (the segment then is) and every cell of its samples is in sight. A move's value is what
  ``StealthTask.step_visibility`` would judge a step started now on: with moving lights it
  includes the light's motion during that one step (the model's own step), a small look ahead
  documented as such;
- a **wait**'s light, where the lights move (the scenario has the wait): the node's light over
  one step's time from the current bin (``model.step_visibility``'s wait), sensed with the node:
  a robot watching a place sees a beam cross it between two bins, which neither bin's value
  shows. Kept in the phased memory only (the sensed observation has no channel for it).

``Sensing`` says what is in sight from each node (traced on first use, then cached per node:
a robot revisits the same few hundred nodes). ``SensedMemory`` keeps, for every node and move,
the **last value sensed and the step it was sensed at** (-1 and -1 before it is ever sensed):
lights move, so an old value may be stale, and its age says how stale. ``PhasedMemory`` keeps
the last value sensed **at each phase layer** (the layer of the robot's place when it sensed:
the cycle's bin, and heading where exposure is weighed): the lights' motion repeats with the
cycle, so a value sensed at a layer stays true at that layer, never stale (with static lights
it has one layer and equals ``SensedMemory``'s values). ``Sensor`` holds all three for one
episode::

    sensor = Sensor(model)                       # model: lattice_model.LatticeModel of the task
    sensor.reset()                               # at each episode's start
    nodes, moves = sensor.sense(place, step)     # place: the Gym env's node, or
    place = sensor.place_of(x, y, t, yaw)        # from a pose (the ROS environment node)
    sensor.memory.node_light, sensor.memory.node_step  # what is remembered, and since when
    sensor.phased.node_light[layer]              # what is remembered of a phase layer

Plain Python + numpy.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from stealth_core.lighting import GridFrame
from stealth_core.task import WAIT
from stealth_core.visibility import _occluded, corner_maps

UNKNOWN = -1.0  # a value never sensed
NO_PLACE = -2.0  # a lattice point that is no valid node, or a move that does not exist
UP, DOWN, LEFT, RIGHT = range(4)  # the lattice's move directions (move_lattice.ACTIONS)


class Sensing:
    """The floor plan's sensing geometry for one lattice model (walls only, never its lights).

    nodes: node k is ``model.nodes[k]``; moves: ``move_from[e]`` to ``move_to[e]`` in direction
    ``move_direction[e]`` (UP or RIGHT), lower node first.
    """

    def __init__(self, model, sensing_range: float | None = None):
        scenario = model.task.scenario
        if sensing_range is None:
            sensing_range = scenario.sensing_range
        self.range = float(sensing_range)
        self.model = model
        occupancy = scenario.map
        self.blocked = occupancy.blocked
        self.frame = GridFrame.of(self.blocked, occupancy.resolution, occupancy.origin)
        self._corners = corner_maps(self.blocked)
        n = len(model.nodes)
        self.n = n
        self.points = model.points[:n]
        moves = model.successors[:n, :4] % n  # layer 0: where each move leads (itself: none)
        starts, directions, ends = [], [], []
        for direction in (UP, RIGHT):
            has = moves[:, direction] != np.arange(n)
            starts.append(np.flatnonzero(has))
            directions.append(np.full(int(has.sum()), direction))
            ends.append(moves[has, direction])
        self.move_from = np.concatenate(starts)
        self.move_direction = np.concatenate(directions)
        self.move_to = np.concatenate(ends)
        self._back = np.where(self.move_direction == UP, DOWN, LEFT)  # the move from its end
        # Every cell a move's samples fall in (its two ends included), as indices into cells.
        samples = max(int(model.task.step_samples), 1)
        fractions = np.linspace(0.0, 1.0, samples + 1)
        a, b = self.points[self.move_from], self.points[self.move_to]
        xs = a[:, None, 0] + (b[:, None, 0] - a[:, None, 0]) * fractions
        ys = a[:, None, 1] + (b[:, None, 1] - a[:, None, 1]) * fractions
        node_cells = self._flat_cells(self.points[:, 0], self.points[:, 1])
        move_cells = self._flat_cells(xs, ys)
        self.cells, inverse = np.unique(
            np.concatenate([node_cells, move_cells.ravel()]), return_inverse=True
        )
        self.node_cell = inverse[:n]
        self.move_cell = inverse[n:].reshape(move_cells.shape)
        self._cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        # Grid layout of the observation: node k at [row, col] = [j - j_min, i - i_min].
        lattice = model.task.lattice
        self.shape = (lattice.shape[1], lattice.shape[0])  # (rows, cols)
        nodes = np.asarray(model.nodes, dtype=np.int64).reshape(-1, 2)
        self.grid_col = nodes[:, 0] - lattice.i_min
        self.grid_row = nodes[:, 1] - lattice.j_min
        channel = (self.move_direction == RIGHT).astype(np.int64)
        self._move_at = (channel, self.grid_row[self.move_from], self.grid_col[self.move_from])

    def _flat_cells(self, xs, ys) -> np.ndarray:
        frame = self.frame
        cols = np.floor((np.asarray(xs) - frame.origin_x) / frame.resolution).astype(np.int64)
        rows = np.floor((np.asarray(ys) - frame.origin_y) / frame.resolution).astype(np.int64)
        return rows * frame.width + cols

    @property
    def moves(self) -> int:
        return len(self.move_from)

    def visible(self, node: int) -> tuple[np.ndarray, np.ndarray]:
        """(nodes, moves) in sight from node ``node`` (indices, ascending), cached per node."""
        found = self._cache.get(node)
        if found is None:
            found = self._cache[node] = self.trace(node)
        return found

    def trace(self, node: int) -> tuple[np.ndarray, np.ndarray]:
        """``visible`` without the cache: the lines of sight traced afresh."""
        x, y = self.points[node]
        gaps = self.points - (x, y)
        near = np.einsum('ij,ij->i', gaps, gaps) <= self.range * self.range
        moves_near = np.flatnonzero(near[self.move_from] & near[self.move_to])
        wanted = np.zeros(len(self.cells), dtype=bool)
        wanted[self.node_cell[near]] = True
        wanted[self.move_cell[moves_near].ravel()] = True
        targets = np.flatnonzero(wanted)
        width = self.frame.width
        robot = divmod(int(self.cells[self.node_cell[node]]), width)[::-1]  # (col, row)
        flat = self.cells[targets]
        occluded = _occluded(self.blocked, self._corners, robot, flat % width, flat // width)
        in_sight = np.zeros(len(self.cells), dtype=bool)
        in_sight[targets[~occluded]] = True
        nodes = np.flatnonzero(near & in_sight[self.node_cell])
        moves = moves_near[in_sight[self.move_cell[moves_near]].all(axis=1)]
        return nodes, moves

    def truth(self, place: int, nodes=slice(None), moves=slice(None)):
        """(node values, move values): the light on the nodes and moves (indices; default
        all) at the layer (bin and heading) of ``place``, what the robot senses where it sees."""
        model = self.model
        layer = place - model.node_of(place)
        node_values = model.visibility[layer : layer + self.n][nodes]
        step = model.step_visibility
        forward = step[layer + self.move_from[moves], self.move_direction[moves]]
        back = step[layer + self.move_to[moves], self._back[moves]]
        return node_values, np.maximum(forward, back)

    def wait_truth(self, place: int, nodes=slice(None)) -> np.ndarray:
        """The light of a wait on the nodes (indices; default all) from the layer of
        ``place`` (module docstring); without a wait action (still lights: the light does not
        change over a step), the nodes' light."""
        model = self.model
        layer = place - model.node_of(place)
        if model.num_actions <= WAIT:
            return model.visibility[layer : layer + self.n][nodes]
        return model.step_visibility[layer : layer + self.n, WAIT][nodes]

    def grid(self, node_values: np.ndarray, fill: float = NO_PLACE) -> np.ndarray:
        """(rows, cols) float32: node values laid on the lattice, [j - j_min, i - i_min] (row 0
        the southernmost), ``fill`` where no valid node is."""
        out = np.full(self.shape, fill, dtype=np.float32)
        out[self.grid_row, self.grid_col] = node_values
        return out

    def move_grid(self, move_values: np.ndarray, fill: float = NO_PLACE) -> np.ndarray:
        """(2, rows, cols) float32: [0] the move up from each node, [1] the move right."""
        out = np.full((2, *self.shape), fill, dtype=np.float32)
        out[self._move_at] = move_values
        return out


@dataclasses.dataclass
class SensedMemory:
    """The last value sensed of every node and move, and the step it was sensed at (-1 and -1:
    never). Step 0 is the episode's first observation (the reset), then one per action."""

    node_light: np.ndarray
    node_step: np.ndarray
    move_light: np.ndarray
    move_step: np.ndarray

    @classmethod
    def empty(cls, sensing: Sensing) -> SensedMemory:
        n, m = sensing.n, sensing.moves
        return cls(
            np.full(n, UNKNOWN),
            np.full(n, -1, dtype=np.int64),
            np.full(m, UNKNOWN),
            np.full(m, -1, dtype=np.int64),
        )

    def update(self, nodes, node_values, moves, move_values, step: int) -> None:
        """Remember what was sensed at ``step``: the values of these nodes and moves replace
        whatever was remembered of them."""
        self.node_light[nodes] = node_values
        self.node_step[nodes] = step
        self.move_light[moves] = move_values
        self.move_step[moves] = step

    @property
    def node_known(self) -> np.ndarray:
        return self.node_step >= 0

    @property
    def move_known(self) -> np.ndarray:
        return self.move_step >= 0


@dataclasses.dataclass
class PhasedMemory:
    """Per phase layer (row), the last value sensed of every node and move while the robot's
    place was at that layer (-1: never); see the module docstring."""

    node_light: np.ndarray  # (layers, nodes)
    move_light: np.ndarray  # (layers, moves)
    wait_light: np.ndarray  # (layers, nodes): a wait from each node at each layer

    @classmethod
    def empty(cls, sensing: Sensing) -> PhasedMemory:
        layers, n = sensing.model.layers, sensing.n
        return cls(
            np.full((layers, n), UNKNOWN),
            np.full((layers, sensing.moves), UNKNOWN),
            np.full((layers, n), UNKNOWN),
        )

    def update(self, layer: int, nodes, node_values, moves, move_values, wait_values) -> None:
        """Remember what was sensed at ``layer``."""
        self.node_light[layer, nodes] = node_values
        self.move_light[layer, moves] = move_values
        self.wait_light[layer, nodes] = wait_values

    @property
    def layers(self) -> int:
        return self.node_light.shape[0]


class Sensor:
    """A ``Sensing`` and its memories (``SensedMemory``, ``PhasedMemory``) over one episode:
    ``reset`` then ``sense`` at every step. The memories are public; ``sense`` returns what
    was in sight."""

    def __init__(self, model, sensing_range: float | None = None):
        self.sensing = Sensing(model, sensing_range)
        self.reset()
        self._index: dict | None = None  # node (i, j) -> its index

    def reset(self) -> None:
        self.memory = SensedMemory.empty(self.sensing)
        self.phased = PhasedMemory.empty(self.sensing)

    def place_of(self, x: float, y: float, t: float = 0.0, yaw: float = 0.0) -> int:
        """The model place of a pose (x, y, yaw) at time t (s): the nearest valid node, the
        bin t falls in, the heading nearest yaw (what a caller outside the Gym env, such as the
        ROS environment node, passes to ``sense``)."""
        model = self.sensing.model
        task, lattice = model.task, model.task.lattice
        node = lattice.point_to_node(x, y)
        if not lattice.is_valid(node):
            node = lattice.nearest_valid_node(x, y)
        if self._index is None:
            self._index = {tuple(k): i for i, k in enumerate(model.nodes)}
        features = task.features_at(t, yaw)
        cycle_bin = int(features[0]) if task.timing is not None else 0
        heading = int(features[-1]) if task.footprint is not None else 0
        return (heading * model.cycle_bins + cycle_bin) * self.sensing.n + self._index[node]

    def sense(self, place: int, step: int) -> tuple[np.ndarray, np.ndarray]:
        """Sense from ``place`` (a model place: node, bin, heading) at ``step``: the (nodes,
        moves) in sight, their values stored in the memory."""
        sensing = self.sensing
        nodes, moves = sensing.visible(sensing.model.node_of(place))
        node_values, move_values = sensing.truth(place, nodes, moves)
        self.memory.update(nodes, node_values, moves, move_values, step)
        layer = int(place) // sensing.n
        waits = sensing.wait_truth(place, nodes)
        self.phased.update(layer, nodes, node_values, moves, move_values, waits)
        return nodes, moves


def flat_observation(observation: dict) -> np.ndarray:
    """The sensed track's observation as one float32 vector, in the order a flat state
    (``RLStateReward.state``) uses: state, lit, light (row-major), moves (channel, row, col)."""
    return np.concatenate(
        [
            np.asarray(observation['state'], dtype=np.float32).ravel(),
            np.asarray(observation['lit'], dtype=np.float32).ravel(),
            np.asarray(observation['light'], dtype=np.float32).ravel(),
            np.asarray(observation['moves'], dtype=np.float32).ravel(),
        ]
    )
