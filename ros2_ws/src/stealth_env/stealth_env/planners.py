"""Baselines on the robot's move lattice: how good a learned covert path is, measured against the
shortest path, a risk-aware planner and the exact optimum.

All three work on ``LatticeModel``, the task of one scenario and goal as arrays over the valid
lattice nodes (the exact MDP the Gymnasium environment steps through, which uses the same
arrays), and every path is judged by ``StealthTask.judge``, as the environments judge steps:

- ``astar``: the shortest path to the goal, ignoring the lights (unit-cost A*, Manhattan
  heuristic). On every shipped scenario it is detected: the scenarios are not trivial.
- ``dark_path``: risk-aware, in the spirit of the Dark Path algorithm (Marzouqi & Jarvis):
  the cheapest path with edge cost ``step_distance + weight * visibility`` of the node entered
  (metres, weight in metres per unit of visibility), never entering a node whose visibility
  reaches the detection threshold. weight 0 is the shortest undetected path; a large weight
  the darkest.
- ``value_iteration``: the exact optimum of the task's reward. Finite-horizon backward
  induction over the step limit, so truncation is modelled exactly, on the deterministic
  lattice or with slip (a move goes to one of the two perpendicular directions with
  probability ``slip``, each half of it, as ``gym_env``), in 'threshold' or 'probabilistic'
  detection mode (in expectation). gamma defaults to 1: the optimum of the *undiscounted* return
  (rewards after the first state, summed), which is what the project's 5 % criterion compares;
  the learners themselves discount (gamma 0.99 by default).

With moving lights and ``phase_bins`` the model is time-expanded: its places are (node, bin)
pairs, a step advances the bin, a fifth action waits, and every step is judged on the most
light along it (sampled in space and time, ``StealthTask.step_visibility``), so the optimum
times its passages and cannot slip through a beam between two nodes; ``dark_path`` is then a
time-aware Dark Path (A* over (node, bin), never taking a detected step). Moving lights
without ``phase_bins`` are frozen at time ``t``. Walls: a move into a wall leaves the robot
where it is, and still counts as a step (the model's successor of a blocked move is the node
itself, at the next bin).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import dataclasses
import heapq
import math
from typing import NamedTuple

import numpy as np

from stealth_env import exposure
from stealth_env.move_lattice import ACTIONS, Node
from stealth_env.reward import (
    EpisodeOutcome,
    detection_probability,
    detection_reward,
    step_reward,
    success_reward,
)
from stealth_env.task import StealthTask

# The two moves at right angles to each action (0 up, 1 down, 2 left, 3 right); a wait or a
# turn (4 and up) never slips.
PERPENDICULAR = ((2, 3), (2, 3), (0, 1), (0, 1), (), (), ())
DEFAULT_DARK_PATH_WEIGHT = 10.0  # m per unit of visibility: a 0.3 glimpse costs 3 m of detour


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
    of four headings (``stealth_env.exposure``), index ``(heading * cycle_bins + cycle_bin) *
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
    headings: int = 1  # 4 where lights are weighed by exposure (stealth_env.exposure)

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


# --- judging paths ------------------------------------------------------------------------------


class PathResult(NamedTuple):
    """A path (node indices from the start) walked through the task, as an episode would be."""

    outcome: EpisodeOutcome | None  # None: the path ended before anything ended the episode
    total_reward: float  # undiscounted, rewards after the first state
    steps: int
    peak_visibility: float
    accumulated_visibility: float
    path_length: float  # m
    points: np.ndarray  # (steps + 1, 2): the poses actually walked (cut at the end)

    @property
    def detected(self) -> bool:
        return self.outcome is EpisodeOutcome.DETECTED


def walk(model: LatticeModel, path: Sequence[int]) -> PathResult:
    """Judge each step of the path of places in turn (the first is the start, not judged) until
    one ends the episode (goal, detection or the step limit)."""
    task = model.task
    stats = task.start_episode(*model.points[path[0]])
    outcome = None
    walked = 1
    for step_index, (previous, i) in enumerate(zip(path, path[1:], strict=False), start=1):
        judgement = model.judge(i, step_index, previous=previous)
        stats.add(*model.points[i], judgement)
        walked += 1
        if judgement.terminal:
            outcome = judgement.outcome
            break
    return PathResult(
        outcome,
        stats.total_reward,
        stats.steps,
        stats.peak_visibility,
        stats.accumulated_visibility,
        stats.path_length,
        model.points[list(path[:walked])],
    )


# --- shortest paths -----------------------------------------------------------------------------


def _cheapest_path(
    model: LatticeModel,
    step_cost: np.ndarray,
    passable: np.ndarray,
    heuristic: np.ndarray,
) -> list[int] | None:
    """A* over places from the start to any goal place: a step in direction b from place i
    costs step_cost[i, b] (>= the heuristic's drop, so the heuristic is consistent) and is taken
    only when passable[i, b]. Steps that lead nowhere new (a blocked move) are skipped."""
    start = model.start
    best = {start: 0.0}
    came_from: dict[int, int] = {}
    frontier = [(float(heuristic[start]), 0.0, start)]
    closed = set()
    successors = model.successors.tolist()
    while frontier:
        _, cost, i = heapq.heappop(frontier)
        if i in closed:
            continue
        if model.goal[i]:
            path = [i]
            while path[-1] != start:
                path.append(came_from[path[-1]])
            return path[::-1]
        closed.add(i)
        for direction, j in enumerate(successors[i]):
            if j == i or j in closed or not passable[i, direction]:
                continue
            candidate = cost + float(step_cost[i, direction])
            if candidate < best.get(j, math.inf):
                best[j] = candidate
                came_from[j] = i
                heapq.heappush(frontier, (candidate + float(heuristic[j]), candidate, j))
    return None


def _moves_to_goal(model: LatticeModel) -> np.ndarray:
    """(places,) Manhattan distance in moves to the nearest goal node: an admissible
    heuristic."""
    nodes = np.asarray(model.nodes)
    n = len(nodes)
    targets = nodes[model.goal[:n]]
    if targets.size == 0:
        return np.zeros(model.size)
    gaps = np.abs(nodes[:, None, :] - targets[None, :, :]).sum(axis=2)
    return np.tile(gaps.min(axis=1).astype(np.float64), model.layers)


def _is_move(model: LatticeModel) -> np.ndarray:
    """(places, directions): whether the step changes the node (not a wait or a blocked move)."""
    n = len(model.nodes)
    return (model.successors % n) != (np.arange(model.size) % n)[:, None]


def astar(model: LatticeModel) -> list[int] | None:
    """The shortest path (fewest moves) from the start to the goal, ignoring the lights (and so
    never waiting)."""
    step = model.task.scenario.step_distance
    return _cheapest_path(
        model,
        np.full(model.successors.shape, step),
        _is_move(model),
        step * _moves_to_goal(model),
    )


def dark_path(model: LatticeModel, weight: float = DEFAULT_DARK_PATH_WEIGHT) -> list[int] | None:
    """The cheapest path with cost step_distance + weight * visibility per step (a wait costs
    the same as a move: it takes a step), never taking a step whose visibility reaches the
    detection threshold; None when every way is seen. With moving lights this is A* over
    (node, bin): it waits where waiting lets a beam pass."""
    if not (math.isfinite(weight) and weight >= 0):
        raise ValueError(f'weight: expected a number >= 0 (m per unit visibility), got {weight!r}')
    step = model.task.scenario.step_distance
    moves = _is_move(model)
    if model.layers > 1:  # a wait or a turn goes somewhere new: the node at another layer
        moves |= model.successors != np.arange(model.size)[:, None]
    return _cheapest_path(
        model,
        step + weight * model.step_visibility,
        ~model.step_seen & moves,
        step * _moves_to_goal(model),
    )


# --- the exact optimum --------------------------------------------------------------------------


class ValueIterationResult(NamedTuple):
    optimal_return: float  # expected return from the start with the whole step limit ahead
    values: np.ndarray  # (places,) the same from every place
    q: np.ndarray  # (places, actions) action values with the whole step limit ahead
    policy: np.ndarray  # (places,) greedy action of q (first maximal)
    converged: bool  # one more step of horizon would not change the start's value
    horizon: int
    gamma: float
    slip: float


def step_terms(model: LatticeModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step (place, direction): (probability of detection, reward if detected, reward
    otherwise), judged on the step's visibility at the place it enters.

    Detection is judged first, then the goal (``reward.step_outcome``'s order); in 'threshold'
    mode the probability is 0 or 1.
    """
    scenario = model.task.scenario
    weights = scenario.rewards
    threshold = scenario.detection_threshold
    visibility = model.step_visibility
    if scenario.detection_mode == 'threshold':
        p_detected = model.step_seen.astype(np.float64)
    else:
        p_detected = np.vectorize(lambda v: detection_probability(v, threshold))(visibility)
    distance = model.distance[model.successors]
    at_goal = model.goal[model.successors]
    # The reward functions are sums and products of their arguments: given arrays, they give
    # each element what they give the element as a float, bit for bit, at numpy's speed.
    caught = detection_reward(distance, weights)
    radius = model.task.goal.radius
    safe = np.where(
        at_goal,
        success_reward(distance, radius, weights),
        step_reward(visibility, distance, weights),
    )
    return p_detected, caught, safe


def value_iteration(
    model: LatticeModel, slip: float = 0.0, gamma: float = 1.0, horizon: int | None = None
) -> ValueIterationResult:
    """Optimal expected return and policy by backward induction over ``horizon`` steps (default:
    the scenario's step limit), V_0 = 0 (the episode is truncated); over (node, bin) places
    where lights move, so exact with time."""
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f'gamma: expected a number in [0, 1], got {gamma!r}')
    horizon = model.task.step_limit if horizon is None else int(horizon)
    moves = action_distribution(slip, model.num_actions)  # (actions, directions)
    p_detected, caught, safe = step_terms(model)
    # probability the episode continues after each step
    goes_on = (1.0 - p_detected) * ~model.goal[model.successors]
    immediate = p_detected * caught + (1.0 - p_detected) * safe  # (places, directions)
    values = np.zeros(model.size)
    previous = values
    q = np.zeros((model.size, model.num_actions))
    continues = gamma * goes_on
    exact_moves = slip == 0.0 and np.array_equal(moves, np.eye(model.num_actions))
    successors = model.successors
    if exact_moves:
        # Without slip, each action goes where it says: q is the outcome itself (bit for bit).
        # Laid out (directions, places), the max over actions is an elementwise maximum of
        # contiguous rows, several times faster than a max along short rows.
        successors, continues, immediate = (
            np.ascontiguousarray(a.T) for a in (successors, continues, immediate)
        )
        q = q.T
    for _ in range(horizon):
        outcome = np.take(values, successors)  # (places, directions), then in place:
        outcome *= continues
        outcome += immediate  # immediate + continues * values[successors]
        q = outcome if exact_moves else outcome @ moves.T  # (places, actions)
        previous, values = values, q.max(axis=0 if exact_moves else 1)
    if exact_moves:
        q = np.ascontiguousarray(q.T)
    # Places that cannot reach the goal keep losing value with every step of horizon; what
    # matters is whether the step limit binds from the start.
    converged = bool(abs(values[model.start] - previous[model.start]) <= 1e-9)
    return ValueIterationResult(
        float(values[model.start]),
        values,
        q,
        q.argmax(axis=1),
        converged,
        horizon,
        float(gamma),
        float(slip),
    )


