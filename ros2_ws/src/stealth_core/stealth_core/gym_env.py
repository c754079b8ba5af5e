"""stealth-nav as a Gymnasium environment: the same task, in-process (no DDS, no simulator).

Importing ``stealth_core`` registers it as ``StealthNav-v0``::

    import gymnasium as gym
    import stealth_core

    gym.register_envs(stealth_core)

    env = gym.make('StealthNav-v0', scenario='lgfloor', goal='hard', slip=0.1)
    observation, info = env.reset(seed=1)

Steps are judged by ``stealth_core.task.StealthTask`` on the move lattice's exact arrays
(``stealth_core.lattice_model.LatticeModel``), so the environment, the ROS environment node and the
planners agree on every reward, and a policy trained here runs unchanged in the ROS system: the
observation is the float32 ``[x, y]`` the ROS environment sends for the same pose.
"""

from __future__ import annotations

import dataclasses
import functools
import os
from pathlib import Path

import gymnasium as gym
from gymnasium import spaces
from matplotlib import colormaps
from matplotlib.colors import to_rgb
import numpy as np

from stealth_core import ENV_ID, palette  # noqa: F401  (ENV_ID: the id it is registered as)
from stealth_core.bounce import bounce_bound
from stealth_core.lattice_model import PERPENDICULAR, LatticeModel
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import Scenario, find_scenario, load_scenario
from stealth_core.sensing import NO_PLACE, Sensor
from stealth_core.task import EpisodeStats, StealthTask, StepJudgement
from stealth_core.visibility_cache import scenario_visibility

DEFAULT_SCENARIO = 'map1'
TRACKS = ('full', 'sensed')  # the lights known to the agent; sensed where it has seen them


