"""Covert paths for Nav2's planner interface, on the robot's move lattice (no rclpy).

A request (start, goal, planner id, the lights' time) becomes a path of lattice nodes, each
with the time to be there, or a ``PlanError`` carrying Nav2's error name
(``nav2_msgs/action/ComputePathToPose`` result codes) and one line saying why. Planner ids:

- ``covert`` (the default: '' and Nav2's default id ``GridBased`` too): value iteration's
  optimum (``stealth_core.planners``) on the time-expanded lattice where lights move, followed
  greedily from the start's place (node, bin of the lights' cycle, heading where lights weigh
  exposure): the path ``optimal_path`` gives.
- ``dark_path``: Dark Path (A* with a light cost, never entering a seen step), time-aware.
- ``astar``: the shortest path, blind to the lights.
- ``policy``: the greedy actions of a tabular policy saved by ``stealth train``
  (``stealth_agent.policy_store``), refused when it was learned on another map or lights.

Every path is judged before it is returned, step by step on the light model
(``LatticeModel.step_seen``: the most light along each step, sampled in space and time): a path
that is seen, or that does not reach the goal within the step limit, is NO_VALID_PATH, never an
answer. A planner that ignores the lights (astar) therefore answers only where the shortest
path happens to be dark.

What is cached, per scene (its grid and lights' SHA-256) and task numbers: the lattice model
(the expensive part: every step's visibility at every bin); per goal point: value iteration's
greedy policy. A request for a cached goal only follows the policy.

The lattice is anchored at the scenario's start (or, for a scene from topics, at the start of
the first request on that scene, as the environment anchors it at the episode's); a request's
start is snapped to the nearest node the robot fits at (within one step), which is the path's
first pose. A goal of the scenario keeps its own radius; any other goal point has
``goal_radius``.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
import dataclasses
import math
import time
from typing import NamedTuple

import numpy as np
from stealth_core import exposure
from stealth_core.lattice_model import LatticeModel
from stealth_core.light_cycle import TimingError, check_timing
from stealth_core.move_lattice import MoveLattice
from stealth_core.planners import (
    DEFAULT_DARK_PATH_WEIGHT,
    astar,
    dark_path,
    follow,
    value_iteration,
)
from stealth_core.reward import RewardWeights
from stealth_core.scenario import Goal, Scenario
from stealth_core.task import StealthTask

from stealth_nav2.plan_errors import PlanError
from stealth_nav2.policy_behaviour import greedy_actions
from stealth_nav2.request_poses import check_on_map, goal_label
from stealth_nav2.scene_source import Scene

PLANNER_IDS = ('covert', 'dark_path', 'astar', 'policy')
DEFAULT_PLANNER = PLANNER_IDS[0]
# Nav2's default planner id (nav2_params.yaml's planner_plugins, the default behaviour trees'
# PlannerSelector): an unchanged Nav2 setup asks for it, and gets the covert optimum.
PLANNER_ALIASES = {'': DEFAULT_PLANNER, 'GridBased': DEFAULT_PLANNER}
_SAME_POINT = 1e-6  # m: a request goal this close to a scenario goal is that goal


@dataclasses.dataclass(frozen=True)
class TaskNumbers:
    """The task's numbers for a scene from topics (a scenario file brings its own)."""

    robot_radius: float = 0.2  # m
    step_distance: float = 0.5  # m per lattice move
    goal_radius: float = 0.5  # m
    detection_threshold: float = 0.3
    step_limit: int = 400  # moves (and waits) per path leg
    phase_bins: int = 8  # bins of the moving lights' joint cycle
    step_seconds: float = 0.0  # s per step where lights move; 0: one bin


class Pose(NamedTuple):
    x: float
    y: float
    yaw: float = 0.0


