"""The task of one scenario and goal, judged step by step: the one place that says what a pose
is worth, shared by the ROS environment node and the in-process Gymnasium environment so both
judge every step identically (pure Python + numpy, no rclpy).

    task = StealthTask(scenario, goal='hard', rng=np.random.default_rng(seed))
    state = task.state_of(x_estimate, y_estimate)         # what the agent sees
    judgement = task.judge(x_true, y_true, t, step_index)  # what it paid; whether it ends
    stats = task.start_episode(x_true, y_true, episode=0)
    stats.add(x_true, y_true, judgement)
    summary = stats.summary(judgement.outcome)             # EpisodeSummary's fields

Decisions:

- **State**: ``[x, y]`` of a pose rounded to the nearest point of the state grid
  ``start + k*state_cell`` (k an integer, per axis): ``start + floor((x - start)/cell + 1/2)
  * cell``, i.e. cells of ``state_cell`` centred on those points. The robot's move lattice is
  anchored at the start too, so (with ``state_cell`` = ``step_distance``, as in every shipped
  scenario) each lattice node is the centre of its own cell and its state is the node itself:
  localisation error of up to half a cell keeps the node's state. (The original truncated
  AMCL's pose to multiples of the cell, which put every node on a cell edge: a few cm of error
  then moved about one step in six into the neighbouring state.) ``floor(u + 1/2)`` rather
  than Python's round-half-even, so every cell is the same size (on both sides of 0 too, for
  maps with negative coordinates such as lgfloor); a point exactly half-way belongs to the cell
  above.
- **Visibility** of a pose at time t is the per-point lighting model
  (``lighting.point_visibility``) at the pose itself: the definition of the model, not the
  cell-centre field. It is computed by ``visibility.PointVisibility``, equal to the reference to
  the last bit, with its lines of sight cached per lamp cell (tens of microseconds a step).
  Callers that judge the same points over and over (the Gym environment, the planners) may
  fill a table once with ``visibility`` and pass the value to ``judge``.
- **Judging** is ``reward.step_outcome`` with the goal's own radius: detection first (in
  'probabilistic' mode drawn from ``task.rng``), then the goal, then an ordinary step, which is
  terminal with ``Outcome.TIMEOUT`` when ``step_index`` (actions taken so far, this one
  included, from 1) reaches ``step_limit``.
- **Episode statistics** follow stealth_interfaces/EpisodeSummary: the return sums the rewards
  after the first state (undiscounted); peak and accumulated visibility are over the judged
  poses after each action (not the start); the path length adds up the straight distances
  between consecutive true poses.
"""

from __future__ import annotations

import dataclasses
from functools import cached_property
import math
from typing import NamedTuple

import numpy as np

from stealth_env.move_lattice import ACTIONS, MoveLattice
from stealth_env.reward import Outcome, detection_reward, step_outcome, success_reward
from stealth_env.scenario import Goal, Scenario
from stealth_env.visibility import PointVisibility, scenario_point_visibility

NUM_ACTIONS = len(ACTIONS)  # 0 up (+y), 1 down (-y), 2 left (-x), 3 right (+x)
_CELL_TOLERANCE = 1e-9  # in cells: a map edge this close to a cell boundary counts as on it


class StepJudgement(NamedTuple):
    """What one step paid and why; the fields StepInfo reports besides poses and state."""

    reward: float
    terminal: bool
    outcome: Outcome | None  # None while the episode goes on
    visibility: float  # total visibility at the judged pose (unitless)
    distance_to_goal: float  # from the judged pose to the goal point (m)
    detected: bool


class EpisodeSummaryFields(NamedTuple):
    """stealth_interfaces/EpisodeSummary without its header, field for field."""

    episode: int
    outcome: int  # an Outcome value
    steps: int
    total_reward: float
    peak_visibility: float
    accumulated_visibility: float
    path_length: float
    final_distance_to_goal: float
    goal: str


