"""The light fields a plan weighs: every lattice step's light under a hypothesis' lights. No
rclpy.

A plan asks every step of the lattice (tens of thousands on floorplan-moving's time-expanded
lattice), so each light's field is kept by its parameters while it is asked: between fits most
lights stay as they were. A plan weighs each step at its nodes, also where the pose jitters
(through ROS): weighing it at the shifts as well, as the likelihood does, was measured and not
kept (docs: the light model).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from stealth_core.light_world import LightWorld
from stealth_core.visibility import PointVisibility

NODE_FIELDS = 256  # lights' fields kept (one float per sample each)


class PlanFields:
    """Lattice-wide step visibilities of hypothesised lights (objects with ``params``), each
    light's field kept by its parameters; ``seeing(params)`` is its point visibility."""

    def __init__(self, world: LightWorld, seeing: Callable[[tuple], PointVisibility]):
        self.world, self._seeing = world, seeing
        self._node: dict[tuple, np.ndarray] = {}

    def step_visibility(self, lights) -> np.ndarray:
        """(places, directions): the lights' step visibility of every lattice step."""
        samples = self.world.samples
        total = None
        for light in lights:
            field = self._node.get(light.params)
            if field is None:
                field = samples.light_at(self._seeing(light.params))
                if len(self._node) > NODE_FIELDS:
                    self._node.clear()
                self._node[light.params] = field
            total = field if total is None else total + field
        if total is None:
            return np.zeros(samples.shape)
        return samples.step_peaks(total).reshape(samples.shape)