@dataclasses.dataclass(frozen=True)
class Plan:
    """A path: poses (n, 3) x, y, yaw in the scene's frame at lattice nodes; times (n,) s after
    the request at which to be at each; how it went."""

    poses: np.ndarray
    times: np.ndarray
    planner_id: str
    steps: int  # lattice steps taken (moves, waits, turns)
    peak_visibility: float  # the most light along the path (all its steps)
    cached: bool  # the lattice model and the goal's values came from the cache


@dataclasses.dataclass(eq=False)
class _Setting:
    """One scene's planning state: its scenario, lattice model and per-goal policies."""

    scenario: Scenario
    model: LatticeModel
    node_index: dict
    policies: OrderedDict  # goal key -> (model for the goal, greedy action per place)


class CovertPlanner:
    """Plans on the latest scene, caching per scene and goal (see the module).

    numbers: the task's numbers for scenes from topics; policy: a loaded
    ``stealth_agent.policy_store.SavedPolicy`` for planner id 'policy' (None: refused);
    cache_goals: goals whose values are kept per scene.
    """

    def __init__(
        self,
        numbers: TaskNumbers | None = None,
        dark_path_weight: float = DEFAULT_DARK_PATH_WEIGHT,
        policy=None,
        cache_goals: int = 16,
    ):
        self.numbers = numbers or TaskNumbers()
        self.dark_path_weight = float(dark_path_weight)
        self.policy = policy
        self.cache_goals = int(cache_goals)
        self._key = None
        self._setting: _Setting | None = None

    # --- requests -------------------------------------------------------------------------

    def plan(
        self,
        scene: Scene,
        start: Pose,
        goal: Pose,
        planner_id: str = '',
        t: float = 0.0,
        max_time: float | None = None,
    ) -> Plan:
        """A path from start to goal for lights at time t (s of the lights' clock) when the
        robot is at the start; max_time: seconds of planning after which it is TIMEOUT."""
        return self.plan_through(scene, start, [goal], planner_id, t, max_time)

    def plan_through(
        self,
        scene: Scene,
        start: Pose,
        goals: Sequence[Pose],
        planner_id: str = '',
        t: float = 0.0,
        max_time: float | None = None,
    ) -> Plan:
        """A path through the goals in order, each leg starting where the last ended (the
        same node, time and heading), as Nav2's planner server joins its legs."""
        planner_id = PLANNER_ALIASES.get(planner_id, planner_id)
        if planner_id not in PLANNER_IDS:
            raise PlanError(
                'INVALID_PLANNER',
                f'planner id {planner_id!r} is invalid; planner ids are: {" ".join(PLANNER_IDS)}'
                " (and GridBased, Nav2's default, for covert)",
            )
        if not goals:
            raise PlanError('NO_VIAPOINTS_GIVEN', 'no goals given: expected at least one pose')
        clock = _Deadline(max_time)
        occupancy = scene.map
        check_on_map(occupancy, start, 'START', 'start')
        for k, goal in enumerate(goals):
            check_on_map(occupancy, goal, 'GOAL', goal_label(k, len(goals)))
        setting, cached = self._setting_for(scene, start)
        clock.check('building the lattice model')
        place, t0 = self._start_place(setting, start, t)
        places, all_cached = [place], cached
        for goal in goals:
            leg, leg_cached = self._leg(setting, planner_id, places[-1], goal, clock)
            places += leg[1:]
            all_cached = all_cached and leg_cached
        return self._plan_of(setting, places, goals[-1].yaw, t0 - t, planner_id, all_cached)

    # --- the scene ------------------------------------------------------------------------

    @property
    def model(self) -> LatticeModel | None:
        """The current scene's lattice model (None before the first scene)."""
        return None if self._setting is None else self._setting.model

    def prepare(self, scene: Scene, start: Pose | None = None) -> None:
        """Build the scene's lattice model now (the slow part of a first request); a scene
        from topics needs the start its lattice is anchored at."""
        self._setting_for(scene, start)

    def _setting_for(self, scene: Scene, start: Pose | None) -> tuple[_Setting, bool]:
        """The scene's setting, built when the scene (or the task numbers) changed; a scene
        from topics is anchored at this start."""
        key = (scene.key, self.numbers if scene.scenario is None else None)
        if self._setting is not None and self._key == key:
            return self._setting, True
        if scene.scenario is None and start is None:
            raise ValueError('a scene from topics is anchored at a start: give one')
        scenario = scene.scenario or scenario_of(scene, self.numbers, start[:2])
        model = LatticeModel.build(StealthTask(scenario))
        node_index = {node: i for i, node in enumerate(model.nodes)}
        self._key, self._setting = key, _Setting(scenario, model, node_index, OrderedDict())
        return self._setting, False

    def _start_place(self, setting: _Setting, start: Pose, t: float) -> tuple[int, float]:
        """The place the robot starts at, and the time (>= t) it is there: where lights move,
        the next boundary of a bin of their cycle (the model's steps start on them)."""
        model = setting.model
        node = _fitting_node(model.task.lattice, start.x, start.y, 1.0)
        if node is None:
            raise PlanError(
                'START_OCCUPIED',
                f'start ({start.x:.2f}, {start.y:.2f}): no lattice node within one step '
                f'({model.task.scenario.step_distance:g} m) where the robot fits (robot_radius '
                f'{model.task.scenario.robot_radius:g} m from walls and unknown cells)',
            )
        place, t0 = setting.node_index[node], float(t)
        timing = model.task.timing
        if timing is not None:
            cycle_bin = math.ceil(t / timing.bin_seconds - 1e-9)
            t0 = cycle_bin * timing.bin_seconds
            place += (cycle_bin % model.cycle_bins) * len(model.nodes)
        if model.headings > 1:
            place += exposure.heading_of(start.yaw) * model.cycle_bins * len(model.nodes)
        return place, t0

    # --- one leg --------------------------------------------------------------------------

    def _leg(self, setting, planner_id, place, goal: Pose, clock) -> tuple[list[int], bool]:
        """The places of one leg from place to the goal (place first), judged."""
        model, cached = self._goal_model(setting, goal)
        model = dataclasses.replace(model, start=place)
        if planner_id == 'covert':
            if cached is None:
                greedy = value_iteration(model).policy
                self._remember(setting, goal, model, greedy)
                clock.check('value iteration')
            else:
                greedy = cached
            path = follow(model, lambda i: greedy[i])
        elif planner_id == 'policy':
            actions = self._policy_actions(setting, model)
            path = follow(model, lambda i: actions[i])
        elif planner_id == 'dark_path':
            path = dark_path(model, self.dark_path_weight)
        else:
            path = astar(model)
        clock.check(f'planner {planner_id}')
        _judge(model, path, planner_id, goal)
        return path, cached is not None

    def _goal_model(self, setting: _Setting, goal: Pose):
        """(the model with this goal, its cached greedy policy or None)."""
        target = self._goal_of(setting, goal)
        key = (target.x, target.y, target.radius)
        if key in setting.policies:
            setting.policies.move_to_end(key)
            return setting.policies[key]
        lattice = setting.model.task.lattice
        if not lattice.nodes_within(target.x, target.y, target.radius):
            raise PlanError(
                'GOAL_OCCUPIED',
                f'goal ({goal.x:.2f}, {goal.y:.2f}): no lattice node within the goal radius '
                f'{target.radius:g} m where the robot fits (robot_radius '
                f'{setting.scenario.robot_radius:g} m from walls and unknown cells)',
            )
        base = setting.model
        distance = np.hypot(base.points[:, 0] - target.x, base.points[:, 1] - target.y)
        model = dataclasses.replace(
            base,
            task=StealthTask(setting.scenario, target),
            distance=distance,
            goal=distance <= target.radius,
        )
        return model, None

    def _goal_of(self, setting: _Setting, goal: Pose) -> Goal:
        for known in setting.scenario.goals.values():
            if math.hypot(known.x - goal.x, known.y - goal.y) <= _SAME_POINT:
                return known
        return Goal('request', float(goal.x), float(goal.y), setting.scenario.goal_radius)

    def _remember(self, setting: _Setting, goal: Pose, model, greedy) -> None:
        target = self._goal_of(setting, goal)
        setting.policies[(target.x, target.y, target.radius)] = (model, greedy)
        while len(setting.policies) > self.cache_goals:
            setting.policies.popitem(last=False)

    def _policy_actions(self, setting: _Setting, model: LatticeModel):
        """The saved policy's greedy action at each place (the first maximal, as argmax), -1
        where it never saw the state."""
        return greedy_actions(self.policy, setting.scenario, model)

    # --- the answer -----------------------------------------------------------------------

    def _plan_of(self, setting, places, goal_yaw, delay, planner_id, cached) -> Plan:
        model = setting.model
        points = model.points[places]
        if model.headings > 1:
            yaws = model.heading_of(places) * (math.pi / 2)
        else:
            yaws = _yaws_along(points)
        yaws = np.asarray(yaws, dtype=np.float64)
        yaws[-1] = goal_yaw
        steps = len(places) - 1
        times = delay + np.arange(len(places)) * model.task.step_seconds
        peak = 0.0
        for i, j in zip(places, places[1:], strict=False):
            peak = max(peak, float(model.step_visibility[i, model.direction(i, j)]))
        poses = np.column_stack([points, yaws])
        return Plan(poses, times, planner_id, steps, peak, cached)


