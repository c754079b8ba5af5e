"""What the robot believes of the searchlights: a set of light hypotheses that explain every step
it has taken, found by stochastic search under the light law's own form. No rclpy.

The field is a sum of lights (``light_world``), each a static cone with six unknowns: the
lamp's (x, y), direction, opening angle, ``beta`` and range; where the world's lights move (it
has phase bins), a light may also sweep or patrol, with five more (``hypothesis_light``), and the
search may set it moving or stop it (``light_motion``). A *hypothesis* is a short list of such
lights; it predicts every step's visibility exactly as the environment judges it
(``LatticeSamples``). The evidence is what the steps said (``StepEvidence``: a value read off the
reward, or a bound from a detection or a goal). A hypothesis' energy is

    E = sum_k (sqrt(1 + z_k^2) - 1) + light_cost * lights (+ still_cost with no moving light
        where lights move),

z_k the step's miss in units of its tolerance (``abs_tol + rel_tol * v``: the environment's
rounding in-process, the pose noise through ROS), and the belief is ``particles`` hypotheses,
each weighed by ``exp(-E)``: an approximation of the posterior under a sparsity prior, the
number of lights included. Each fit runs Metropolis moves on every particle (birth, death,
perturbation at a random scale), annealed from ANNEAL_START down to temperature 1, then a
pattern-search polish of each light (``polish``: its parameters stepped, then its cone's edges
placed at the angles the misses ask for, ``light_polish``). A birth is proposed from the data: a
step lit more than the hypothesis says is explained by a lamp at a free place that sees it,
aimed at the unexplained steps near it, with ``beta`` their median, the place scored by how well
one ``beta`` fits them (one light's intensities ``1/(1 + beta*d^2)`` fix the ratio of its
distances). Where light bounces, a light's bounce is traced when the fit ends and kept through
the moves (a trace costs tens of ms; the direct light is recomputed at every move).

Where the evidence says nothing (rooms not yet seen) the particles hold no light: the plan is
optimistic there, and the robot finds out. A step the best particle still misses by more than
``CONTRADICTION_Z`` tolerances after a fit is a *contradiction*: the law is not the one modelled
(noise beyond the tolerance, soft edges, a motion other than a sweep or a straight patrol) or the
search has not found it yet, reported by ``contradictions``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from stealth_core import exposure
from stealth_core.light_evidence import EvidenceSet
from stealth_core.light_fields import PlanFields
from stealth_core.light_motion import (
    MOTION_POLISH_STEPS,
    STILL_TAIL,
    animated,
    motion_perturbed,
    stilled,
)
from stealth_core.light_polish import (
    EDGE_ROUNDS,
    MIN_FOV,
    POLISH_HALVINGS,
    POLISH_STEPS,
    edge_moved,
    edge_steps,
    stepped,
)
from stealth_core.light_world import (
    PATROL,
    STATIC,
    LightWorld,
    StepEvidence,
    hypothesis_light,
)

CONTRADICTION_Z = 6.0
ANNEAL_START = 30.0  # the search's first temperature, in units of energy
_LAMP_STRIDE = 0.25  # m between the candidate lamp places of a birth


@dataclasses.dataclass(frozen=True)
class BeliefSettings:
    """How the belief searches; the defaults are measured (docs: the light model)."""

    particles: int = 8
    moves: int = 120  # Metropolis moves per particle per fit
    light_cost: float = 4.0  # energy of one more light (sparsity)
    motion_cost: float = 0.0  # and of its moving (a motion's five more unknowns)
    # Of a hypothesis with no moving light where the world has phase bins, which a scenario
    # has only when a light moves.
    still_cost: float = 4.0
    abs_tol: float = 0.004  # tolerance of a read visibility, absolute
    rel_tol: float = 0.02  # and relative to it
    # m: how far the judged pose may stand off its lattice node (light_evidence; through ROS
    # the agent node's parameter pose_jitter, in-process 0: the pose is the node's)
    pose_jitter: float = 0.0
    max_range: float = 30.0  # m, the farthest a hypothesised light may reach
    max_lights: int = 12

    def __post_init__(self):
        if self.particles < 1 or self.moves < 0 or self.max_lights < 1:
            raise ValueError('belief settings: particles and max_lights >= 1, moves >= 0')
        if self.abs_tol <= 0 or self.rel_tol < 0 or self.light_cost < 0:
            raise ValueError('belief settings: abs_tol > 0, rel_tol >= 0, light_cost >= 0')
        if not 0.0 <= self.pose_jitter <= 1.0:
            raise ValueError(f'belief settings: pose_jitter in [0, 1] m, got {self.pose_jitter}')


@dataclasses.dataclass
class _Light:
    """One hypothesised light: its parameters and its light at the evidence's samples."""

    params: tuple  # x, y, direction, fov, beta, range (and kind, a, b, period_bins, offset)
    at_evidence: np.ndarray  # (distinct steps, shifts * width): its direct light
    # Its bounced light there, where light bounces (None: none yet). Tracing a light's bounce
    # costs tens of ms, so a moved light keeps its parent's until the fit's end refreshes it.
    bounced: np.ndarray | None = None

    def light(self) -> np.ndarray:
        return self.at_evidence if self.bounced is None else self.at_evidence + self.bounced

    @property
    def moving(self) -> bool:
        return len(self.params) > 6 and int(self.params[6]) != STATIC


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
        settings = self.settings
        self.observed = EvidenceSet(
            world, settings.abs_tol, settings.rel_tol, settings.pose_jitter
        )
        self.particles = [_Particle([]) for _ in range(self.settings.particles)]
        self._lamps = _lamp_places(world)
        self._sight_from: dict[tuple[int, int], np.ndarray] = {}
        self._seeing_cache: dict[tuple, object] = {}
        self.fields = PlanFields(world, self._seeing)

    # --- evidence ------------------------------------------------------------------------------

    @property
    def evidence(self) -> list[StepEvidence]:
        """What every step taken said, in order."""
        return self.observed.steps

    def observe(self, evidence: StepEvidence) -> None:
        """Add what one step said (a light learns a new step's light when next read,
        ``_current``: a stop landing part-way leaves no light short of the evidence)."""
        self.observed.observe(evidence)
        for particle in self.particles:
            particle.energy = math.inf

    def _current(self, light: _Light) -> _Light:
        """The light with its light at every distinct evidence step: the steps observed since
        it was made or last read are added (its direct and bounced light each, by its own
        count, so a half-done extension is finished on the next read)."""
        count = len(self.observed.distinct)
        have = light.at_evidence.shape[0]
        if have < count:
            extra = self._light_at(light.params, np.arange(have, count))
            light.at_evidence = np.concatenate([light.at_evidence, extra])
        if light.bounced is not None and light.bounced.shape[0] < count:
            new = np.arange(light.bounced.shape[0], count)
            light.bounced = np.concatenate([light.bounced, self._bounced_at(light.params, new)])
        return light

    def _energy(self, lights: list[_Light]) -> float:
        misses = self.observed.energy(self._total(lights))
        cost = self.settings.light_cost * len(lights)
        moving = sum(light.moving for light in lights)
        cost += self.settings.motion_cost * moving
        if self.world.timing is not None and not moving:  # the world says a light moves
            cost += self.settings.still_cost
        return misses + cost

    def _total(self, lights: list[_Light]) -> np.ndarray | None:
        """The lights' summed light at the evidence's samples (None: no light)."""
        total = None
        for light in lights:
            light = self._current(light).light()
            total = light if total is None else total + light
        return total

    def _predict(self, lights: list[_Light]) -> tuple[np.ndarray, np.ndarray]:
        """(low, high): the light the lights put on each observation's step, as a range
        (``EvidenceSet.predict``)."""
        return self.observed.predict(self._total(lights))

    def _light_at(self, params: tuple, distinct: np.ndarray | None = None) -> np.ndarray:
        """A light's direct light at the samples of distinct evidence steps (all by default)."""
        light = hypothesis_light('hypothesis', params, self.world.timing)
        return self.observed.light_at(self.world.see([light], bounce=False), distinct)

    def _seeing(self, params: tuple):
        """The point visibility of one light, bounce included, kept while its light is asked
        (its bounce's emitters are traced once)."""
        see = self._seeing_cache.get(params)
        if see is None:
            see = self.world.see([hypothesis_light('hypothesis', params, self.world.timing)])
            if len(self._seeing_cache) >= 64:
                self._seeing_cache.pop(next(iter(self._seeing_cache)))
            self._seeing_cache[params] = see
        return see

    def _bounced_at(self, params: tuple, distinct: np.ndarray | None = None) -> np.ndarray:
        """A light's bounced light at the samples of distinct evidence steps (all by default)."""
        seen = self.observed.light_at(self._seeing(params), distinct)
        return seen - self._light_at(params, distinct)

    def _make(self, params: tuple, parent: _Light | None = None) -> _Light:
        """A light at params (its bounced light the parent's until the fit's end traces its
        own: ``_Light.bounced``)."""
        bounced = None if parent is None else self._current(parent).bounced
        return _Light(params, self._light_at(params), bounced)

    def _refresh_bounce(self, particle: _Particle) -> None:
        """Trace the bounce of every light of a particle afresh, and its energy with it."""
        if self.world.bounces:
            for light in particle.lights:
                light.bounced = self._bounced_at(light.params)
            particle.energy = self._energy(particle.lights)

    # --- search --------------------------------------------------------------------------------

    def fit(self, moves: int | None = None, polish: bool = True) -> None:
        """Metropolis moves on every particle (``settings.moves`` each by default), then each
        particle's lights polished (``polish``)."""
        moves = self.settings.moves if moves is None else moves
        if not self.evidence:
            return
        for particle in self.particles:
            if not math.isfinite(particle.energy):
                particle.energy = self._energy(particle.lights)
            for move in range(moves):
                proposal = self._propose(particle.lights)
                if proposal is None:
                    continue
                energy = self._energy(proposal)
                # Annealed from ANNEAL_START down to 1 (the posterior's own temperature): the
                # misses are counted in tolerances, so the landscape is rugged when cold.
                temperature = ANNEAL_START ** (1.0 - move / max(moves - 1, 1))
                if energy <= particle.energy or self.rng.random() < math.exp(
                    (particle.energy - energy) / temperature
                ):
                    particle.lights, particle.energy = proposal, energy
            if polish:
                self.polish(particle)
            self._refresh_bounce(particle)

    def polish(self, particle: _Particle, halvings: int = POLISH_HALVINGS) -> None:
        """Pattern search on each light of a particle: every parameter stepped both ways, a
        step that lowers the energy kept, a step that does not halved, ``halvings`` times;
        then each light's cone edges placed where the misses ask (``_place_edges``). The
        Metropolis moves find a light near the truth; this fits it to the tolerances."""
        if not math.isfinite(particle.energy):
            particle.energy = self._energy(particle.lights)
        for k in range(len(particle.lights)):
            params = particle.lights[k].params
            kind = STATIC if len(params) == 6 else int(params[6])
            for parameter, first in POLISH_STEPS + MOTION_POLISH_STEPS.get(kind, ()):
                step = first
                for _ in range(halvings):
                    for sign in (1.0, -1.0):
                        params = stepped(particle.lights[k].params, parameter, sign * step)
                        tried = self._with_light(particle, k, params)
                        if tried is not None and tried[0] < particle.energy:
                            particle.energy, particle.lights = tried
                            break
                    else:
                        step /= 2
        for k in range(len(particle.lights)):
            self._place_edges(particle, k)

    def _place_edges(self, particle: _Particle, k: int) -> None:
        """Light k's cone edges set where the misses ask (``light_polish.edge_steps``): of
        the moves, the one that lowers the energy most kept, ``EDGE_ROUNDS`` times."""
        for _ in range(EDGE_ROUNDS):
            params = particle.lights[k].params
            too_dark, too_bright = self.observed.wanting(*self._predict(particle.lights))
            moves = edge_steps(
                hypothesis_light('hypothesis', params, self.world.timing),
                params,
                self.observed.sample_points(too_dark),
                self.observed.sample_points(too_bright),
            )
            best = None
            for edge, delta in moves:
                tried = self._with_light(particle, k, edge_moved(params, edge, delta))
                if tried is not None and tried[0] < (particle.energy if best is None else best[0]):
                    best = tried
            if best is None:
                return
            particle.energy, particle.lights = best

    def _with_light(self, particle: _Particle, k: int, params: tuple | None):
        """(energy, lights) of the particle with light k's parameters replaced (None where
        ``params`` is None or its lamp stands in a wall)."""
        if params is None or not self._placeable(params):
            return None
        lights = [*particle.lights[:k], self._make(params, particle.lights[k])]
        lights += particle.lights[k + 1 :]
        return self._energy(lights), lights

    def _propose(self, lights: list[_Light]) -> list[_Light] | None:
        kind = self.rng.random()
        if kind < 0.3 or not lights:
            born = self._birth(lights)
            return None if born is None else [*lights, born]
        k = int(self.rng.integers(len(lights)))
        if kind < 0.4:
            return lights[:k] + lights[k + 1 :]
        if self.world.timing is not None and kind < 0.55:  # set moving, or stopped
            light, timing = lights[k], self.world.timing
            if light.moving:
                params = stilled(light.params, self._lit_time(light), timing)
            else:
                params = self._animated(light)
        elif lights[k].moving and kind < 0.75:
            params = motion_perturbed(
                self.rng, lights[k].params, self.world.timing, self._rail_free
            )
        else:
            params = self._perturbed(lights[k].params)
        if params is None:
            return None
        return [*lights[:k], self._make(params, lights[k]), *lights[k + 1 :]]

    # --- moving lights (a world with timing) ---------------------------------------------------

    def _lit_time(self, light: _Light) -> float:
        """The time of the evidence sample the light lights most (a random time of the cycle
        when it lights none): where a motion keeps it."""
        lit = self._current(light).at_evidence
        if lit.size == 0 or lit.max() <= 0.0:
            return float(self.rng.uniform(0.0, self.world.timing.cycle))
        row, column = np.unravel_index(int(np.argmax(lit)), lit.shape)
        return self.observed.sample_time(int(row), int(column))

    def _animated(self, light: _Light) -> tuple | None:
        when = self._lit_time(light)
        return animated(self.rng, light.params, when, self.world.timing, self._rail_free)

    def _rail_free(self, start, end) -> bool:
        """Whether a patrol's rail runs over free places only (every 0.1 m)."""
        steps = max(2, math.ceil(float(np.hypot(*(end - start))) / 0.1) + 1)
        points = start + (end - start) * np.linspace(0.0, 1.0, steps)[:, None]
        return not any(self._blocked(px, py) for px, py in points)

    def _perturbed(self, params: tuple) -> tuple | None:
        x, y, direction, fov, beta, light_range = params[:6]
        tail = params[6:]
        rng = self.rng
        which = int(rng.integers(5))
        scale = 10.0 ** rng.uniform(-1.5, 0.0)  # coarse moves to find, fine ones to fit
        if which == 0:
            x, y = x + rng.normal(0, 0.4 * scale), y + rng.normal(0, 0.4 * scale)
            if self._blocked(x, y):
                return None
        elif which == 1:
            direction += rng.normal(0, math.radians(10.0) * scale)
        elif which == 2:
            fov = float(
                np.clip(fov + rng.normal(0, math.radians(10.0) * scale), MIN_FOV, 2 * math.pi)
            )
        elif which == 3:
            beta *= math.exp(rng.normal(0, 0.3 * scale))
        else:
            light_range = float(
                np.clip(light_range + rng.normal(0, 1.0 * scale), 0.2, self.settings.max_range)
            )
        if tail and int(tail[0]) == PATROL and which == 0:  # the rail moves with its lamp
            tail = (tail[0], tail[1] + x - params[0], tail[2] + y - params[1], *tail[3:])
            if not self._rail_free(np.array([x, y]), np.array(tail[1:3])):
                return None
        return (x, y, direction, fov, beta, light_range, *tail)

    def _placeable(self, params: tuple) -> bool:
        """Whether a light's lamp (and a patrol's whole rail) stands on free places."""
        if len(params) > 6 and int(params[6]) == PATROL:
            return self._rail_free(np.array(params[:2]), np.array(params[7:9]))
        return not self._blocked(params[0], params[1])

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
        observed = self.observed
        _, most = self._predict(lights)
        missing = np.where(np.isfinite(observed.high), observed.high, observed.low) - most
        candidates = np.flatnonzero(missing > observed.tolerance())
        if candidates.size == 0:
            return None
        k = int(candidates[self.rng.choice(candidates.size, p=_normalised(missing[candidates]))])
        target = float(missing[k])
        if not np.isfinite(observed.high[k]):  # a detection: at least that much more
            target += float(self.rng.uniform(0.0, 0.5))
        target = min(target, 0.95)
        found = self._lamp_for(k, target, candidates, missing)
        if found is None:
            return None
        lamp, points, intensities = found
        # Aimed at the middle of the lit steps it explains, opened to take them all in; beta
        # the median their distances and intensities imply.
        offsets = points - lamp
        distances = np.maximum(np.hypot(*offsets.T), 0.1)
        beta = float(np.median((1.0 / intensities - 1.0) / distances**2))
        first = math.atan2(offsets[0, 1], offsets[0, 0])
        turns = np.angle(np.exp(1j * (np.arctan2(offsets[:, 1], offsets[:, 0]) - first)))
        aim = first + (turns.min() + turns.max()) / 2
        fov = float(
            np.clip(
                turns.max() - turns.min() + math.radians(self.rng.uniform(5.0, 40.0)),
                math.radians(10.0),
                2 * math.pi,
            )
        )
        distance = float(distances.max())
        delta = 0.1 if self.rng.random() < 0.5 else math.exp(self.rng.uniform(-3.5, -0.7))
        light_range = math.sqrt((1.0 - delta) / (delta * beta))
        if light_range < distance:
            light_range = distance + float(self.rng.uniform(0.0, 1.0))
        light_range = min(light_range, self.settings.max_range)
        params = (float(lamp[0]), float(lamp[1]), aim, fov, beta, light_range)
        if self.world.timing is None:
            return self._make(params)
        born = self._make((*params, *STILL_TAIL))
        if self.rng.random() < 0.5:  # where lights move, half the births move
            moving = self._animated(born)
            if moving is not None:
                return self._make(moving)
        return born

    def _lamp_for(self, k: int, target: float, candidates, missing):
        """(lamp place, points, the unweighted intensities there) for evidence step k: a lamp
        place in sight of the step, scored by how well one beta explains the step and the
        unexplained steps within 4 m of it (each by its arrival and missing light; where
        exposure weighs the lights, divided by the share of the robot the lamp would see)."""
        samples = self.world.samples
        # Where exposure weighs the lights, column 0 is the move's first sample, not its arrival,
        # and the share is the drive's, not the brightest sample's: fixing both made the learner
        # worse (it was cautious by this), so it stays until caution is built in (docs: the
        # light model, "why the fix is not in").
        arrival = samples.width - 1 if not samples.weighs_heading else 0
        observed = self.observed
        others = candidates[np.isfinite(observed.high[candidates]) & (candidates != k)]
        rows = observed.rows[np.append(k, others)]
        points = np.stack([samples.x[rows, arrival], samples.y[rows, arrival]], 1)
        values = np.minimum(np.append(target, missing[others]), 0.95)
        close = np.hypot(*(points - points[0]).T) <= 4.0
        close[0] = True
        keep = np.flatnonzero(close)[:13]
        points, values, rows = points[keep], values[keep], rows[keep]
        anchor = points[0]
        lamps = self._lamps
        near = np.hypot(*(lamps - anchor).T) <= self.settings.max_range
        near &= self._seen_from(anchor)
        lamps = lamps[near]
        if lamps.size == 0:
            return None
        dx = points[None, :, 0] - lamps[:, None, 0]  # (lamps, points)
        dy = points[None, :, 1] - lamps[:, None, 1]
        intensities = np.broadcast_to(values, dx.shape)
        footprint = self.world.task.footprint
        if samples.weighs_heading and footprint is not None:
            share = exposure.factor(footprint, samples.yaw[rows, arrival][None, :], dx, dy)
            intensities = intensities / np.maximum(share, 1e-3)
        intensities = np.clip(intensities, 1e-6, 0.95)
        log_beta = np.log((1.0 / intensities - 1.0) / np.maximum(dx * dx + dy * dy, 0.01))
        spread = log_beta.std(axis=1) if len(points) > 1 else np.zeros(len(lamps))
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
                return lamp, points, intensities[index]
        return None

    def _seen_from(self, anchor) -> np.ndarray:
        """(lamp places,) bool: the lamp places in sight of the anchor's cell, traced from the
        anchor in one call (the line is nearly symmetric; the lamp chosen is checked exactly)."""
        cell = self.world.points.frame.cell_of(*anchor)
        mask = self._sight_from.get(cell)
        if mask is None:
            mask = self.world.points.sight_from(*anchor, *self._lamps.T)
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
        return self.fields.step_visibility(self.particles[particle].lights)

    def best(self) -> int:
        return int(np.argmax(self.weights()))

    def contradictions(self) -> list[str]:
        """The evidence steps the best particle misses by more than CONTRADICTION_Z tolerances:
        one line each, naming the step, what it said and what the belief says."""
        if not self.evidence:
            return []
        lights = self.particles[self.best()].lights
        low, high = self._predict(lights)
        z = self.observed.misses(low, high)
        lines = []
        model = self.world.model
        for k in np.flatnonzero(z > CONTRADICTION_Z):
            e = self.evidence[k]
            x, y = model.points[e.place]
            said = f'{e.low:.3f}' if e.exact else f'in [{e.low:.3f}, {e.high:.3f}]'
            says = f'{low[k]:.3f}' if low[k] == high[k] else f'{low[k]:.3f} to {high[k]:.3f}'
            lines.append(
                f'step from ({x:.2f}, {y:.2f}) direction {e.direction}: light {said}, '
                f'the best of {len(self.particles)} hypotheses ({len(lights)} lights) says '
                f'{says}'
            )
        return lines

    def lights(self, particle: int | None = None):
        """The lights of a particle (the best by default) as Searchlights."""
        particle = self.best() if particle is None else particle
        return [
            hypothesis_light(f'inferred-{i}', light.params, self.world.timing)
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
