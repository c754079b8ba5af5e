"""The task of one scenario and goal as arrays over the move lattice: the exact MDP that the
planners solve (``stealth_core.planners``) and the Gymnasium environment steps through.

Its places are lattice nodes, with moving lights and ``phase_bins`` (node, bin) pairs (a step
advances the bin, a fifth action waits), and with exposure by orientation each of four headings;
every step is judged by ``StealthTask`` on the most light along it (sampled in space and time,
``StealthTask.step_visibility``). A move into a wall leaves the robot where it is, and still
counts as a step (the successor of a blocked move is the node itself, at the next bin).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from stealth_core import exposure
from stealth_core.move_lattice import ACTIONS, Node
from stealth_core.task import StealthTask

# The two moves at right angles to each action (0 up, 1 down, 2 left, 3 right); a wait or a
# turn (4 and up) never slips.
PERPENDICULAR = ((2, 3), (2, 3), (0, 1), (0, 1), (), (), ())


def action_distribution(slip: float, num_actions: int = len(ACTIONS)) -> np.ndarray:
    """P[a, b]: probability that action a moves the robot in direction b (a wait, action 4,
    always waits)."""
    if not 0.0 <= slip <= 1.0:
        raise ValueError(f'slip: expected a probability in [0, 1], got {slip!r}')
    matrix = np.eye(num_actions)
    for action, sideways in enumerate(PERPENDICULAR[:num_actions]):
        if sideways:
            matrix[action, action] = 1.0 - slip
        for direction in sideways:
            matrix[action, direction] += slip / 2
    return matrix


@dataclasses.dataclass(frozen=True, eq=False)
class LatticeModel:
    """The task on its time-expanded move lattice, as arrays over *places*: a place is a valid
    node at a bin of the lights' cycle and, where lights are weighed by exposure, facing one
    of four headings (``stealth_core.exposure``), index ``(heading * cycle_bins + cycle_bin) *
    len(nodes) + node`` (node in the order of ``MoveLattice.valid_nodes``); one bin when the
    lights do not move or the state has no phase (moving lights are then frozen at time ``t``,
    and the model is not the task), one heading without exposure.

    successors[i, b]: the place a step in direction b (0-3 the moves, then a wait where lights
    move, then the turns where the scenario has them: ``task.action_names``) from place i
    reaches: the target node (i's own when the move is blocked or a turn) at the bin
    ``bins_per_step`` later, facing the step's heading (``StealthTask.heading_after``).
    step_visibility[i, b]: that step's visibility
    (``StealthTask.step_visibility``: the most light along the move, sampled in space and
    time, the arrival included), what the step is judged on. visibility[i]: the light at the
    place itself (its node at its bin's start); states[i]: the agent's float32 state there.
    """

    task: StealthTask
    t: float
    nodes: list[Node]
    points: np.ndarray  # (places, 2) float64, m
    states: np.ndarray  # (places, features) float32
    successors: np.ndarray  # (places, directions) int
    step_visibility: np.ndarray  # (places, directions)
    visibility: np.ndarray  # (places,)
    distance: np.ndarray  # (places,) to the goal point, m
    goal: np.ndarray  # (places,) bool: within the goal's radius
    start: int
    cycle_bins: int = 1
    headings: int = 1  # 4 where lights are weighed by exposure (stealth_core.exposure)

    @classmethod
    def build(cls, task: StealthTask, t: float = 0.0) -> LatticeModel:
        lattice = task.lattice
        nodes = list(lattice.valid_nodes())
        n = len(nodes)
        index = {node: i for i, node in enumerate(nodes)}
        node_points = np.array([lattice.node_to_point(node) for node in nodes], dtype=np.float64)
        directions = task.num_actions
        moves = np.repeat(np.arange(n)[:, None], directions, axis=1)  # waits and turns stay
        moves[:, : len(ACTIONS)] = lattice.successor_table()
        timing = task.timing
        cycle_bins, headings = task.cycle_bins, task.headings
        advance = 0 if timing is None else timing.bins_per_step
        bin_seconds = 0.0 if timing is None else timing.bin_seconds
        step_seconds = 0.0 if timing is None else timing.step_seconds
        places = np.arange(n * cycle_bins * headings)
        node_of_place = places % n
        bin_of_place = (places // n) % cycle_bins
        heading_of_place = places // (n * cycle_bins)
        # The heading after each step: (headings, n, directions).
        moved = moves != np.arange(n)[:, None]
        after = np.array(
            [
                [[task.heading_after(h, a, m) for a, m in enumerate(row)] for row in moved]
                for h in range(headings)
            ]
        ) if headings > 1 else np.zeros((1, n, directions), dtype=np.int64)  # fmt: skip
        successors = (
            after[heading_of_place, node_of_place] * cycle_bins
            + (bin_of_place[:, None] + advance) % cycle_bins
        ) * n + moves[node_of_place]
        step_visibility = np.empty((places.size, directions))
        visibility = np.empty(places.size)
        ends = node_points[moves]  # (n, directions, 2)
        for layer in range(cycle_bins * headings):
            heading, cycle_bin = divmod(layer, cycle_bins)
            t0 = t + cycle_bin * bin_seconds
            rows = slice(layer * n, (layer + 1) * n)
            yaw = exposure.heading_angle(heading) if task.footprint is not None else None
            step_visibility[rows] = _step_peaks(
                task, node_points, ends, t0, t0 + step_seconds, yaw, after[heading]
            )
            visibility[rows] = task._point_visibility.many(
                *node_points.T, t0, None if yaw is None else np.full(n, yaw)
            )
        points = node_points[node_of_place]
        goal = task.goal
        distance = np.hypot(points[:, 0] - goal.x, points[:, 1] - goal.y)
        start_x, start_y, start_yaw = task.scenario.start
        start = index[lattice.point_to_node(start_x, start_y)]
        if headings > 1:
            start += exposure.heading_of(start_yaw) * cycle_bins * n
        bin_starts = t + bin_of_place * bin_seconds
        yaws = heading_of_place * (math.pi / 2)
        # task.state_of at every place: the position is the node's, the features the layer's.
        features = [
            task.features_at(float(bin_starts[layer * n]), float(yaws[layer * n]))
            for layer in range(cycle_bins * headings)
        ]
        states = np.empty((places.size, 2 + len(features[0])), dtype=np.float32)
        states[:, :2] = task.positions_of(points[:, 0], points[:, 1])
        if features[0]:
            states[:, 2:] = np.repeat(np.array(features, dtype=np.float32), n, axis=0)
        return cls(
            task=task,
            t=float(t),
            nodes=nodes,
            points=points,
            states=states,
            successors=successors,
            step_visibility=step_visibility,
            visibility=visibility,
            distance=distance,
            goal=distance <= goal.radius,
            start=start,
            cycle_bins=cycle_bins,
            headings=headings,
        )

    @property
    def size(self) -> int:
        """The number of places (nodes x bins x headings)."""
        return len(self.points)

    @property
    def layers(self) -> int:
        """Places per node: bins x headings."""
        return self.cycle_bins * self.headings

    def heading_of(self, place) -> np.ndarray:
        """The lattice heading (quarter turns from +x) of places; 0 without headings."""
        return np.asarray(place) // (len(self.nodes) * self.cycle_bins)

    @property
    def num_actions(self) -> int:
        return self.successors.shape[1]

    def node_of(self, place: int) -> int:
        """The node index (into ``nodes``) of a place."""
        return place % len(self.nodes)

    @property
    def seen(self) -> np.ndarray:
        """(places,) bool: places at or above the detection threshold."""
        return self.visibility >= self.task.scenario.detection_threshold

    @property
    def step_seen(self) -> np.ndarray:
        """(places, directions) bool: steps whose visibility reaches the detection threshold."""
        return self.step_visibility >= self.task.scenario.detection_threshold

    def direction(self, i: int, j: int) -> int:
        """The direction of a step from place i to place j (ValueError when there is none)."""
        found = np.flatnonzero(self.successors[i] == j)
        if found.size == 0:
            raise ValueError(f'no step leads from place {i} to place {j}')
        return int(found[0])

    def judge(self, i: int, step_index: int, direction: int | None = None, previous=None):
        """``StealthTask.judge`` of a step in ``direction`` from place ``previous`` into place i
        (action number step_index); without them, of arriving at i with its own light."""
        x, y = self.points[i]
        if previous is None:
            visibility = self.visibility[i]
        else:
            direction = self.direction(previous, i) if direction is None else direction
            visibility = self.step_visibility[previous, direction]
        t = self.t + step_index * self.task.step_seconds
        return self.task.judge(x, y, t, step_index, visibility=visibility)


def _step_peaks(task: StealthTask, points, ends, t0, t1, yaw, after) -> np.ndarray:
    """(n, directions): the most light of each step from each node at t0 (judged as
    ``StealthTask.step_visibility``): the drive sampled in space and time, and, where lights are
    weighed by exposure (``yaw`` the heading at the departure, ``after`` (n, directions) the
    heading after each step), the turn before it."""
    see = task._point_visibility
    xs, ys, ts = task.step_samples_of(
        points[:, None, 0], points[:, None, 1], t0, ends[..., 0], ends[..., 1], t1
    )
    yaw1 = None if yaw is None else after * (math.pi / 2)
    if task.scenario.has_moving_lights:
        samples = zip(xs, ys, ts, strict=True)
        peak = np.max([see.many(x, y, time, yaw1) for x, y, time in samples], 0)
    else:  # the lights are the same at every sample's time: all samples in one call
        peak = see.many(xs, ys, t0, yaw1).max(axis=0)
    if yaw is None:
        return peak
    _, _, _, yaws = task.turn_samples_of(points[:, None, 0], points[:, None, 1], t0, yaw, yaw1)
    if len(yaws):  # the turns at the departures, all at t0: the lights traced once
        xs, ys = (np.broadcast_to(points[:, None, k], yaw1.shape) for k in (0, 1))
        turning = np.max(see.turning(xs, ys, t0, yaws), 0)
        turned = exposure.wrap(yaw1 - yaw) != 0.0  # a step without a turn has no turn samples
        peak = np.maximum(peak, np.where(turned, turning, 0.0))
    return peak