def scenario_of(scene: Scene, numbers: TaskNumbers, anchor: tuple[float, float]) -> Scenario:
    """The Scenario of a scene from topics, with these task numbers, its lattice anchored at
    ``anchor`` (the robot's start at the first request, as the environment anchors its lattice
    at the episode's start), or at the nearest node of that grid the robot fits at.
    PlanError START_OCCUPIED when none fits, UNKNOWN when the lights' timing does not fit the
    phase bins."""
    occupancy, step = scene.map, numbers.step_distance
    lattice = MoveLattice(occupancy, anchor, step, numbers.robot_radius)
    node = lattice.nearest_valid_node(*anchor)
    if node is None:
        raise PlanError(
            'START_OCCUPIED',
            f'the map from {scene.source} has no place the robot fits (robot_radius '
            f'{numbers.robot_radius:g} m, step {step:g} m)',
        )
    anchor = lattice.node_to_point(node)
    try:
        timing = check_timing(
            scene.lights, numbers.phase_bins, numbers.step_seconds or None
        ) if scene.has_moving_lights else None  # fmt: skip
    except TimingError as error:
        raise PlanError('UNKNOWN', f'the lights from {scene.source}: {error}') from None
    goal = Goal('hard', *anchor, numbers.goal_radius)
    return Scenario(
        name='scene',
        path=scene.source,
        map_path=scene.source,
        map=occupancy,
        start=(*anchor, 0.0),
        goals={'hard': goal},
        default_goal='hard',
        lights=scene.lights,
        robot_radius=numbers.robot_radius,
        step_distance=step,
        state_cell=step,
        goal_radius=numbers.goal_radius,
        detection_threshold=numbers.detection_threshold,
        detection_mode='threshold',
        step_limit=numbers.step_limit,
        rewards=RewardWeights(),
        timing=timing,
    )