class StealthNavEnv(gym.Env):
    """Cross a known floor plan to a goal without being seen by searchlights.

    ## Description

    A robot moves on a lattice of points ``start + (i, j) * step_distance`` of a scenario's map
    (``scenarios/<name>.yaml``): walls, unknown space and searchlights whose light falls off with
    distance, stays inside a cone and is stopped by walls (``stealth_core.lighting``). The robot
    must reach the goal while the total light on it stays below the detection threshold. The
    shortest way is always seen; the ways round are longer.

    ## Action Space

    ``Discrete(4)``: 0 up (+y), 1 down (-y), 2 left (-x), 3 right (+x), each a move of the
    scenario's ``step_distance`` (m) in the map frame. A move whose swept disc (``robot_radius``)
    would touch a wall leaves the robot in place; it still counts as a step and pays the step
    reward. With ``slip`` > 0 the robot moves at right angles to the chosen direction with that
    probability (each side half of it). Scenarios with moving lights add ``4`` wait (stay at the
    node for one step; it never slips): ``Discrete(5)``. Scenarios with ``exposure.turn_actions``
    add turn left and turn right (a quarter turn in place, one step; never slips) after those
    (``task.action_names``).

    ## Observation Space

    ``Box(low, high, (2,), float32)``: ``[x, y]`` of the robot (m, map frame) rounded to the
    state grid ``start + k*state_cell`` (cells centred on the move lattice's nodes), exactly the
    state the ROS environment sends (``StealthTask.state_of``); low and high span the map.
    Scenarios with ``phase_bins`` add the phase of the lights' cycle (0 .. phase_bins - 1):
    ``(3,)``; scenarios with ``exposure`` add the heading (0 east, 1 north, 2 west, 3 south),
    each light then weighed by how much of the robot it sees (``stealth_core.exposure``). Each
    step takes the scenario's ``step_seconds``; an episode starts at phase 0.

    ### The sensed track (``track='sensed'``)

    The robot knows the floor plan but not the lights (``stealth_core.sensing``): it senses the
    light on the lattice nodes and moves in its line of sight within the scenario's
    ``sensing_range`` (default 8 m) and remembers the last value of each. The observation is a
    ``Dict`` (every array float32 unless said; grids over the move lattice, ``[row, col] =
    [j - j_min, i - i_min]`` for node ``start + (i, j) * step_distance``, row 0 southernmost):

    - ``state``: the full track's observation above (``[x, y]`` and any phase and heading);
    - ``lit``: ``MultiBinary(1)``, int8: 1 when the light on the robot (the visibility the judge
      used for the last step; at reset, at the start) reaches the detection threshold;
    - ``light``: ``(rows, cols)``: the last light sensed at each node, -1 never sensed, -2 no
      valid node there (wall, or too close to one: the floor plan is known);
    - ``moves``: ``(2, rows, cols)``: the most light along the move up ([0], to row + 1) and
      right ([1], to col + 1) from each node, last sensed; -1 never sensed, -2 no such move.

    Light values are at most 1 per light (plus a bound of the bounced light): the spaces' high.

    ``env.sensor.memory`` also keeps the step each value was sensed at (a moving light's old
    value may be stale). ``sensing.flat_observation`` flattens it in the documented order.
    Rewards, detection and episode ends are the full track's.

    ## Rewards

    Those of the scenario (``stealth_core.reward``), with d the distance to the goal point and v
    the light on the robot: detected, ``-(detection_penalty + detection_distance_weight * d)``;
    goal reached, ``goal_reward + goal_distance_weight * (goal_radius - d)``; otherwise
    ``-(visibility_weight * v + distance_weight * d + time_cost)``. v is the most light on the
    robot during the step, sampled along the move in space and time
    (``StealthTask.step_visibility``).

    ## Starting State

    The scenario's start, always.

    ## Episode End

    Terminated when the robot is detected (v at or above the threshold, or by chance in
    'probabilistic' mode) or reaches the goal; truncated at the scenario's ``step_limit``.
    ``info`` holds ``pose`` (the true position, m), ``visibility``, ``distance_to_goal``,
    ``detected``, ``outcome`` ('SUCCESS', 'DETECTED', 'TIMEOUT' or None) and ``steps``.
    ``env.stats`` (``task.EpisodeStats``) keeps the episode's EpisodeSummary figures, as the
    ROS environment does, and ``env.trajectory`` the poses so far.

    ## Arguments

    ```python
    gym.make('StealthNav-v0', scenario='map1', goal=None, slip=0.0, render_mode=None,
             track='full')
    ```

    - ``scenario``: a shipped scenario's name, a scenario YAML path, or a loaded ``Scenario``.
    - ``goal``: 'easy', 'medium', 'hard' (whichever the scenario has); None: its default goal.
    - ``slip``: probability in [0, 1] of moving sideways instead.
    - ``render_mode``: 'ansi' (a text picture of the lattice) or 'rgb_array' (the map at one
      pixel per map cell: visibility heat, walls, the path so far, the robot).
    - ``track``: 'full' (the lights known: the observation is the state) or 'sensed' (the
      lights sensed as the robot goes: the Dict above).

    ## Version History

    - v0: Initial version.
    """

    metadata = {'render_modes': ['ansi', 'rgb_array'], 'render_fps': 4}

    def __init__(
        self,
        scenario: str | os.PathLike | Scenario = DEFAULT_SCENARIO,
        goal: str | None = None,
        slip: float = 0.0,
        render_mode: str | None = None,
        track: str = 'full',
    ):
        if track not in TRACKS:
            raise ValueError(f'track: expected one of {", ".join(TRACKS)}, got {track!r}')
        if render_mode is not None and render_mode not in self.metadata['render_modes']:
            raise ValueError(f'render_mode: expected one of ansi, rgb_array, got {render_mode!r}')
        if not 0.0 <= slip <= 1.0:
            raise ValueError(f'slip: expected a probability in [0, 1], got {slip!r}')
        self.model = lattice_model(scenario, goal)
        self.task = self.model.task
        self.scenario = self.task.scenario
        self.slip = float(slip)
        self.step_seconds = self.task.step_seconds
        self.render_mode = render_mode
        # Plain Python containers: indexing them is several times faster than numpy scalars.
        self._successors = self.model.successors.tolist()
        self._points = [tuple(p) for p in self.model.points.tolist()]
        self._visibility = self.model.visibility.tolist()
        self._step_visibility = self.model.step_visibility.tolist()
        low, high = self.task.state_bounds()
        self.action_space = spaces.Discrete(self.model.num_actions)
        self.observation_space = spaces.Box(
            np.array(low, dtype=np.float32), np.array(high, dtype=np.float32), dtype=np.float32
        )
        self.track = track
        self.sensor: Sensor | None = None
        if track == 'sensed':
            self.sensor = Sensor(self.model)
            self.observation_space = _sensed_space(self.observation_space, self.sensor)
        self._node = self.model.start
        self._steps = 0
        self._path = [self._node]  # node indices since the start
        self._judgements: list[StepJudgement] = []  # one per step
        self._episode = -1  # resets so far, minus one: EpisodeSummary's episode number
        self._picture: np.ndarray | None = None

    @property
    def stats(self) -> EpisodeStats:
        """This episode's statistics so far (EpisodeSummary's figures), as the ROS environment
        keeps them; replayed from the steps on demand, which keeps ``step`` fast."""
        stats = self.task.start_episode(*self._points[self._path[0]], max(self._episode, 0))
        for node, judgement in zip(self._path[1:], self._judgements, strict=True):
            stats.add(*self._points[node], judgement)
        return stats

    @property
    def node(self) -> int:
        """The robot's node: an index into ``self.model``'s arrays."""
        return self._node

    @property
    def trajectory(self) -> np.ndarray:
        """(steps + 1, 2): the poses (m) of this episode so far, from the start."""
        return self.model.points[self._path]

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.task.rng = self.np_random  # probabilistic detection draws from the env's stream
        self._node = self.model.start
        self._steps = 0
        self._path = [self._node]
        self._judgements = []
        self._episode += 1
        if self.sensor is not None:
            self.sensor.reset()  # each episode starts knowing no light
        x, y = self._points[self._node]
        info = {
            'pose': (x, y),
            'visibility': self._visibility[self._node],
            'distance_to_goal': self.task.distance_to_goal(x, y),
            'detected': False,
            'outcome': None,
            'steps': 0,
        }
        return self._observation(info['visibility']), info

    def step(self, action):
        if not self.action_space.contains(action):
            choices = ', '.join(map(str, range(self.action_space.n)))
            raise ValueError(f'action: expected one of {choices}, got {action!r}')
        direction = int(action)
        if self.slip and PERPENDICULAR[direction] and self.np_random.random() < self.slip:
            direction = PERPENDICULAR[direction][int(self.np_random.integers(2))]
        self._steps += 1
        before = self._node
        node = self._node = self._successors[before][direction]
        self._path.append(node)
        x, y = self._points[node]
        visibility = self._step_visibility[before][direction]
        judgement = self.task.judge(x, y, self._steps * self.step_seconds, self._steps, visibility)
        self._judgements.append(judgement)
        outcome = judgement.outcome
        timed_out = outcome is EpisodeOutcome.TIMEOUT
        info = {
            'pose': (x, y),
            'visibility': judgement.visibility,
            'distance_to_goal': judgement.distance_to_goal,
            'detected': judgement.detected,
            'outcome': None if outcome is None else outcome.name,
            'steps': self._steps,
        }
        observation = self._observation(judgement.visibility)
        return observation, judgement.reward, judgement.terminal and not timed_out, timed_out, info

    def _observation(self, visibility: float):
        """The state at the robot's place; on the sensed track, with what it senses there."""
        state = self.model.states[self._node].copy()
        if self.sensor is None:
            return state
        self.sensor.sense(self._node, self._steps)
        memory, sensing = self.sensor.memory, self.sensor.sensing
        lit = visibility >= self.scenario.detection_threshold
        return {
            'state': state,
            'lit': np.array([lit], dtype=np.int8),
            'light': sensing.grid(memory.node_light),
            'moves': sensing.move_grid(memory.move_light),
        }

    # --- rendering ------------------------------------------------------------------------------

    def render(self):
        if self.render_mode == 'ansi':
            return self._text()
        if self.render_mode == 'rgb_array':
            return self._image()
        return None

    def _text(self) -> str:
        """The lattice, north up: # no node, ! seen, + lit, . dark, G goal, S start, R robot."""
        model, lattice = self.model, self.task.lattice
        columns, rows = lattice.shape
        grid = [['#'] * columns for _ in range(rows)]
        threshold = self.scenario.detection_threshold
        n = len(model.nodes)
        layer_start = self._node - model.node_of(self._node)  # the lights at the robot's bin
        for i, (a, b) in enumerate(model.nodes):
            v = self._visibility[layer_start + i]
            mark = 'G' if model.goal[i] else '!' if v >= threshold else '+' if v > 0 else '.'
            grid[rows - 1 - (b - lattice.j_min)][a - lattice.i_min] = mark
        for i, mark in ((model.start, 'S'), (self._node, 'R')):
            a, b = model.nodes[i % n]
            grid[rows - 1 - (b - lattice.j_min)][a - lattice.i_min] = mark
        x, y = self._points[self._node]
        status = (
            f'{self.task.title}: step {self._steps}/{self.task.step_limit}, robot at '
            f'({x:g}, {y:g}), light {self._visibility[self._node]:.3f}'
        )
        return '\n'.join([status, *(''.join(row) for row in grid)]) + '\n'

    def _image(self) -> np.ndarray:
        """(height, width, 3) uint8, one pixel per map cell, north up."""
        if self._picture is None:
            self._picture = _scenario_picture(self.scenario)
        image = self._picture.copy()
        occupancy = self.scenario.map
        height = image.shape[0]

        def pixel(x: float, y: float) -> tuple[int, int]:
            col, row = occupancy.world_to_cell(x, y)
            return height - 1 - row, col

        path_rgb = palette.FRAME_PATH
        for before, after in zip(self._path, self._path[1:], strict=False):
            (r0, c0), (r1, c1) = pixel(*self._points[before]), pixel(*self._points[after])
            image[min(r0, r1) - 1 : max(r0, r1) + 2, min(c0, c1) - 1 : max(c0, c1) + 2] = path_rgb
        goal = self.task.goal
        goal_radius = goal.radius / occupancy.resolution
        _disc(image, *pixel(goal.x, goal.y), goal_radius, palette.FRAME_GOAL)
        radius = max(self.scenario.robot_radius / occupancy.resolution, 2.0)
        _disc(image, *pixel(*self._points[self._node]), radius, palette.FRAME_ROBOT)
        return image


