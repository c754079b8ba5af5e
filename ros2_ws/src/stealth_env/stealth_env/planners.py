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

Moving lights are frozen at time ``t`` (the model is not time-aware); the shipped scenarios'
lights are static. Walls: a move into a wall leaves the robot where it is, and still counts as
a step (the model's successor of a blocked move is the node itself).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import dataclasses
import heapq
import math
from typing import NamedTuple

import numpy as np

from stealth_env.move_lattice import ACTIONS, Node
from stealth_env.reward import (
    Outcome,
    detection_probability,
    detection_reward,
    step_reward,
    success_reward,
)
from stealth_env.task import StealthTask

# The two moves at right angles to each action (0 up, 1 down, 2 left, 3 right).
PERPENDICULAR = ((2, 3), (2, 3), (0, 1), (0, 1))
DEFAULT_DARK_PATH_WEIGHT = 10.0  # m per unit of visibility: a 0.3 glimpse costs 3 m of detour


def action_distribution(slip: float) -> np.ndarray:
    """P[a, b]: probability that action a moves the robot in direction b."""
    if not 0.0 <= slip <= 1.0:
        raise ValueError(f'slip: expected a probability in [0, 1], got {slip!r}')
    matrix = np.eye(len(ACTIONS)) * (1.0 - slip)
    for action, sideways in enumerate(PERPENDICULAR):
        for direction in sideways:
            matrix[action, direction] += slip / 2
    return matrix


@dataclasses.dataclass(frozen=True, eq=False)
class LatticeModel:
    """The task on its move lattice as arrays over valid nodes (index order of
    ``MoveLattice.valid_nodes``).

    successors[i, b]: the node index a move in direction b from node i reaches (i itself when
    the move is blocked); visibility[i]: ``task.visibility`` at node i at time t (the per-point
    model); states[i]: the agent's float32 state there (``task.state_of``).
    """

    task: StealthTask
    t: float
    nodes: list[Node]
    points: np.ndarray  # (n, 2) float64, m
    states: np.ndarray  # (n, 2) float32
    successors: np.ndarray  # (n, 4) int
    visibility: np.ndarray  # (n,)
    distance: np.ndarray  # (n,) to the goal point, m
    goal: np.ndarray  # (n,) bool: within the goal's radius
    start: int

    @classmethod
    def build(cls, task: StealthTask, t: float = 0.0) -> LatticeModel:
        lattice = task.lattice
        nodes = list(lattice.valid_nodes())
        index = {node: i for i, node in enumerate(nodes)}
        points = np.array([lattice.node_to_point(node) for node in nodes], dtype=np.float64)
        successors = np.empty((len(nodes), len(ACTIONS)), dtype=np.int64)
        for i, node in enumerate(nodes):
            for action in range(len(ACTIONS)):
                target = lattice.successor(node, action)
                successors[i, action] = i if target is None else index[target]
        goal = task.goal
        distance = np.hypot(points[:, 0] - goal.x, points[:, 1] - goal.y)
        start = lattice.point_to_node(*task.scenario.start[:2])
        return cls(
            task=task,
            t=float(t),
            nodes=nodes,
            points=points,
            states=np.array([task.state_of(x, y) for x, y in points], dtype=np.float32),
            successors=successors,
            visibility=np.array([task.visibility(x, y, t) for x, y in points]),
            distance=distance,
            goal=np.array([task.distance_to_goal(x, y) <= goal.radius for x, y in points]),
            start=index[start],
        )

    @property
    def size(self) -> int:
        return len(self.nodes)

    @property
    def seen(self) -> np.ndarray:
        """(n,) bool: nodes at or above the detection threshold."""
        return self.visibility >= self.task.scenario.detection_threshold

    def judge(self, i: int, step_index: int):
        """``StealthTask.judge`` of arriving at node i with action number step_index."""
        x, y = self.points[i]
        return self.task.judge(x, y, self.t, step_index, visibility=self.visibility[i])


# --- judging paths ------------------------------------------------------------------------------


class PathResult(NamedTuple):
    """A path (node indices from the start) walked through the task, as an episode would be."""

    outcome: Outcome | None  # None: the path ended before anything ended the episode
    total_reward: float  # undiscounted, rewards after the first state
    steps: int
    peak_visibility: float
    accumulated_visibility: float
    path_length: float  # m
    points: np.ndarray  # (steps + 1, 2): the poses actually walked (cut at the end)

    @property
    def detected(self) -> bool:
        return self.outcome is Outcome.DETECTED


def walk(model: LatticeModel, path: Sequence[int]) -> PathResult:
    """Judge each node of the path in turn (the first is the start, not judged) until one ends
    the episode (goal, detection or the step limit)."""
    task = model.task
    stats = task.start_episode(*model.points[path[0]])
    outcome = None
    walked = 1
    for step_index, i in enumerate(path[1:], start=1):
        judgement = model.judge(i, step_index)
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
    entry_cost: np.ndarray,
    passable: np.ndarray,
    heuristic: np.ndarray,
) -> list[int] | None:
    """A* from the start to any goal node: a move into node j costs entry_cost[j] (>= the
    heuristic's drop, so the heuristic is consistent); only passable nodes are entered."""
    start = model.start
    if not passable[start]:
        return None
    best = {start: 0.0}
    came_from: dict[int, int] = {}
    frontier = [(float(heuristic[start]), 0.0, start)]
    closed = set()
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
        for j in set(model.successors[i].tolist()) - {i}:
            if not passable[j] or j in closed:
                continue
            candidate = cost + float(entry_cost[j])
            if candidate < best.get(j, math.inf):
                best[j] = candidate
                came_from[j] = i
                heapq.heappush(frontier, (candidate + float(heuristic[j]), candidate, j))
    return None