def densify(poses: np.ndarray, times: np.ndarray, spacing: float):
    """(poses, times) with poses added along each straight segment so that none is longer
    than ``spacing`` m (times interpolated, each added pose facing along its segment);
    spacing 0: unchanged (the lattice nodes only)."""
    if spacing <= 0 or len(poses) < 2:
        return poses, times
    out_poses, out_times = [poses[0]], [times[0]]
    for (a, b), (ta, tb) in zip(
        zip(poses, poses[1:], strict=False), zip(times, times[1:], strict=False), strict=True
    ):
        pieces = max(1, math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / spacing - 1e-9))
        heading = a[2] if pieces == 1 else math.atan2(b[1] - a[1], b[0] - a[0])
        for k in range(1, pieces):
            f = k / pieces
            out_poses.append((a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), heading))
            out_times.append(ta + f * (tb - ta))
        out_poses.append(b)
        out_times.append(tb)
    return np.asarray(out_poses, dtype=np.float64), np.asarray(out_times, dtype=np.float64)


# --- helpers ------------------------------------------------------------------------------------


class _Deadline:
    """TIMEOUT once planning has taken more than max_time s (None: never), checked between
    its stages (the work of a stage is not interrupted; what it computed stays cached)."""

    def __init__(self, max_time: float | None):
        self.max_time = max_time
        self.started = time.perf_counter()

    def check(self, stage: str) -> None:
        if self.max_time is None:
            return
        took = time.perf_counter() - self.started
        if took > self.max_time:
            raise PlanError(
                'TIMEOUT',
                f'planning took {took:.3f} s, more than max_planning_time {self.max_time:g} s '
                f'(after {stage})',
            )