def _sensed_space(state: spaces.Box, sensor: Sensor) -> spaces.Dict:
    """The sensed track's observation space (see the class docstring)."""
    shape = sensor.sensing.shape
    scenario = sensor.sensing.model.task.scenario
    n_lights = len(scenario.lights)  # each light gives at most 1, plus what the walls bounce
    most = n_lights + bounce_bound(scenario.bounce, scenario.map.resolution, n_lights)
    return spaces.Dict(
        {
            'state': state,
            'lit': spaces.MultiBinary(1),
            'light': spaces.Box(NO_PLACE, most, shape, dtype=np.float32),
            'moves': spaces.Box(NO_PLACE, most, (2, *shape), dtype=np.float32),
        }
    )


def _scenario_picture(scenario: Scenario) -> np.ndarray:
    """Visibility heat on free cells (the pictures' colours), walls and unknown space; north up."""
    occupancy = scenario.map
    total, _ = scenario_visibility(scenario)
    scale = max(float(total[~occupancy.blocked].max(initial=0.0)), scenario.detection_threshold)
    heat = colormaps[palette.HEATMAP](np.clip(total / scale, 0.0, 1.0))[..., :3]
    rgb = np.where((total > 0)[..., None], heat, to_rgb(palette.DARK_FLOOR))
    rgb[occupancy.unknown] = palette.UNKNOWN_SPACE[:3]
    rgb[occupancy.occupied] = palette.WALL[:3]
    return np.ascontiguousarray((rgb[::-1] * 255).round().astype(np.uint8))


