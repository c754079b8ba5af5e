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
- **Time** (scenarios with moving lights): the state grows by the features of
  ``state_features`` beyond x and y; today ``phase``, the bin of the lights' joint cycle
  (``stealth_core.light_cycle``) the time falls in, when the scenario sets ``phase_bins``. A fifth
  action, ``wait`` (4), keeps the robot at its node for one step; it exists only where lights
  move (``num_actions``). A step takes ``step_seconds`` of simulated time in-process; in ROS
  the simulator's reported time.
- **Heading** (scenarios with ``exposure``, ``stealth_core.exposure``): each light is weighed by
  how much of the robot it sees, which depends on the way the robot faces, so the state grows
  by ``heading``, the quarter turn nearest the pose's yaw (0 east, 1 north, 2 west, 3 south; a
  move leaves the robot facing its direction, a blocked move leaves the heading as it was).
  Where the scenario sets ``exposure.turn_actions``, two more actions turn a quarter left or
  right in place, each taking a step (``action_names``: the actions are numbered moves, then
  wait where lights move, then the turns). A step's samples then carry the robot's heading:
  the turn at the departure from the previous heading to the step's, then the drive facing
  the step's heading.
- **A step's visibility** is the most light the robot gets during it (``step_visibility``):
  the move (or the wait) is sampled at the map's resolution, each sample at its own time
  (the move's time shared out evenly along it), up to and including the arrival, so a robot
  cannot slip through a beam between two lattice nodes, nor sit still while a sweep crosses it.
- **Visibility** of a pose at time t is the per-point lighting model
  (``lighting.point_visibility``) at the pose itself: the definition of the model, not the
  cell-centre field. It is computed by ``visibility.PointVisibility``, equal to the reference to
  the last bit, with its lines of sight cached per lamp cell (tens of microseconds a step).
  Callers that judge the same points over and over (the Gym environment, the planners) may
  fill a table once with ``visibility`` and pass the value to ``judge``.
- **Judging** is ``reward.step_outcome`` with the goal's own radius: detection first (in
  'probabilistic' mode drawn from ``task.rng``), then the goal, then an ordinary step, which is
  terminal with ``EpisodeOutcome.TIMEOUT`` when ``step_index`` (actions taken so far, this one
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

from stealth_core import exposure
from stealth_core.move_lattice import ACTIONS, MoveLattice
from stealth_core.reward import EpisodeOutcome, detection_reward, step_outcome, success_reward
from stealth_core.scenario import Goal, Scenario
from stealth_core.visibility import PointVisibility, scenario_point_visibility

NUM_ACTIONS = len(ACTIONS)  # 0 up (+y), 1 down (-y), 2 left (-x), 3 right (+x)
WAIT = NUM_ACTIONS  # 4: stay one step (scenarios with moving lights only)
ACTION_NAMES = (*(name for name, _ in ACTIONS), 'wait')
TURNS = {'turn_left': 1, 'turn_right': -1}  # turn actions: quarter turns counter-clockwise
DEFAULT_STEP_SECONDS = 1.0  # s per step when the scenario does not say (no phase_bins)
_CELL_TOLERANCE = 1e-9  # in cells: a map edge this close to a cell boundary counts as on it


class StepJudgement(NamedTuple):
    """What one step paid and why; the fields StepInfo reports besides poses and state."""

    reward: float
    terminal: bool
    outcome: EpisodeOutcome | None  # None while the episode goes on
    visibility: float  # total visibility at the judged pose (unitless)
    distance_to_goal: float  # from the judged pose to the goal point (m)
    detected: bool


class EpisodeSummaryFields(NamedTuple):
    """stealth_interfaces/EpisodeSummary without its header, field for field."""

    episode: int
    outcome: int  # an EpisodeOutcome value
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

    def summary(self, outcome: EpisodeOutcome | int) -> EpisodeSummaryFields:
        """EpisodeSummary's fields for an episode that ended with ``outcome``."""
        return EpisodeSummaryFields(
            episode=self.episode,
            outcome=int(EpisodeOutcome(outcome)),
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
        self.timing = scenario.timing
        self.step_seconds = (
            self.timing.step_seconds if self.timing is not None else DEFAULT_STEP_SECONDS
        )
        self.footprint = scenario.exposure
        # Waiting is an action wherever time matters: lights that move, or a world that keeps
        # their timing with the lights unknown (``light_world``).
        timed = scenario.has_moving_lights or self.timing is not None
        names = ACTION_NAMES if timed else ACTION_NAMES[:NUM_ACTIONS]
        if self.footprint is not None and self.footprint.turn_actions:
            names += tuple(TURNS)
        self.action_names: tuple[str, ...] = names
        self.num_actions = len(names)
        # Features beyond (x, y), in order: (name, low, high) each.
        self.extra_features: tuple[tuple[str, float, float], ...] = ()
        if self.timing is not None:
            self.extra_features += (('phase', 0.0, float(self.timing.cycle_bins - 1)),)
        if self.footprint is not None:
            self.extra_features += (('heading', 0.0, float(exposure.HEADINGS - 1)),)
        samples = math.ceil(scenario.step_distance / scenario.map.resolution - 1e-9)
        self.step_samples = max(samples, 1)  # samples of a step, the arrival included

    @property
    def title(self) -> str:
        """The environment's name in RLEnvDescription (policy files are checked against it)."""
        return f'stealth-nav: {self.scenario.name} ({self.goal.name})'

    @cached_property
    def lattice(self) -> MoveLattice:
        """The robot's move lattice (built on first use)."""
        return MoveLattice.from_scenario(self.scenario)

    # --- states ---------------------------------------------------------------------------------

    @property
    def state_features(self) -> tuple[str, ...]:
        """The names of the state's dimensions, in order: x, y, then any extra features."""
        return ('x', 'y', *(name for name, _, _ in self.extra_features))

    @property
    def headings(self) -> int:
        """Headings of the state (1 when the state has no heading)."""
        return 1 if self.footprint is None else exposure.HEADINGS

    def turn_of(self, action: int) -> int:
        """Quarter turns (counter-clockwise) of a turn action; 0 for any other action."""
        return TURNS.get(self.action_names[action], 0) if 0 <= action < self.num_actions else 0

    def heading_in(self, state) -> int:
        """The lattice heading of a state (0 without headings)."""
        return int(state[len(self.state_features) - 1]) if self.footprint is not None else 0

    def heading_after(self, heading: int, action: int, moved: bool = True) -> int:
        """The lattice heading after ``action`` from ``heading``: a move's direction (when it
        moved: a blocked move turns nothing), a turn's quarter, else unchanged."""
        if action < NUM_ACTIONS:
            return exposure.MOVE_HEADINGS[action] if moved else heading
        return (heading + self.turn_of(action)) % exposure.HEADINGS

    @property
    def cycle_bins(self) -> int:
        """Bins of the lights' cycle in the state (1 when the state has no phase)."""
        return 1 if self.timing is None else self.timing.cycle_bins

    def state_of(self, x: float, y: float, t: float = 0.0, yaw: float = 0.0) -> tuple[float, ...]:
        """The agent's state for a pose (x, y, yaw) at time t (s): (x, y) rounded to the nearest
        point of the state grid ``start + k*state_cell`` (see "State" in the module docstring),
        then the extra features (the phase of t, the heading of yaw)."""
        position = (self._centre(x, self._anchor[0]), self._centre(y, self._anchor[1]))
        return position + self.features_at(t, yaw)

    def positions_of(self, xs, ys) -> np.ndarray:
        """(k, 2): the (x, y) of ``state_of`` for arrays of points, in the same float64
        arithmetic (so equal to it bit for bit)."""
        return np.column_stack(
            [self._centres(xs, self._anchor[0]), self._centres(ys, self._anchor[1])]
        )

    def _centres(self, values, anchor: float) -> np.ndarray:
        steps = np.floor((np.asarray(values, dtype=np.float64) - anchor) / self.cell + 0.5)
        return anchor + steps * self.cell

    def features_at(self, t: float, yaw: float = 0.0) -> tuple[float, ...]:
        """The extra state features at time t (s) and yaw (rad): (), (phase,), (heading,) or
        (phase, heading)."""
        features = ()
        if self.timing is not None:
            features += (float(self.timing.bin_of(t)),)
        if self.footprint is not None:
            features += (float(exposure.heading_of(yaw)),)
        return features

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
        node = self._start_node(x, y)
        successor = None if action == WAIT else lattice.successor(node, action)
        return lattice.node_to_point(node if successor is None else successor)

    def move_start(self, x: float, y: float) -> tuple[float, float]:
        """The lattice node a move from (x, y) starts from (``move_target``'s)."""
        return self.lattice.node_to_point(self._start_node(x, y))

    def _start_node(self, x: float, y: float):
        lattice = self.lattice
        node = lattice.point_to_node(x, y)
        if not lattice.is_valid(node):  # beside a wall, or localisation far off: the nearest
            node = lattice.nearest_valid_node(x, y)
        return node

    def state_bounds(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(min, max) state over every point of the map and time: RLEnvDescription's state
        ranges."""
        x_min, y_min, x_max, y_max = self.scenario.map.bounds
        (x_anchor, y_anchor) = self._anchor
        high = (self._last_centre_below(x_max, x_anchor), self._last_centre_below(y_max, y_anchor))
        low = (self._centre(x_min, x_anchor), self._centre(y_min, y_anchor))
        extra_low = tuple(low for _, low, _ in self.extra_features)
        extra_high = tuple(high for _, _, high in self.extra_features)
        return low + extra_low, high + extra_high

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
            'num_actions': self.num_actions,
            'num_states': len(states) * self.cycle_bins * self.headings,
            'min_state_range': list(low),
            'max_state_range': list(high),
            'max_reward': max_reward,
            'reward_range': reward_range,
            'stochastic': bool(stochastic),
            'episodic': True,
            'title': self.title,
        }

    # --- judging --------------------------------------------------------------------------------

    def visibility(self, x: float, y: float, t: float = 0.0, yaw: float | None = None) -> float:
        """Total visibility at (x, y) m at time t s, by the per-point model (ValueError off the
        map); weighed by exposure for a robot facing yaw (rad) where the scenario says so."""
        return self._point_visibility(x, y, t, self._heading(yaw))

    def _heading(self, yaw):
        return None if self.footprint is None else yaw

    def step_samples_of(self, x0, y0, t0, x1, y1, t1):
        """(xs, ys, ts): the samples a step from (x0, y0) at t0 to (x1, y1) at t1 is judged on,
        ``step_samples`` of them evenly along it in space and time, the arrival last (the
        departure is the previous step's arrival). Works on arrays of steps too (then (k, ...))."""
        fractions = np.arange(1, self.step_samples + 1) / self.step_samples
        shape = (-1,) + (1,) * np.ndim(x0)
        fractions = fractions.reshape(shape)
        x0, y0, x1, y1 = (np.asarray(v, dtype=np.float64) for v in (x0, y0, x1, y1))
        xs = x0 + (x1 - x0) * fractions
        ys = y0 + (y1 - y0) * fractions
        ts = t0 + (t1 - t0) * fractions.ravel()
        xs[-1], ys[-1] = x1, y1  # exactly the arrival
        return xs, ys, ts

    def turn_samples_of(self, x0, y0, t0, yaw0, yaw1):
        """(xs, ys, ts, yaws): the samples of the turn in place at (x0, y0) from yaw0 to yaw1
        (rad, the shorter way; a half turn either way shows the same) a step starts with: every
        ``exposure.TURN_SAMPLE`` from yaw0 and the final heading, yaw0 itself not (it is the
        previous step's arrival), all at t0; (0, ...) arrays when nothing turns. Works on arrays
        of steps too (then (k, ...), shorter turns repeating their final heading)."""
        yaw0 = np.asarray(yaw0, dtype=np.float64)
        turn = exposure.wrap(np.asarray(yaw1, dtype=np.float64) - yaw0)
        size = np.abs(turn)
        count = math.ceil(float(np.max(size, initial=0.0)) / exposure.TURN_SAMPLE - 1e-9)
        steps = np.arange(1, count + 1).reshape((-1,) + (1,) * turn.ndim) * exposure.TURN_SAMPLE
        yaws = yaw0 + np.sign(turn) * np.minimum(steps, size)
        shape = (count, *np.broadcast_shapes(np.shape(x0), np.shape(y0), turn.shape))
        xs = np.broadcast_to(np.asarray(x0, dtype=np.float64), shape)
        ys = np.broadcast_to(np.asarray(y0, dtype=np.float64), shape)
        return xs, ys, np.full(count, float(t0)), np.broadcast_to(yaws, shape)

    def step_visibility(self, x0, y0, t0: float, x1, y1, t1: float, yaw0=None, yaw1=None) -> float:
        """The most light on the robot during a step from (x0, y0) at t0 s to (x1, y1) at t1 s
        (see "A step's visibility"): what ``judge`` is given. Where lights are weighed by
        exposure, the robot turns from yaw0 to yaw1 (rad) at the departure and drives facing
        yaw1."""
        see = self._point_visibility
        xs, ys, ts = self.step_samples_of(x0, y0, t0, x1, y1, t1)
        if self.footprint is None or yaw1 is None:
            if not self.scenario.has_moving_lights:
                return float(see.many(xs, ys, t1).max())
            return max(see(x, y, t) for x, y, t in zip(xs, ys, ts, strict=True))
        yaws = np.full(xs.shape, float(yaw1))
        turn = self.turn_samples_of(x0, y0, t0, yaw1 if yaw0 is None else yaw0, yaw1)
        if not self.scenario.has_moving_lights:
            drive = see.many(xs, ys, t1, yaws)
            turning = see.turning(np.asarray(x0, float), np.asarray(y0, float), t1, turn[3])
            return float(max([drive.max(), *turning]))
        samples = zip(
            (*turn[0], *xs), (*turn[1], *ys), (*turn[2], *ts), (*turn[3], *yaws), strict=True
        )
        return max(see(x, y, t, yaw) for x, y, t, yaw in samples)

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
        yaw: float | None = None,
    ) -> StepJudgement:
        """Judge the true pose (x, y, yaw) reached at time t by action number ``step_index``
        (from 1).

        visibility: the pose's visibility at t when the caller already has it (it must be
        ``self.visibility(x, y, t, yaw)``, or the step's); computed otherwise.
        """
        if isinstance(step_index, bool) or not isinstance(step_index, int | np.integer):
            raise ValueError(f'step_index: expected an integer >= 1, got {step_index!r}')
        if step_index < 1:
            raise ValueError(f'step_index: expected an integer >= 1, got {step_index}')
        if visibility is None:
            visibility = self.visibility(x, y, t, yaw)
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
            result.outcome is EpisodeOutcome.DETECTED,
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