def _moves_to_goal(model: LatticeModel) -> np.ndarray:
    """(n,) Manhattan distance in moves to the nearest goal node: an admissible heuristic."""
    nodes = np.asarray(model.nodes)
    targets = nodes[model.goal]
    if targets.size == 0:
        return np.zeros(model.size)
    gaps = np.abs(nodes[:, None, :] - targets[None, :, :]).sum(axis=2)
    return gaps.min(axis=1).astype(np.float64)


def astar(model: LatticeModel) -> list[int] | None:
    """The shortest path (fewest moves) from the start to the goal, ignoring the lights."""
    step = model.task.scenario.step_distance
    return _cheapest_path(
        model,
        np.full(model.size, step),
        np.ones(model.size, dtype=bool),
        step * _moves_to_goal(model),
    )


def dark_path(model: LatticeModel, weight: float = DEFAULT_DARK_PATH_WEIGHT) -> list[int] | None:
    """The cheapest path with cost step_distance + weight * visibility per node entered, through
    nodes below the detection threshold only; None when every way is seen."""
    if not (math.isfinite(weight) and weight >= 0):
        raise ValueError(f'weight: expected a number >= 0 (m per unit visibility), got {weight!r}')
    step = model.task.scenario.step_distance
    return _cheapest_path(
        model,
        step + weight * model.visibility,
        ~model.seen,
        step * _moves_to_goal(model),
    )


# --- the exact optimum --------------------------------------------------------------------------


class ValueIterationResult(NamedTuple):
    optimal_return: float  # expected return from the start with the whole step limit ahead
    values: np.ndarray  # (n,) the same from every node
    q: np.ndarray  # (n, 4) action values with the whole step limit ahead
    policy: np.ndarray  # (n,) greedy action of q (first maximal)
    converged: bool  # one more step of horizon would not change the start's value
    horizon: int
    gamma: float
    slip: float


def arrival_terms(model: LatticeModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per node entered: (probability of detection, reward if detected, reward otherwise).

    Detection is judged first, then the goal (``reward.step_outcome``'s order); in 'threshold'
    mode the probability is 0 or 1.
    """
    scenario = model.task.scenario
    weights = scenario.rewards
    threshold = scenario.detection_threshold
    if scenario.detection_mode == 'threshold':
        p_detected = model.seen.astype(np.float64)
    else:
        p_detected = np.array([detection_probability(v, threshold) for v in model.visibility])
    caught = np.array([detection_reward(d, weights) for d in model.distance])
    radius = model.task.goal.radius
    safe = np.array(
        [
            success_reward(d, radius, weights) if at_goal else step_reward(v, d, weights)
            for v, d, at_goal in zip(model.visibility, model.distance, model.goal, strict=True)
        ]
    )
    return p_detected, caught, safe


def value_iteration(
    model: LatticeModel, slip: float = 0.0, gamma: float = 1.0, horizon: int | None = None
) -> ValueIterationResult:
    """Optimal expected return and policy by backward induction over ``horizon`` steps (default:
    the scenario's step limit), V_0 = 0 (the episode is truncated)."""
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f'gamma: expected a number in [0, 1], got {gamma!r}')
    horizon = model.task.step_limit if horizon is None else int(horizon)
    moves = action_distribution(slip)  # (actions, directions)
    p_detected, caught, safe = arrival_terms(model)
    goes_on = (1.0 - p_detected) * ~model.goal  # probability the episode continues after entry
    immediate = p_detected * caught + (1.0 - p_detected) * safe
    values = np.zeros(model.size)
    previous = values
    q = np.zeros((model.size, len(ACTIONS)))
    for _ in range(horizon):
        arrival = immediate + gamma * goes_on * values  # (n,): worth of entering each node
        q = arrival[model.successors] @ moves.T  # (n, directions) -> (n, actions)
        previous, values = values, q.max(axis=1)
    # Nodes that cannot reach the goal keep losing value with every step of horizon; what
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
    """The deterministic path (no slip) from the start taking action choose(i) at node i, until
    a node ends the episode or the step limit."""
    limit = model.task.step_limit if limit is None else limit
    seen = model.seen
    path = [model.start]
    for _ in range(limit):
        i = int(model.successors[path[-1], choose(path[-1])])
        path.append(i)
        if model.goal[i] or seen[i]:
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


def optimal_path(scenario, goal: str):
    """The value-iteration optimum on the move lattice: (points (n, 2), PathResult)."""
    model = LatticeModel.build(StealthTask(scenario, goal))
    optimum = value_iteration(model)
    result = walk(model, follow(model, lambda i: int(optimum.policy[i])))
    return result.points, result