def follow(
    model: LatticeModel, choose: Callable[[int], int], limit: int | None = None
) -> list[int]:
    """The deterministic path of places (no slip) from the start taking action choose(i) at
    place i, until a step ends the episode, the step limit, or a place without an action
    (choose(i) < 0: a policy that never saw it)."""
    limit = model.task.step_limit if limit is None else limit
    seen = model.step_seen
    path = [model.start]
    for _ in range(limit):
        here = path[-1]
        action = int(choose(here))
        if action < 0:
            break
        i = int(model.successors[here, action])
        path.append(i)
        if model.goal[i] or seen[here, action]:
            break
    return path


def baseline_paths(
    model: LatticeModel, weight: float = DEFAULT_DARK_PATH_WEIGHT
) -> dict[str, tuple[list[int] | None, PathResult | None]]:
    """{'A*': ..., 'Dark Path': ..., 'value iteration': ...}: each path and how it went."""
    optimum = value_iteration(model)
    paths = {
        'A*': astar(model),
        'Dark Path': dark_path(model, weight),
        'value iteration': follow(model, lambda i: int(optimum.policy[i])),
    }
    return {
        name: (path, None if path is None else walk(model, path)) for name, path in paths.items()
    }


def optimal_path(scenario, goal: str | None, poses: bool = False):
    """The value-iteration optimum on the move lattice: (points (n, 2), PathResult); with
    ``poses``, the points are (n, 3) with the yaw (rad) of each place's heading (to draw the
    robot's footprint)."""
    model = LatticeModel.build(StealthTask(scenario, goal))
    optimum = value_iteration(model)
    path = follow(model, lambda i: int(optimum.policy[i]))
    result = walk(model, path)
    if not poses:
        return result.points, result
    yaws = model.heading_of(path[: len(result.points)]) * (np.pi / 2)
    return np.column_stack([result.points, yaws]), result
