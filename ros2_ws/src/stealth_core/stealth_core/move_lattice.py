"""The lattice of places the robot's RL moves can reach, and which moves are collision-free.

The original's actions move the robot up (+y), down (-y), left (-x) or right (+x) by the step
distance, starting from the start pose, so every place it can be is a node
``start + (i * step, j * step)``. A node is valid when the robot's disc (``robot_radius``) at it
touches no blocked map cell (occupied or unknown) and stays inside the map; a move is valid when
the disc swept along the straight segment between two valid neighbours touches none either.

"Touches" is exact at the cell level: a cell counts when its square is closer than
``robot_radius`` to the point or segment (a cell merely grazing the disc at exactly the radius
does not), and the cell holding the point always counts, so a zero radius means "the cells under
the path are free". Validity is computed once for all nodes and moves with numpy (a 600 x 600
cell map with 0.25 m steps takes a few tens of milliseconds: bench/bench_lattice.py); searches are
then cheap.

Scenario validation uses ``bfs`` to prove each goal reachable; the lighting checks, the planners
and the environment build on the same lattice so that all of them agree on what a move is.
"""

from collections import deque
from collections.abc import Callable, Iterator
import contextlib
import math
import weakref

import numpy as np

from stealth_core.occupancy_map import OccupancyMap

