"""What the robot believes of the searchlights: a set of light hypotheses that explain every step
it has taken, found by stochastic search under the light law's own form. No rclpy.

The field is a sum of lights (``light_world``), each a static cone with six unknowns: the
lamp's (x, y), direction, opening angle, ``beta`` and range. A *hypothesis* is a short list of
such lights; it predicts every step's visibility exactly as the environment judges it
(``LatticeSamples``). The evidence is what the steps said (``StepEvidence``: a value read off the
reward, or a bound from a detection or a goal). A hypothesis' energy is

    E = 1/2 * sum_k min(z_k^2, Z_CAP^2) + light_cost * lights,

z_k the step's miss in units of its tolerance (``abs_tol + rel_tol * v``: the environment's
rounding in-process, the pose noise through ROS), and the belief is ``particles`` hypotheses
kept by Metropolis moves at temperature 1 (birth, death, perturbation), each particle weighed by
``exp(-E)``: a sample of the posterior under a sparsity prior, the number of lights included.
A birth is proposed from the data: a step lit more than the hypothesis says is explained by a
lamp at a free place that sees it, aimed at it, with ``beta`` chosen so that its light there is
the missing light, the place scored by how well one ``beta`` fits the other unexplained steps
near it (one light's intensities ``1/(1 + beta*d^2)`` fix the ratio of its distances).

Where the evidence says nothing (rooms not yet seen) the particles hold no light: the plan is
optimistic there, and the robot finds out. A step the best particle still misses by more than
``CONTRADICTION_Z`` tolerances after a fit is a *contradiction*: the law is not the one modelled
(noise beyond the tolerance, soft edges, moving lights), reported by ``contradictions``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from stealth_core.light_world import LightWorld, StepEvidence, light_from_parameters
from stealth_core.visibility import _occluded, corner_maps

Z_CAP = 10.0  # a step missed by more tolerances than this costs no more (robustness)
CONTRADICTION_Z = 6.0
_MIN_FOV = math.radians(5.0)
_LAMP_STRIDE = 0.25  # m between the candidate lamp places of a birth


@dataclasses.dataclass(frozen=True)
class BeliefSettings:
    """How the belief searches; the defaults are measured (docs: the light model)."""

    particles: int = 8
    moves: int = 120  # Metropolis moves per particle per fit
    light_cost: float = 4.0  # energy of one more light (sparsity)
    abs_tol: float = 0.004  # tolerance of a read visibility, absolute
    rel_tol: float = 0.02  # and relative to it
    max_range: float = 30.0  # m, the farthest a hypothesised light may reach
    max_lights: int = 12

    def __post_init__(self):
        if self.particles < 1 or self.moves < 0 or self.max_lights < 1:
            raise ValueError('belief settings: particles and max_lights >= 1, moves >= 0')
        if self.abs_tol <= 0 or self.rel_tol < 0 or self.light_cost < 0:
            raise ValueError('belief settings: abs_tol > 0, rel_tol >= 0, light_cost >= 0')


@dataclasses.dataclass
class _Light:
    """One hypothesised light: its parameters and its light at the evidence's samples."""

    params: tuple  # x, y, direction, fov, beta, range
    at_evidence: np.ndarray  # (evidence rows, width)


class _Particle:
    def __init__(self, lights: list[_Light]):
        self.lights = lights
        self.energy = math.inf