def _disc(image: np.ndarray, row: int, col: int, radius: float, colour) -> None:
    reach = int(np.ceil(radius))
    rows, cols = np.ogrid[-reach : reach + 1, -reach : reach + 1]
    inside = rows * rows + cols * cols <= radius * radius
    r, c = np.nonzero(inside)
    r, c = r + row - reach, c + col - reach
    keep = (r >= 0) & (r < image.shape[0]) & (c >= 0) & (c < image.shape[1])
    image[r[keep], c[keep]] = colour


def lattice_model(scenario: str | os.PathLike | Scenario, goal: str | None = None) -> LatticeModel:
    """The model of a scenario and goal with a task of its own (models of files are cached:
    building one judges every node with the per-point lighting model)."""
    if isinstance(scenario, Scenario):
        model = LatticeModel.build(StealthTask(scenario, goal))
    else:
        path = Path(find_scenario(scenario)).resolve()
        model = _cached_model(str(path), path.stat().st_mtime_ns, goal)
    # A fresh task: each environment's probabilistic detection draws from its own generator.
    return dataclasses.replace(model, task=StealthTask(model.task.scenario, model.task.goal))


@functools.lru_cache(maxsize=16)
def _cached_model(path: str, modified_ns: int, goal: str | None) -> LatticeModel:
    del modified_ns  # part of the key only: an edited file is loaded again
    return LatticeModel.build(StealthTask(load_scenario(path), goal))