Node = tuple[int, int]
# The original's action order: 0 up, 1 down, 2 left, 3 right.
ACTIONS: tuple[tuple[str, Node], ...] = (
    ('up', (0, 1)),
    ('down', (0, -1)),
    ('left', (-1, 0)),
    ('right', (1, 0)),
)
_DELTAS = frozenset(delta for _, delta in ACTIONS)
_CHUNK = 4096  # nodes per vectorised footprint check, to bound memory on fine lattices
# Each scenario's lattice, built once (load_scenario builds it to check the start; every task
# of the scenario reuses it): keyed by the scenario object, dropped with it.
_SCENARIO_LATTICES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class MoveLattice:
    """Nodes ``anchor + (i * step, j * step)`` over a map, with their validity and moves.

    ``node_mask[a, b]`` says whether node ``(i_min + a, j_min + b)`` is valid;
    ``right_moves[a, b]`` whether the move from that node to ``(i + 1, j)`` is,
    ``up_moves[a, b]`` whether the move to ``(i, j + 1)`` is. Planners may use these arrays
    directly; everything else goes through the methods.
    """

    def __init__(
        self,
        occupancy_map: OccupancyMap,
        anchor: tuple[float, float],
        step: float,
        robot_radius: float = 0.0,
    ):
        if not (math.isfinite(step) and step > 0):
            raise ValueError(f'step: expected a number > 0 (m), got {step!r}')
        if not (math.isfinite(robot_radius) and robot_radius >= 0):
            raise ValueError(f'robot_radius: expected a number >= 0 (m), got {robot_radius!r}')
        self.map = occupancy_map
        self.anchor = (float(anchor[0]), float(anchor[1]))
        self.step = float(step)
        self.robot_radius = float(robot_radius)
        x_min, y_min, x_max, y_max = occupancy_map.bounds
        self.i_min, i_max = self._index_span(x_min, x_max, self.anchor[0])
        self.j_min, j_max = self._index_span(y_min, y_max, self.anchor[1])
        self.shape = (max(i_max - self.i_min + 1, 0), max(j_max - self.j_min + 1, 0))
        self._padding = math.ceil(self.robot_radius / occupancy_map.resolution) + 2
        self._blocked = np.pad(occupancy_map.blocked, self._padding, constant_values=True)
        self._blocked_sums = _summed_area_table(self._blocked)
        self.node_mask = self._footprints_clear()
        self.right_moves = self.node_mask[:-1, :] & self.node_mask[1:, :]
        self.right_moves &= self._sweeps_clear(horizontal=True)
        self.up_moves = self.node_mask[:, :-1] & self.node_mask[:, 1:]
        self.up_moves &= self._sweeps_clear(horizontal=False)

    @classmethod
    def from_scenario(cls, scenario) -> 'MoveLattice':
        """The lattice of a ``stealth_core.scenario.Scenario``: anchored at its start; built
        once per scenario object (the lattice is never changed after it is built)."""
        try:
            lattice = _SCENARIO_LATTICES.get(scenario)
        except TypeError:  # not weakly referable (a stand-in for a scenario): never shared
            lattice = None
        if lattice is None or not lattice.fits(scenario):
            lattice = cls(
                scenario.map, scenario.start[:2], scenario.step_distance, scenario.robot_radius
            )
            lattice.share_with(scenario)
        return lattice

    def fits(self, scenario) -> bool:
        """Whether this is the lattice of the scenario: its map, start, step and radius."""
        return (
            self.map is scenario.map
            and self.anchor == (float(scenario.start[0]), float(scenario.start[1]))
            and self.step == float(scenario.step_distance)
            and self.robot_radius == float(scenario.robot_radius)
        )

    def share_with(self, scenario) -> None:
        """Make this the lattice ``from_scenario`` gives for the scenario (when it fits)."""
        if self.fits(scenario):
            with contextlib.suppress(TypeError):  # not weakly referable: built for each caller
                _SCENARIO_LATTICES[scenario] = self

    # --- geometry ---------------------------------------------------------------------------

    def _index_span(self, low: float, high: float, anchor: float) -> tuple[int, int]:
        """The lattice indices whose coordinate lies in [low, high)."""
        first = math.ceil((low - anchor) / self.step)
        last = math.floor((high - anchor) / self.step)
        while anchor + last * self.step >= high:
            last -= 1
        while anchor + first * self.step < low:
            first += 1
        return first, last

    def node_to_point(self, node: Node) -> tuple[float, float]:
        return (self.anchor[0] + node[0] * self.step, self.anchor[1] + node[1] * self.step)

    def point_to_node(self, x: float, y: float) -> Node:
        """The nearest lattice node to a point (whether valid or not)."""
        return (
            round((x - self.anchor[0]) / self.step),
            round((y - self.anchor[1]) / self.step),
        )

    def _grid_coordinates(self, xs: np.ndarray, ys: np.ndarray):
        """World coordinates as continuous cell coordinates of the padded blocked grid."""
        x0, y0, _ = self.map.origin
        u = (xs - x0) / self.map.resolution + self._padding
        v = (ys - y0) / self.map.resolution + self._padding
        return u, v

    def _node_points(self) -> tuple[np.ndarray, np.ndarray]:
        i = np.arange(self.i_min, self.i_min + self.shape[0])
        j = np.arange(self.j_min, self.j_min + self.shape[1])
        ii, jj = np.meshgrid(i, j, indexing='ij')
        return self.anchor[0] + ii * self.step, self.anchor[1] + jj * self.step

    def _footprints_clear(self) -> np.ndarray:
        """Per node: no blocked cell within the robot's radius (or under its centre). Only the
        nodes with a blocked cell in their window of cells get the exact test: the others are
        clear whatever the distances."""
        xs, ys = self._node_points()
        u, v = self._grid_coordinates(xs.ravel(), ys.ravel())
        radius = self.robot_radius / self.map.resolution
        reach = math.ceil(radius) + 1
        offsets = np.arange(-reach, reach + 1)
        d_col, d_row = (o.ravel() for o in np.meshgrid(offsets, offsets, indexing='ij'))
        base_col, base_row = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
        near_wall = _count_in_box(
            self._blocked_sums, base_row - reach, base_row + reach,
            base_col - reach, base_col + reach,
        ) > 0  # fmt: skip
        clear = np.ones(u.size, dtype=bool)
        exact = np.flatnonzero(near_wall)
        u, v = u[exact], v[exact]
        for start in range(0, u.size, _CHUNK):
            cu, cv = u[start : start + _CHUNK, None], v[start : start + _CHUNK, None]
            cols = np.floor(cu).astype(np.int64) + d_col
            rows = np.floor(cv).astype(np.int64) + d_row
            gap_u = np.maximum(np.maximum(cols - cu, cu - (cols + 1)), 0.0)
            gap_v = np.maximum(np.maximum(rows - cv, cv - (rows + 1)), 0.0)
            distance_squared = gap_u * gap_u + gap_v * gap_v
            touched = (distance_squared < radius * radius) | (distance_squared == 0.0)
            clear[exact[start : start + _CHUNK]] = ~(touched & self._blocked[rows, cols]).any(
                axis=1
            )
        return clear.reshape(self.shape)

    def _sweeps_clear(self, horizontal: bool) -> np.ndarray:
        """Per move: no blocked cell in the band the robot's disc sweeps between the nodes.

        The disc swept along an axis-aligned segment is the two end discs (checked with the
        nodes) plus the band of cells level with the segment and nearer than the radius.
        """
        xs, ys = self._node_points()
        xs, ys = (xs[:-1, :], ys[:-1, :]) if horizontal else (xs[:, :-1], ys[:, :-1])
        u, v = self._grid_coordinates(xs, ys)
        length = self.step / self.map.resolution
        radius = self.robot_radius / self.map.resolution
        along, across = (u, v) if horizontal else (v, u)
        along_first = np.floor(along).astype(np.int64)
        along_last = np.floor(along + length).astype(np.int64)
        across_first = np.minimum(np.floor(across - radius), np.floor(across)).astype(np.int64)
        across_last = np.maximum(np.ceil(across + radius) - 1, np.floor(across)).astype(np.int64)
        if horizontal:
            count = _count_in_box(
                self._blocked_sums, across_first, across_last, along_first, along_last
            )
        else:
            count = _count_in_box(
                self._blocked_sums, along_first, along_last, across_first, across_last
            )
        return count == 0

    # --- queries ----------------------------------------------------------------------------

    def contains(self, node: Node) -> bool:
        a, b = node[0] - self.i_min, node[1] - self.j_min
        return 0 <= a < self.shape[0] and 0 <= b < self.shape[1]

    def is_valid(self, node: Node) -> bool:
        return self.contains(node) and bool(
            self.node_mask[node[0] - self.i_min, node[1] - self.j_min]
        )

    def can_move(self, node: Node, delta: Node) -> bool:
        """Whether the one-step move by delta (one of the ACTIONS' deltas) is collision-free."""
        if tuple(delta) not in _DELTAS:
            raise ValueError(f'delta: expected one of {sorted(_DELTAS)}, got {delta!r}')
        target = (node[0] + delta[0], node[1] + delta[1])
        if not (self.is_valid(node) and self.is_valid(target)):
            return False
        low = min(node, target)
        a, b = low[0] - self.i_min, low[1] - self.j_min
        moves = self.right_moves if delta[1] == 0 else self.up_moves
        return bool(moves[a, b])

    def successor(self, node: Node, action: int) -> Node | None:
        """The node action ``action`` (0 up, 1 down, 2 left, 3 right) leads to, or None."""
        delta = ACTIONS[action][1]
        if not self.can_move(node, delta):
            return None
        return (node[0] + delta[0], node[1] + delta[1])

    def neighbours(self, node: Node) -> list[Node]:
        """The nodes one valid move away, in action order (up, down, left, right)."""
        return [(node[0] + d[0], node[1] + d[1]) for _, d in ACTIONS if self.can_move(node, d)]

    def reachable(self, start_node: Node) -> np.ndarray:
        """(shape) bool, like ``node_mask``: the nodes some path of valid moves leads to from
        start_node (none when it is not valid); ``bfs`` for every goal at once, in numpy."""
        reach = np.zeros(self.shape, dtype=bool)
        if not self.is_valid(start_node):
            return reach
        reach[start_node[0] - self.i_min, start_node[1] - self.j_min] = True
        right, up = self.right_moves, self.up_moves
        while True:
            grown = reach.copy()
            grown[1:, :] |= reach[:-1, :] & right
            grown[:-1, :] |= reach[1:, :] & right
            grown[:, 1:] |= reach[:, :-1] & up
            grown[:, :-1] |= reach[:, 1:] & up
            if np.array_equal(grown, reach):
                return reach
            reach = grown

    def successor_table(self) -> np.ndarray:
        """(valid nodes, ACTIONS) int: the index (in ``valid_nodes``' order) of each action's
        successor from each valid node, the node's own index where the move is blocked; what
        ``successor`` gives, for every node at once."""
        a, b = np.nonzero(self.node_mask)
        index = np.full(self.shape, -1, dtype=np.int64)
        own = np.arange(a.size)
        index[a, b] = own
        table = np.repeat(own[:, None], len(ACTIONS), axis=1)
        for action, (_, (di, dj)) in enumerate(ACTIONS):
            ta, tb = a + di, b + dj
            inside = (ta >= 0) & (ta < self.shape[0]) & (tb >= 0) & (tb < self.shape[1])
            la, lb = np.minimum(a, ta)[inside], np.minimum(b, tb)[inside]
            moves = self.right_moves if dj == 0 else self.up_moves
            allowed = np.zeros(a.size, dtype=bool)
            allowed[inside] = moves[la, lb] & (index[ta[inside], tb[inside]] >= 0)
            table[allowed, action] = index[ta[allowed], tb[allowed]]
        return table

    def valid_nodes(self) -> Iterator[Node]:
        for a, b in zip(*np.nonzero(self.node_mask), strict=True):
            yield (int(a) + self.i_min, int(b) + self.j_min)

    def nodes_within(self, x: float, y: float, radius: float) -> list[Node]:
        """Valid nodes at most ``radius`` from (x, y): where a goal of that radius is reached."""
        reach = math.ceil(radius / self.step) + 1
        ci, cj = self.point_to_node(x, y)
        found = []
        for i in range(ci - reach, ci + reach + 1):
            for j in range(cj - reach, cj + reach + 1):
                px, py = self.node_to_point((i, j))
                if math.hypot(px - x, py - y) <= radius and self.is_valid((i, j)):
                    found.append((i, j))
        return found

    def nearest_valid_node(self, x: float, y: float) -> Node | None:
        """The valid node nearest to (x, y), however far (None on a lattice without one)."""
        a, b = np.nonzero(self.node_mask)
        if a.size == 0:
            return None
        px = self.anchor[0] + (a + self.i_min) * self.step
        py = self.anchor[1] + (b + self.j_min) * self.step
        k = int(np.argmin((px - x) ** 2 + (py - y) ** 2))
        return (int(a[k]) + self.i_min, int(b[k]) + self.j_min)

    def bfs(
        self,
        start_node: Node,
        goal: Callable[[Node], bool],
        passable: Callable[[Node], bool] = lambda node: True,
    ) -> list[Node] | None:
        """A shortest path (fewest moves) from start_node to a node where ``goal`` holds.

        Only valid moves between nodes for which ``passable`` holds are taken (the start must
        be passable too). Returns the nodes from start to goal, or None when there is none.
        """
        if not self.is_valid(start_node) or not passable(start_node):
            return None
        came_from: dict[Node, Node | None] = {start_node: None}
        frontier = deque([start_node])
        while frontier:
            node = frontier.popleft()
            if goal(node):
                path = [node]
                while (previous := came_from[path[-1]]) is not None:
                    path.append(previous)
                return path[::-1]
            for neighbour in self.neighbours(node):
                if neighbour not in came_from and passable(neighbour):
                    came_from[neighbour] = node
                    frontier.append(neighbour)
        return None


def _summed_area_table(mask: np.ndarray) -> np.ndarray:
    """S[r, c] = number of True cells in mask[:r, :c] (one extra leading row and column)."""
    table = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), dtype=np.int64)
    table[1:, 1:] = mask.cumsum(axis=0).cumsum(axis=1)
    return table


def _count_in_box(table, row_first, row_last, col_first, col_last) -> np.ndarray:
    """True cells in the inclusive boxes [row_first, row_last] x [col_first, col_last]."""
    rows, cols = table.shape[0] - 1, table.shape[1] - 1
    r0, r1 = np.clip(row_first, 0, rows), np.clip(row_last + 1, 0, rows)
    c0, c1 = np.clip(col_first, 0, cols), np.clip(col_last + 1, 0, cols)
    return table[r1, c1] - table[r0, c1] - table[r1, c0] + table[r0, c0]
