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
import heapq
import math
from typing import NamedTuple

import numpy as np

from stealth_core.lattice_model import LatticeModel, action_distribution
from stealth_core.reward import (
    EpisodeOutcome,
    detection_probability,
    detection_reward,
    step_reward,
    success_reward,
)
from stealth_core.task import StealthTask

DEFAULT_DARK_PATH_WEIGHT = 10.0  # m per unit of visibility: a 0.3 glimpse costs 3 m of detour


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
    model: LatticeModel,
    slip: float = 0.0,
    gamma: float = 1.0,
    horizon: int | None = None,
    terms: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> ValueIterationResult:
    """Optimal expected return and policy by backward induction over ``horizon`` steps (default:
    the scenario's step limit), V_0 = 0 (the episode is truncated); over (node, bin) places
    where lights move, so exact with time. ``terms`` replaces the model's ``step_terms`` (a
    learner planning against a belief gives its own detection probabilities and rewards)."""
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f'gamma: expected a number in [0, 1], got {gamma!r}')
    horizon = model.task.step_limit if horizon is None else int(horizon)
    moves = action_distribution(slip, model.num_actions)  # (actions, directions)
    p_detected, caught, safe = step_terms(model) if terms is None else terms
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
