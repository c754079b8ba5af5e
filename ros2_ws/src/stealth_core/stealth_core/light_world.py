"""What a learner that infers the searchlights may know, and what a step tells it. No rclpy.

A robot crossing a known floor plan knows the map, the start, the goal, the reward's weights and
the form of the light law (cone, ``1/(1 + beta*d^2)`` out to the range, occlusion on the
Bresenham line, lights adding up; the one-bounce and exposure variants where the scenario turns
them on). It does not know the lights. ``LightWorld`` is that knowledge: the scenario with its
lights removed (``lights=()``) and the lattice model of that dark world, so nothing built from it
can read a light. Where lights move, it keeps the scenario's ``Timing`` (the phase bins, the
cycle they split and a step's seconds): what the state's phase means, which the robot reads off
its states (the phase advances by ``bins_per_step`` a step), not off the lights; the dark world's
lattice is then time-expanded with the wait action, as the task's is.

``LatticeSamples`` are the points every lattice step is judged on (the move's samples, and the
turn's where lights are weighed by exposure; where lights move, each at its time), laid out so
that one light's light at all of them is one vectorised call; a light field's step visibilities
are the most of the lights' sum over each step's samples, as ``LatticeModel.step_visibility``
is.

Each step's reward gives the light the robot met on it (``evidence_of_step``): a non-terminal
reward is ``-(visibility_weight*v + distance_weight*d + time_cost)`` with d known, so v; a
detection says v reached the threshold; a goal reached says it did not.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from stealth_core import exposure
from stealth_core.lattice_model import LatticeModel
from stealth_core.light_cycle import Timing
from stealth_core.reward import detection_reward
from stealth_core.scenario import Scenario
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion
from stealth_core.task import StealthTask
from stealth_core.visibility import PointVisibility, scenario_point_visibility

# Lamp cells whose lines of sight a world keeps (one int8 per map cell each) and blocks of them
# (16 x 16 bools each): a belief's search asks a few hundred lamp places over and over.
SIGHT_LAMPS = 384
SIGHT_TILES = 65536


class UnmodelledLawError(ValueError):
    """A scenario whose light law or reward the light model cannot model (one line, naming it)."""


def check_modelled(scenario: Scenario) -> None:
    """UnmodelledLawError naming the feature the light model does not model, if any. Reads only
    what the robot is told (the law's form, the state, the rewards), never the lights."""
    if scenario.detection_mode != 'threshold':
        raise UnmodelledLawError(
            f'{scenario.name}: detection_mode {scenario.detection_mode!r} is not modelled by '
            "light-model (it infers lights seen at a threshold: detection_mode 'threshold')"
        )
    if scenario.rewards.visibility_weight <= 0.0:
        raise UnmodelledLawError(
            f'{scenario.name}: rewards.visibility_weight 0 leaves the light out of the reward; '
            'light-model needs it > 0 to read the light from a step'
        )


class LightWorld:
    """A scenario and goal as the light model may know them: every light removed."""

    def __init__(self, scenario: Scenario, goal=None):
        check_modelled(scenario)
        self.scenario = dataclasses.replace(scenario, lights=())  # the timing kept
        self.task = StealthTask(self.scenario, goal)
        self.model = LatticeModel.build(self.task)  # the dark world's lattice
        # No lights: the lines of sight its hypotheses share, kept for many lamp places.
        self.points = scenario_point_visibility(self.scenario)
        self.points.max_lamps, self.points.max_tiles = SIGHT_LAMPS, SIGHT_TILES
        self.samples = LatticeSamples(self.task, self.model)

    @property
    def threshold(self) -> float:
        return float(self.scenario.detection_threshold)

    def see(self, lights, bounce: bool = True) -> PointVisibility:
        """The point visibility of hypothesised lights, sharing the traced lines of sight (their
        direct light only when ``bounce`` is False)."""
        return self.points.with_lights(lights, bounce)

    @property
    def timing(self) -> Timing | None:
        """The phase's meaning where lights move (None where they do not)."""
        return self.scenario.timing

    @property
    def bounces(self) -> bool:
        """Whether light bounces off the walls here (the law's one-bounce variant)."""
        return self.points.bounce is not None


class SamplePoints(NamedTuple):
    """Sample points of lattice steps, (rows, columns) each: where, the robot's heading (None
    where exposure does not weigh the lights) and the time, an index into
    ``LatticeSamples.times`` (None where lights do not move)."""

    x: np.ndarray
    y: np.ndarray
    headings: np.ndarray | None
    time_index: np.ndarray | None


class LatticeSamples:
    """Every step (place, direction) of the lattice model as ``width`` sample points (x, y and,
    where exposure weighs the lights, the robot's heading; where lights move, the time in the
    cycle), padded by repeating the arrival, so that a step's visibility is the most of the
    field over its row (``step_peaks``)."""

    def __init__(self, task: StealthTask, model: LatticeModel):
        places, directions = model.successors.shape
        x0, y0 = (np.broadcast_to(model.points[:, None, k], (places, directions)) for k in (0, 1))
        ends = model.points[model.successors]
        timing = task.timing
        # Each step from its place's bin start, as LatticeModel.build times it.
        bins = (np.arange(places) // len(model.nodes)) % model.cycle_bins
        bin_seconds = 0.0 if timing is None else timing.bin_seconds
        t0 = np.broadcast_to((bins * bin_seconds)[:, None], (places, directions))
        step = 0.0 if timing is None else timing.step_seconds
        drive_x, drive_y, drive_t = task.step_samples_of(
            x0, y0, 0.0, ends[..., 0], ends[..., 1], step
        )
        columns_x, columns_y, columns_yaw = list(drive_x), list(drive_y), []
        columns_t = [t0 + dt for dt in drive_t]
        self.weighs_heading = task.footprint is not None
        if self.weighs_heading:
            yaw0 = np.broadcast_to(
                (model.heading_of(np.arange(places)) * (math.pi / 2))[:, None], x0.shape
            )
            yaw1 = model.heading_of(model.successors) * (math.pi / 2)
            columns_yaw = [yaw1] * len(columns_x)
            _, _, _, turn_yaws = task.turn_samples_of(x0, y0, 0.0, yaw0, yaw1)
            turned = exposure.wrap(yaw1 - yaw0) != 0.0
            for yaws in turn_yaws:  # a step without a turn repeats its arrival instead
                columns_x.append(np.where(turned, x0, ends[..., 0]))
                columns_y.append(np.where(turned, y0, ends[..., 1]))
                columns_yaw.append(np.where(turned, yaws, yaw1))
                columns_t.append(np.where(turned, t0, t0 + step))
        self.shape = (places, directions)
        self.width = len(columns_x)
        self.x = np.stack(columns_x, axis=-1).reshape(places * directions, self.width)
        self.y = np.stack(columns_y, axis=-1).reshape(places * directions, self.width)
        self.yaw = (
            np.stack(columns_yaw, axis=-1).reshape(places * directions, self.width)
            if self.weighs_heading
            else None
        )
        self.t = (
            np.stack(columns_t, axis=-1).reshape(places * directions, self.width)
            if timing is not None
            else None
        )
        # The samples' few distinct times, and each sample's among them (``SamplePoints``).
        self.times, self.time_index = None, None
        if self.t is not None:
            self.times, inverse = np.unique(self.t, return_inverse=True)
            self.time_index = inverse.reshape(self.t.shape).astype(np.int32)

    def step_rows(self, places, directions) -> np.ndarray:
        """The sample rows of steps (arrays of places and directions)."""
        return np.asarray(places) * self.shape[1] + np.asarray(directions)

    def steps_of(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(places, directions) of sample rows: ``step_rows`` undone."""
        return rows // self.shape[1], rows % self.shape[1]

    def points(self, rows: np.ndarray | None = None, offsets=None) -> SamplePoints:
        """The samples of the step rows (all steps when None), (rows, width); with ``offsets``
        ((k, 2) m), (rows, k * width): each row's samples shifted by each offset in turn (the
        step walked that far off its nodes)."""
        pick = slice(None) if rows is None else rows
        xs, ys = self.x[pick], self.y[pick]
        headings = None if self.yaw is None else self.yaw[pick]
        index = None if self.t is None else self.time_index[pick]
        if offsets is not None:
            offsets = np.asarray(offsets, dtype=np.float64)
            count = xs.shape[0]
            xs = (xs[:, None, :] + offsets[None, :, 0, None]).reshape(count, -1)
            ys = (ys[:, None, :] + offsets[None, :, 1, None]).reshape(count, -1)
            headings = None if headings is None else np.tile(headings, (1, len(offsets)))
            index = None if index is None else np.tile(index, (1, len(offsets)))
        return SamplePoints(xs, ys, headings, index)

    def light_of(self, see: PointVisibility, points: SamplePoints) -> np.ndarray:
        """The light of ``see`` (one light's, usually) at sample points (``points``), moving
        lights where each sample's time puts them."""
        if points.time_index is None or not any(light.is_moving for light in see.lights):
            return see.many(points.x, points.y, 0.0, points.headings)
        return see.many_at_times(
            points.x, points.y, self.times, points.headings, time_index=points.time_index
        )

    def light_at(
        self, see: PointVisibility, rows: np.ndarray | None = None, offsets=None
    ) -> np.ndarray:
        """(rows, width): the light of ``see`` at the samples of the step rows (all steps when
        None); with ``offsets``, (rows, k * width), each row's samples shifted (``points``)."""
        return self.light_of(see, self.points(rows, offsets))

    def step_peaks(self, light: np.ndarray) -> np.ndarray:
        """A field at the samples, (rows, width), as each step's visibility: its most."""
        return light.max(axis=1)


class StepEvidence(NamedTuple):
    """What one step said of the light on it: ``low <= v <= high`` (equal when read exactly)."""

    place: int  # where the step started (a LatticeModel place)
    direction: int  # its direction
    low: float
    high: float  # math.inf after a detection

    @property
    def exact(self) -> bool:
        return self.low == self.high


def evidence_of_step(
    world: LightWorld, place: int, direction: int, reward: float, terminated: bool
) -> StepEvidence:
    """The light a step met, read off its reward (module docstring): exact for a step that went
    on (or timed out), at least the threshold for a detection, below it for a goal reached."""
    model, weights = world.model, world.scenario.rewards
    arrival = int(model.successors[place, direction])
    distance = float(model.distance[arrival])
    threshold = world.threshold
    if terminated and reward > 0.0:  # only the goal pays
        return StepEvidence(place, direction, 0.0, math.nextafter(threshold, 0.0))
    if terminated and reward <= detection_reward(0.0, weights):  # -(penalty + weight * d)
        return StepEvidence(place, direction, threshold, math.inf)
    value = (-reward - weights.distance_weight * distance - weights.time_cost) / (
        weights.visibility_weight
    )
    value = max(value, 0.0)  # rounding: a dark step may read -1e-17
    return StepEvidence(place, direction, value, value)


STATIC, SWEEP, PATROL = 0, 1, 2  # a hypothesised light's motion (``hypothesis_light``)


def light_from_parameters(name: str, x, y, direction, fov, beta, light_range) -> Searchlight:
    """A static light from the parameters the model searches over: ``beta`` (1/m^2) and the
    range (m) instead of ``delta``, the intensity at the range, ``1/(1 + beta*range^2)``."""
    delta = 1.0 / (1.0 + float(beta) * float(light_range) ** 2)
    return Searchlight(
        name, float(x), float(y), float(direction) % (2 * math.pi), float(fov),
        float(light_range), delta,
    )  # fmt: skip


def hypothesis_light(name: str, params, timing: Timing | None = None) -> Searchlight:
    """The Searchlight of a hypothesis' parameters: the six of ``light_from_parameters``, then,
    where lights move, ``kind, a, b, period_bins, offset``:

    - ``STATIC``: the rest unused;
    - ``SWEEP``: ``direction`` is the sweep's lower end, ``a`` its span (rad), ``offset`` how far
      along it (rad, in [0, a]) the beam is at time 0, turning up;
    - ``PATROL``: the lamp's rail runs from (x, y) to (a, b) and back; ``offset`` is the way
      along that loop (m, in [0, 2 * length)) it has come at time 0.

    A moving light repeats every ``period_bins`` bins of the timing (a whole number of them, as
    every moving light's period is), which sets its speed."""
    light = light_from_parameters(name, *params[:6])
    if len(params) == 6 or int(params[6]) == STATIC:
        return light
    kind, a, b, period_bins, offset = params[6:11]
    period = float(period_bins) * timing.bin_seconds
    if int(kind) == SWEEP:
        low, span = float(params[2]), float(a)
        motion = SweepMotion(low, low + span, 2.0 * span / period)
        return dataclasses.replace(light, direction=low + float(offset), motion=motion)
    start, end = np.array(params[:2], dtype=np.float64), np.array([a, b], dtype=np.float64)
    length = float(np.hypot(*(end - start)))
    along = float(offset) % (2.0 * length) if length > 0 else 0.0
    if along <= length:  # on the way out: from here to the far end, back, and here
        here = start + (end - start) * (along / max(length, 1e-12))
        waypoints = (tuple(end), tuple(start))
    else:
        here = end + (start - end) * ((along - length) / length)
        waypoints = (tuple(start), tuple(end))
    motion = PatrolMotion(
        tuple((float(px), float(py)) for px, py in waypoints), 2.0 * length / period
    )
    return dataclasses.replace(light, x=float(here[0]), y=float(here[1]), motion=motion)