@dataclasses.dataclass
class EpisodeStats:
    """Running totals of one episode; start with ``StealthTask.start_episode``."""

    goal: str
    episode: int
    x: float  # the last true pose (m)
    y: float
    final_distance_to_goal: float
    steps: int = 0
    total_reward: float = 0.0
    peak_visibility: float = 0.0
    accumulated_visibility: float = 0.0
    path_length: float = 0.0

    def add(self, x: float, y: float, judgement: StepJudgement) -> None:
        """Count one action that led to the true pose (x, y), judged as ``judgement``."""
        self.steps += 1
        self.total_reward += judgement.reward
        self.peak_visibility = max(self.peak_visibility, judgement.visibility)
        self.accumulated_visibility += judgement.visibility
        self.path_length += math.hypot(x - self.x, y - self.y)
        self.x, self.y = float(x), float(y)
        self.final_distance_to_goal = judgement.distance_to_goal

    def summary(self, outcome: Outcome | int) -> EpisodeSummaryFields:
        """EpisodeSummary's fields for an episode that ended with ``outcome``."""
        return EpisodeSummaryFields(
            episode=self.episode,
            outcome=int(Outcome(outcome)),
            steps=self.steps,
            total_reward=self.total_reward,
            peak_visibility=self.peak_visibility,
            accumulated_visibility=self.accumulated_visibility,
            path_length=self.path_length,
            final_distance_to_goal=self.final_distance_to_goal,
            goal=self.goal,
        )


