"""The environment node's sensed track (parameter ``track: sensed``): the robot that knows the
floor plan but not the lights, through ROS. Plain Python + numpy (no rclpy).

The node senses after every step with the Gym env's ``sensing.Sensor`` over the same lattice
model (same places, same memory rules, reset at each episode's first state), from the pose the
step was judged on (the true pose; the estimate under ``judge_on: estimate``) at the judgement's
episode time, and sends the agent exactly ``sensing.flat_observation`` of the Gym env's sensed
observation for the same moves. ``RLStateReward.state``, float32, with k the full track's state
length (``len(task.state_features)``: 2, 3 or 4) and the move lattice's rows x cols (row 0 the
southernmost, ``[row, col] = [j - j_min, i - i_min]``):

- ``[0, k)``: the full track's state (x, y, then any phase and heading), unchanged;
- ``k``: lit, 1 when the light on the robot (the judged visibility of the step; at the first
  state the light at the start) reaches the detection threshold, else 0;
- ``k + 1 ..`` (rows x cols, row-major): the last light sensed at each node;
- then (2 x rows x cols): the most light along the move up ([0]) and right ([1]) from each node,
  last sensed; in both, -1 never sensed and -2 no valid node or no such move.

``RLEnvDescription`` describes it: ``num_states`` stays the full track's count (what a table over
the leading k features holds: see the agent's ``state_features``), the ranges are the full
track's, then [0, 1] for lit and [-2, the Gym space's high] for every light and move. StepInfo
keeps the full track's state (a recording stays small; the sensed part follows from the steps).
"""

from __future__ import annotations

import numpy as np
from stealth_core.grid_observation import lattice_geometry
from stealth_core.sensing import NO_PLACE, Sensor

from stealth_env.markers import visibility_levels

UNKNOWN_LEVEL = -1  # OccupancyGrid's unknown: never sensed, or no node there


class SensedTrack:
    """The sensor of one environment node and the state it adds (see the module docstring)."""

    def __init__(self, task, model=None):
        from stealth_core.bounce import bounce_bound
        from stealth_core.lattice_model import LatticeModel

        self.task = task
        self.model = model if model is not None else LatticeModel.build(task)
        self.sensor = Sensor(self.model)
        scenario = task.scenario
        self.threshold = scenario.detection_threshold
        n_lights = len(scenario.lights)  # the Gym space's high (gym_env._sensed_space)
        self.most = n_lights + bounce_bound(scenario.bounce, scenario.map.resolution, n_lights)
        self.shape = self.sensor.sensing.shape  # (rows, cols)
        self.step = -1  # the step of the latest sensing (-1: none this episode)
        memory, sensing = self.sensor.memory, self.sensor.sensing
        # The latest state's sensed part, (R, C) and (2, R, C): before any, nothing sensed.
        self.light, self.moves = (
            sensing.grid(memory.node_light),
            sensing.move_grid(memory.move_light),
        )
        self.changed = False  # whether the latest state's sensed part differs from the one before

    @property
    def length(self) -> int:
        """The state's length: the full track's, lit, light and moves."""
        rows, cols = self.shape
        return len(self.task.state_features) + 1 + 3 * rows * cols

    def description(self, fields: dict) -> dict:
        """RLEnvDescription's fields of the full track with the sensed ranges appended."""
        cells = 3 * self.shape[0] * self.shape[1]
        return {
            **fields,
            'min_state_range': [*fields['min_state_range'], 0.0, *[NO_PLACE] * cells],
            'max_state_range': [*fields['max_state_range'], 1.0, *[self.most] * cells],
        }

    def first_state(self, state, pose) -> list[float]:
        """The episode's first state from the start pose (x, y, yaw): the memory starts empty."""
        self.sensor.reset()
        x, y, yaw = pose
        place = self.sensor.place_of(x, y, 0.0, yaw)
        return self._observe(state, place, 0, float(self.model.visibility[place]))

    def step_state(self, state, judged, t: float, step: int, visibility: float) -> list[float]:
        """The state after step ``step``, judged at pose ``judged`` (x, y, yaw) at episode time t
        with this visibility on the robot."""
        x, y, yaw = judged
        return self._observe(state, self.sensor.place_of(x, y, t, yaw), step, visibility)

    def _observe(self, state, place: int, step: int, visibility: float) -> list[float]:
        self.sensor.sense(place, step)
        memory, sensing = self.sensor.memory, self.sensor.sensing
        light, moves = sensing.grid(memory.node_light), sensing.move_grid(memory.move_light)
        self.changed = step == 0 or not (
            np.array_equal(light, self.light) and np.array_equal(moves, self.moves)
        )  # an episode's first state: a new memory
        self.step, self.light, self.moves = step, light, moves
        parts = [
            np.asarray(state, dtype=np.float32),
            np.array([visibility >= self.threshold], dtype=np.float32),
            light.ravel(),
            moves.ravel(),
        ]
        return np.concatenate(parts).tolist()

    def levels(self) -> np.ndarray:
        """(rows, cols) int8: the sensed light at each node in 0-100 of the detection threshold
        (as ``markers.visibility_levels``), -1 where never sensed or no node is."""
        memory, sensing = self.sensor.memory, self.sensor.sensing
        light = sensing.grid(memory.node_light)
        known = light >= 0.0
        levels = visibility_levels(np.where(known, light, 0.0), self.threshold)
        return np.where(known, levels, UNKNOWN_LEVEL).astype(np.int8)

    def grid_geometry(self) -> tuple[float, float, float]:
        """(resolution, origin x, origin y) of a grid with one cell centred on each lattice node
        (row 0 southernmost), in the map frame."""
        return lattice_geometry(self.task)
