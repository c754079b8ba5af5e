"""The light fields a plan weighs: every lattice step's light under a hypothesis' lights, at its
nodes and, where the pose is judged off the node, walked off them. No rclpy.

A plan asks every step of the lattice (tens of thousands on floorplan-moving's time-expanded
lattice), so each light's field is kept by its parameters while it is asked: between fits most
lights stay as they were. With a pose jitter (``EvidenceSet.offsets``: the node, then shifts of
0.15 m along +-x and +-y through ROS) the likelihood calls a step's light anything over its
shifts, and a plan weighs it the same way (``shifted_visibility``): a lamp hypothesised on the
robot's way leaves the node itself dark and the steps beside it lit. A light's field at the
shifts is computed only on the steps a shifted sample could stand in its cone and range (as it
stands at the sample's time, where it moves: ``LatticeSamples.rows_within``); the rest get
none of its direct light.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from stealth_core.light_world import LightWorld
from stealth_core.visibility import PointVisibility

NODE_FIELDS = 256  # lights' fields at the nodes kept (one float per sample each)
SHIFTED_FIELDS = 48  # and at the shifts (five per sample, on the steps they reach)


class PlanFields:
    """Lattice-wide step visibilities of hypothesised lights (objects with ``params``), each
    light's field kept by its parameters; ``seeing(params)`` is its point visibility."""

    def __init__(
        self,
        world: LightWorld,
        offsets: np.ndarray,
        seeing: Callable[[tuple], PointVisibility],
    ):
        self.world, self.offsets, self._seeing = world, np.asarray(offsets), seeing
        self._node: dict[tuple, np.ndarray] = {}
        self._shifted: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}

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

    def shifted_visibility(self, lights) -> np.ndarray:
        """(places, directions, shifts): the lights' step visibility of every lattice step at
        its nodes and walked off them by each offset (the node's first: ``step_visibility``
        itself). Without a jitter, one shift."""
        if len(self.offsets) == 1:
            return self.step_visibility(lights)[..., None]
        samples, shifts = self.world.samples, len(self.offsets)
        total = np.zeros((samples.x.shape[0], shifts * samples.width))
        for light in lights:
            rows, field = self._shifted_field(light.params)
            total[rows] += field
        peaks = total.reshape(total.shape[0], shifts, samples.width).max(axis=2)
        return peaks.reshape(*samples.shape, shifts)

    def _shifted_field(self, params: tuple) -> tuple[np.ndarray, np.ndarray]:
        """(rows, light): one light's light at the samples of the step rows it can reach, at
        the node and each shift (the lattice's whole field at five shifts costs about a second
        a light on floorplan-moving)."""
        kept = self._shifted.get(params)
        if kept is None:
            see = self._seeing(params)
            samples = self.world.samples
            reach = float(np.abs(self.offsets).max())
            rows = (
                np.arange(samples.x.shape[0])  # a bounce reaches past the range
                if self.world.bounces
                else samples.rows_within(see.lights[0], reach)
            )
            kept = (rows, samples.light_at(see, rows, self.offsets))
            if len(self._shifted) >= SHIFTED_FIELDS:
                self._shifted.pop(next(iter(self._shifted)))
            self._shifted[params] = kept
        return kept