def _fitting_node(lattice: MoveLattice, x: float, y: float, steps: float):
    """The valid node nearest (x, y) within ``steps`` steps, or None."""
    node = lattice.point_to_node(x, y)
    if lattice.is_valid(node):
        return node
    best, best_distance = None, steps * lattice.step + 1e-9
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            candidate = (node[0] + di, node[1] + dj)
            px, py = lattice.node_to_point(candidate)
            distance = math.hypot(px - x, py - y)
            if lattice.is_valid(candidate) and distance <= best_distance:
                best, best_distance = candidate, distance
    return best


def _judge(model: LatticeModel, path, planner_id: str, goal: Pose) -> None:
    """NO_VALID_PATH unless the path reaches the goal within the step limit, unseen."""
    to = f'to ({goal.x:.2f}, {goal.y:.2f})'
    start = model.points[model.start]
    where = f'from ({start[0]:.2f}, {start[1]:.2f}) {to}'
    limit = model.task.step_limit
    if path is None:
        raise PlanError(
            'NO_VALID_PATH', f'planner {planner_id}: no route {where} that no light sees'
        )
    threshold = model.task.scenario.detection_threshold
    for k, (i, j) in enumerate(zip(path, path[1:], strict=False), start=1):
        direction = model.direction(i, j)
        if model.step_seen[i, direction]:
            x, y = model.points[j]
            raise PlanError(
                'NO_VALID_PATH',
                f'planner {planner_id}: no covert route {where}: its path is seen at '
                f'({x:.2f}, {y:.2f}) after {k} steps (visibility '
                f'{model.step_visibility[i, direction]:.3f} >= detection threshold '
                f'{threshold:g})',
            )
    if not model.goal[path[-1]]:
        raise PlanError(
            'NO_VALID_PATH',
            f'planner {planner_id}: no covert route {where} within the step limit of {limit} '
            'steps',
        )
    if len(path) - 1 > limit:
        raise PlanError(
            'NO_VALID_PATH',
            f'planner {planner_id}: the route {where} takes {len(path) - 1} steps, more than '
            f'the step limit {limit}',
        )


def _yaws_along(points: np.ndarray) -> np.ndarray:
    """Each pose facing the next pose that is elsewhere (waits keep the way they face)."""
    yaws = np.zeros(len(points))
    following = 0.0
    for k in range(len(points) - 2, -1, -1):
        dx, dy = points[k + 1] - points[k]
        if dx or dy:
            following = math.atan2(dy, dx)
        yaws[k] = following
    if len(points) > 1:
        yaws[-1] = yaws[-2]
    return yaws