class LightBelief:
    """Particles of light hypotheses over one ``LightWorld``; ``observe`` then ``fit``."""

    def __init__(self, world: LightWorld, rng: np.random.Generator, settings=None):
        self.world = world
        self.rng = rng
        self.settings = settings or BeliefSettings()
        self.evidence: list[StepEvidence] = []
        self._rows = np.zeros(0, dtype=np.int64)  # sample rows of the evidence
        self._low = np.zeros(0)
        self._high = np.zeros(0)
        self.particles = [_Particle([]) for _ in range(self.settings.particles)]
        self._lamps = _lamp_places(world)
        frame = world.points.frame
        self._lamp_cells = tuple(
            np.floor((self._lamps[:, k] - origin) / frame.resolution).astype(np.int64)
            for k, origin in ((0, frame.origin_x), (1, frame.origin_y))
        )
        self._sight_from: dict[tuple[int, int], np.ndarray] = {}
        self._field_cache: dict[tuple, np.ndarray] = {}

    # --- evidence ------------------------------------------------------------------------------

    def observe(self, evidence: StepEvidence) -> None:
        """Add what one step said (the particles' lights learn its samples' light)."""
        row = int(self.world.samples.step_rows(evidence.place, evidence.direction))
        self.evidence.append(evidence)
        self._rows = np.append(self._rows, row)
        self._low = np.append(self._low, evidence.low)
        self._high = np.append(self._high, evidence.high)
        for particle in self.particles:
            for light in particle.lights:
                extra = self._light_at(light.params, self._rows[-1:])
                light.at_evidence = np.concatenate([light.at_evidence, extra])
            particle.energy = math.inf

    def _tolerance(self) -> np.ndarray:
        finite = np.where(np.isfinite(self._high), self._high, self._low)
        return self.settings.abs_tol + self.settings.rel_tol * finite

    def misses(self, predicted: np.ndarray) -> np.ndarray:
        """Each evidence step's miss, in tolerances (0 inside its bounds)."""
        over = np.maximum(predicted - self._high, 0.0)
        under = np.maximum(self._low - predicted, 0.0)
        return (over + under) / self._tolerance()

    def _energy(self, lights: list[_Light]) -> float:
        z = self.misses(self._predict(lights))
        return 0.5 * float(np.sum(np.minimum(z, Z_CAP) ** 2)) + self.settings.light_cost * len(
            lights
        )

    def _predict(self, lights: list[_Light]) -> np.ndarray:
        if not lights:
            return np.zeros(len(self.evidence))
        total = lights[0].at_evidence
        for light in lights[1:]:
            total = total + light.at_evidence
        return total.max(axis=1)

    def _light_at(self, params: tuple, rows: np.ndarray) -> np.ndarray:
        light = light_from_parameters('hypothesis', *params)
        return self.world.samples.light_at(self.world.see([light]), rows)

    def _make(self, params: tuple) -> _Light:
        return _Light(params, self._light_at(params, self._rows))

    # --- search --------------------------------------------------------------------------------

    def fit(self, moves: int | None = None) -> None:
        """Metropolis moves on every particle (``settings.moves`` each by default)."""
        moves = self.settings.moves if moves is None else moves
        if not self.evidence:
            return
        for particle in self.particles:
            if not math.isfinite(particle.energy):
                particle.energy = self._energy(particle.lights)
            for _ in range(moves):
                proposal = self._propose(particle.lights)
                if proposal is None:
                    continue
                energy = self._energy(proposal)
                if energy <= particle.energy or self.rng.random() < math.exp(
                    particle.energy - energy
                ):
                    particle.lights, particle.energy = proposal, energy

    def _propose(self, lights: list[_Light]) -> list[_Light] | None:
        kind = self.rng.random()
        if kind < 0.3 or not lights:
            born = self._birth(lights)
            return None if born is None else [*lights, born]
        k = int(self.rng.integers(len(lights)))
        if kind < 0.4:
            return lights[:k] + lights[k + 1 :]
        params = self._perturbed(lights[k].params)
        return None if params is None else [*lights[:k], self._make(params), *lights[k + 1 :]]

    def _perturbed(self, params: tuple) -> tuple | None:
        x, y, direction, fov, beta, light_range = params
        rng = self.rng
        which = int(rng.integers(5))
        if which == 0:
            x, y = x + rng.normal(0, 0.2), y + rng.normal(0, 0.2)
            if self._blocked(x, y):
                return None
        elif which == 1:
            direction += rng.normal(0, math.radians(4.0))
        elif which == 2:
            fov = float(np.clip(fov + rng.normal(0, math.radians(5.0)), _MIN_FOV, 2 * math.pi))
        elif which == 3:
            beta *= math.exp(rng.normal(0, 0.15))
        else:
            light_range = float(
                np.clip(light_range + rng.normal(0, 0.4), 0.2, self.settings.max_range)
            )
        return (x, y, direction, fov, beta, light_range)

    def _blocked(self, x: float, y: float) -> bool:
        """Whether a lamp cannot stand at (x, y): off the map or in a wall."""
        frame = self.world.points.frame
        col = math.floor((x - frame.origin_x) / frame.resolution)
        row = math.floor((y - frame.origin_y) / frame.resolution)
        if not (0 <= col < frame.width and 0 <= row < frame.height):
            return True
        return bool(self.world.points.blocked[row, col])

    def _birth(self, lights: list[_Light]) -> _Light | None:
        """A light proposed to explain a step lit more than the hypothesis says."""
        if len(lights) >= self.settings.max_lights:
            return None
        predicted = self._predict(lights)
        missing = np.where(np.isfinite(self._high), self._high, self._low) - predicted
        candidates = np.flatnonzero(missing > self._tolerance())
        if candidates.size == 0:
            return None
        k = int(candidates[self.rng.choice(candidates.size, p=_normalised(missing[candidates]))])
        target = float(missing[k])
        if not np.isfinite(self._high[k]):  # a detection: at least that much more
            target += float(self.rng.uniform(0.0, 0.5))
        target = min(target, 0.95)
        samples = self.world.samples
        row = self._rows[k]
        anchor = np.array([samples.x[row, samples.width - 1], samples.y[row, samples.width - 1]])
        if samples.weighs_heading:
            anchor = np.array([samples.x[row, 0], samples.y[row, 0]])
        lamp = self._lamp_for(anchor, target, candidates, missing, predicted)
        if lamp is None:
            return None
        offset = anchor - lamp
        distance = max(float(np.hypot(*offset)), 0.1)
        beta = (1.0 / target - 1.0) / distance**2
        fov = float(self.rng.uniform(math.radians(15.0), math.radians(120.0)))
        aim = math.atan2(offset[1], offset[0]) + self.rng.uniform(-0.4, 0.4) * fov / 2
        delta = 0.1 if self.rng.random() < 0.5 else math.exp(self.rng.uniform(-3.5, -0.7))
        light_range = math.sqrt((1.0 - delta) / (delta * beta))
        if light_range < distance:
            light_range = distance + float(self.rng.uniform(0.0, 1.0))
        light_range = min(light_range, self.settings.max_range)
        return self._make((float(lamp[0]), float(lamp[1]), aim, fov, beta, light_range))

    def _lamp_for(self, anchor, target, candidates, missing, predicted) -> np.ndarray | None:
        """A lamp place that sees the anchor, scored by how well one beta explains the other
        unexplained steps near the anchor (their arrivals' missing light)."""
        lamps = self._lamps
        near = np.hypot(*(lamps - anchor).T) <= self.settings.max_range
        near &= self._seen_from(anchor)
        lamps = lamps[near]
        if lamps.size == 0:
            return None
        samples = self.world.samples
        others = candidates[np.isfinite(self._high[candidates])]
        rows = self._rows[others]
        points = np.stack(
            [samples.x[rows, samples.width - 1], samples.y[rows, samples.width - 1]], 1
        )
        close = np.hypot(*(points - anchor).T) <= 3.0
        points, values = points[close][:12], np.minimum(missing[others][close][:12], 0.95)
        d_anchor = np.maximum(np.hypot(*(lamps - anchor).T), 0.1)
        log_beta = [np.log((1.0 / target - 1.0) / d_anchor**2)]
        for point, value in zip(points, values, strict=True):
            d = np.maximum(np.hypot(*(lamps - point).T), 0.1)
            log_beta.append(np.log((1.0 / value - 1.0) / d**2))
        spread = np.std(np.stack(log_beta), axis=0) if len(log_beta) > 1 else np.zeros(len(lamps))
        order = np.argsort(spread + self.rng.uniform(0, 0.05, size=spread.size))
        frame, see = self.world.points.frame, self.world.points
        target_cell = frame.cell_of(*anchor)
        for index in order[:40]:
            if self.rng.random() < 0.3:
                continue
            lamp = lamps[index]  # on the grid: its lines of sight are traced once, then kept
            if self._blocked(*lamp):
                continue
            if see.line_of_sight(frame.cell_of(*lamp), target_cell):
                return lamp
        return None

    def _seen_from(self, anchor) -> np.ndarray:
        """(lamp places,) bool: the lamp places in sight of the anchor's cell, traced from the
        anchor in one call (the line is nearly symmetric; the lamp chosen is checked exactly)."""
        frame = self.world.points.frame
        cell = frame.cell_of(*anchor)
        mask = self._sight_from.get(cell)
        if mask is None:
            points = self.world.points
            if points._corners is None:
                points._corners = corner_maps(points.blocked)
            cols, rows = self._lamp_cells
            mask = ~_occluded(points.blocked, points._corners, cell, cols, rows)
            if len(self._sight_from) > 4096:
                self._sight_from.clear()
            self._sight_from[cell] = mask
        return mask

    # --- what the belief says ------------------------------------------------------------------

    def weights(self) -> np.ndarray:
        """The particles' posterior weights, exp(-E) normalised."""
        energies = np.array(
            [
                p.energy if math.isfinite(p.energy) else self._energy(p.lights)
                for p in self.particles
            ]
        )
        w = np.exp(-(energies - energies.min()))
        return w / w.sum()

    def step_visibility(self, particle: int) -> np.ndarray:
        """(places, directions): particle's predicted visibility of every lattice step."""
        samples = self.world.samples
        total = None
        for light in self.particles[particle].lights:
            field = self._field_cache.get(light.params)
            if field is None:
                field = samples.light_at(
                    self.world.see([light_from_parameters('h', *light.params)])
                )
                if len(self._field_cache) > 256:
                    self._field_cache.clear()
                self._field_cache[light.params] = field
            total = field if total is None else total + field
        if total is None:
            return np.zeros(samples.shape)
        return samples.step_peaks(total).reshape(samples.shape)

    def best(self) -> int:
        return int(np.argmax(self.weights()))

    def contradictions(self) -> list[str]:
        """The evidence steps the best particle misses by more than CONTRADICTION_Z tolerances:
        one line each, naming the step, what it said and what the belief says."""
        if not self.evidence:
            return []
        lights = self.particles[self.best()].lights
        predicted = self._predict(lights)
        z = self.misses(predicted)
        lines = []
        model = self.world.model
        for k in np.flatnonzero(z > CONTRADICTION_Z):
            e = self.evidence[k]
            x, y = model.points[e.place]
            said = f'{e.low:.3f}' if e.exact else f'in [{e.low:.3f}, {e.high:.3f}]'
            lines.append(
                f'step from ({x:.2f}, {y:.2f}) direction {e.direction}: light {said}, '
                f'the best of {len(self.particles)} hypotheses ({len(lights)} lights) says '
                f'{predicted[k]:.3f}'
            )
        return lines

    def lights(self, particle: int | None = None):
        """The lights of a particle (the best by default) as Searchlights."""
        particle = self.best() if particle is None else particle
        return [
            light_from_parameters(f'inferred-{i}', *light.params)
            for i, light in enumerate(self.particles[particle].lights)
        ]


def _normalised(values: np.ndarray) -> np.ndarray:
    values = np.maximum(np.asarray(values, dtype=np.float64), 1e-12)
    return values / values.sum()


def _lamp_places(world: LightWorld) -> np.ndarray:
    """(k, 2): free places every _LAMP_STRIDE m, where a birth may put a lamp."""
    frame, blocked = world.points.frame, world.points.blocked
    height, width = blocked.shape
    stride = max(1, round(_LAMP_STRIDE / frame.resolution))
    rows, cols = np.mgrid[stride // 2 : height : stride, stride // 2 : width : stride]
    free = ~blocked[rows, cols]
    x, y = frame.cell_centre(cols[free], rows[free])
    return np.stack([x, y], axis=1)