class StealthTask:
    """One scenario with one goal: states, rewards and episode statistics.

    goal: a goal name of the scenario, a ``Goal``, or None for the scenario's default goal.
    rng: the generator 'probabilistic' detection draws from (required in that mode; a
    public attribute, so an environment can hand it its own generator on reset).
    """

    def __init__(
        self,
        scenario: Scenario,
        goal: str | Goal | None = None,
        rng: np.random.Generator | None = None,
    ):
        self.scenario = scenario
        self.goal = _resolve_goal(scenario, goal)
        self.rng = rng
        self.cell = float(scenario.state_cell)
        self.step_limit = int(scenario.step_limit)
        self._anchor = (float(scenario.start[0]), float(scenario.start[1]))  # state grid origin

    @property
    def title(self) -> str:
        """The environment's name in RLEnvDescription (policy files are checked against it)."""
        return f'stealth-nav: {self.scenario.name} ({self.goal.name})'

    @cached_property
    def lattice(self) -> MoveLattice:
        """The robot's move lattice (built on first use)."""
        return MoveLattice.from_scenario(self.scenario)

    # --- states ---------------------------------------------------------------------------------

    def state_of(self, x: float, y: float) -> tuple[float, float]:
        """The agent's state for a pose: (x, y) rounded to the nearest point of the state grid
        ``start + k*state_cell`` (see "State" in the module docstring)."""
        return (self._centre(x, self._anchor[0]), self._centre(y, self._anchor[1]))

    def _centre(self, value: float, anchor: float) -> float:
        return anchor + math.floor((float(value) - anchor) / self.cell + 0.5) * self.cell

    def move_target(self, x: float, y: float, action: int) -> tuple[float, float]:
        """Where action `action` (0 up, 1 down, 2 left, 3 right) takes a robot at (x, y): the
        lattice node it leads to from the nearest valid node, or that node itself when the map
        blocks the move, as in the lattice model (the robot knows the map and does not drive
        into a wall). Aiming every move at a node keeps a real robot on the lattice: errors of
        one move (tolerance, localisation, a bump) are corrected by the next. A pose whose nearest
        node is not valid (beside a wall, or an estimate gone astray) moves from the nearest
        valid node."""
        lattice = self.lattice
        node = lattice.point_to_node(x, y)
        if not lattice.is_valid(node):  # beside a wall, or localisation far off: the nearest
            node = lattice.nearest_valid_node(x, y)
        successor = lattice.successor(node, action)
        return lattice.node_to_point(node if successor is None else successor)

    def state_bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """(min, max) state over every point of the map: RLEnvDescription's state ranges."""
        x_min, y_min, x_max, y_max = self.scenario.map.bounds
        (x_anchor, y_anchor) = self._anchor
        high = (self._last_centre_below(x_max, x_anchor), self._last_centre_below(y_max, y_anchor))
        return self.state_of(x_min, y_min), high

    def _last_centre_below(self, value: float, anchor: float) -> float:
        """The state of the points just below ``value`` (the map's upper edge, excluded)."""
        last = math.ceil((value - anchor) / self.cell + 0.5 - _CELL_TOLERANCE) - 1
        return anchor + last * self.cell

    def reward_bounds(self) -> tuple[float, float]:
        """(max_reward, reward_range) of one step, for RLEnvDescription.

        The best step reaches the goal point itself; the worst is detected at the far corner
        of the map (which ``check_well_posed`` proves is below any undetected step).
        """
        weights = self.scenario.rewards
        best = success_reward(0.0, self.goal.radius, weights)
        worst = detection_reward(self.max_distance, weights)
        return best, best - worst

    @property
    def max_distance(self) -> float:
        """The largest distance to the goal any point of the map can have (m)."""
        x_min, y_min, x_max, y_max = self.scenario.map.bounds
        return max(
            math.hypot(x - self.goal.x, y - self.goal.y)
            for x in (x_min, x_max)
            for y in (y_min, y_max)
        )

    def description(self, stochastic: bool = False) -> dict:
        """RLEnvDescription's fields. stochastic: whether moves or localisation are noisy."""
        low, high = self.state_bounds()
        max_reward, reward_range = self.reward_bounds()
        lattice = self.lattice
        states = {self.state_of(*lattice.node_to_point(n)) for n in lattice.valid_nodes()}
        return {
            'num_actions': NUM_ACTIONS,
            'num_states': len(states),
            'min_state_range': list(low),
            'max_state_range': list(high),
            'max_reward': max_reward,
            'reward_range': reward_range,
            'stochastic': bool(stochastic),
            'episodic': True,
            'title': self.title,
        }

    # --- judging --------------------------------------------------------------------------------

    def visibility(self, x: float, y: float, t: float = 0.0) -> float:
        """Total visibility at (x, y) m at time t s, by the per-point model (ValueError off the
        map)."""
        return self._point_visibility(x, y, t)

    @cached_property
    def _point_visibility(self) -> PointVisibility:
        return scenario_point_visibility(self.scenario)

    def distance_to_goal(self, x: float, y: float) -> float:
        return math.hypot(x - self.goal.x, y - self.goal.y)

    def judge(
        self,
        x: float,
        y: float,
        t: float,
        step_index: int,
        visibility: float | None = None,
    ) -> StepJudgement:
        """Judge the true pose (x, y) reached at time t by action number ``step_index`` (from 1).

        visibility: the pose's visibility at t when the caller already has it (it must be
        ``self.visibility(x, y, t)``); computed otherwise.
        """
        if isinstance(step_index, bool) or not isinstance(step_index, int | np.integer):
            raise ValueError(f'step_index: expected an integer >= 1, got {step_index!r}')
        if step_index < 1:
            raise ValueError(f'step_index: expected an integer >= 1, got {step_index}')
        if visibility is None:
            visibility = self.visibility(x, y, t)
        distance = self.distance_to_goal(x, y)
        scenario = self.scenario
        result = step_outcome(
            visibility,
            distance,
            goal_radius=self.goal.radius,
            detection_threshold=scenario.detection_threshold,
            weights=scenario.rewards,
            detection_mode=scenario.detection_mode,
            rng=self.rng,
            timed_out=step_index >= self.step_limit,
        )
        return StepJudgement(
            result.reward,
            result.terminal,
            result.outcome,
            float(visibility),
            distance,
            result.outcome is Outcome.DETECTED,
        )

    def start_episode(self, x: float, y: float, episode: int = 0) -> EpisodeStats:
        """Statistics of an episode starting at the true pose (x, y)."""
        return EpisodeStats(
            goal=self.goal.name,
            episode=int(episode),
            x=float(x),
            y=float(y),
            final_distance_to_goal=self.distance_to_goal(x, y),
        )


def _resolve_goal(scenario: Scenario, goal: str | Goal | None) -> Goal:
    if goal is None:
        return scenario.goal
    if isinstance(goal, Goal):
        return goal
    if goal not in scenario.goals:
        raise ValueError(
            f'goal {goal!r}: scenario {scenario.name!r} has {", ".join(scenario.goals)}'
        )
    return scenario.goals[goal]
