"""The learner `light-model`: infers the searchlights from what its steps tell it, and plans
against what it believes. Plain Python + numpy, no rclpy.

Where the tabular learners pay for every lit move once, this one reads each step's reward as
the light it met (``stealth_core.light_world``), keeps the light hypotheses that explain every
step so far (``stealth_core.light_belief``), and after each episode (and whenever a step
surprises the current plan) plans by value iteration on the lattice against that belief. Its
Q-table is the plan's action values, one row per lattice place (``attach`` gives every place
its row, so a saved table is a whole policy).

It may read the floor plan, the start, the goal, the reward weights and the law's form: the
``LightWorld`` it is attached to is the scenario with every light removed. It never sees a
light.

Greedy actions (evaluations, a saved policy) follow the ``expected`` plan; training follows
the plan of the learner's rule (``PLANNING_RULES``), as E3 keeps exploitation apart from
exploration:

- ``expected`` (the default, chosen by measurement: docs, the light model): each step is
  detected with the posterior probability that it is lit (the weighed particles that say so)
  and costs the mean light of those that do not: the plan of the posterior's mean model;
- ``optimistic``: a step is taken as a detection only where every particle of weight > 1 %
  lights it;
- ``thompson``: one particle drawn by weight for each plan, planned on as if it were the truth;
- ``cautious``: a step any particle of weight > 1 % lights is taken as a detection.

Training episodes probe where the rule's plan would teach nothing (measured on validation
buildings: docs, the light model): they follow the ``optimistic`` plan when the rule's plan,
from the start, gives up on the goal (it would wait out the step limit), and after an episode
that reached the goal when the ``optimistic`` plan promises more than ``PROBE_MARGIN`` of the
goal reward above the rule's (a shorter or darker route some weighed hypothesis lights, which
the posterior's plan would never test).

Steps the robot has taken are known exactly: their evidence overrides every particle.
"""

from __future__ import annotations

import math

import numpy as np
from stealth_core.light_belief import BeliefSettings, LightBelief
from stealth_core.light_world import LightWorld, StepEvidence, evidence_of_step
from stealth_core.planners import follow, value_iteration
from stealth_core.reward import detection_reward, step_reward, success_reward

from .learners import LearnerConfig, TabularLearner, argmax_random, register_learner

PLANNING_RULES = ('expected', 'optimistic', 'thompson', 'cautious')
DEFAULT_RULE = 'expected'
MIN_WEIGHT = 1e-3  # particles lighter than this are left out of a plan
PROBE_MARGIN = 1e-3  # of the goal reward: what a probe episode must promise to gain
SURPRISE_MOVES = 15  # Metropolis moves per particle after a surprising step, mid-episode


class LightModelError(ValueError):
    """The light model used before it knows its world, or given a world it cannot use."""


@register_learner
class LightModelLearner(TabularLearner):
    """Infers the lights (a ``LightBelief``) and acts on value iteration against it."""

    name = 'light-model'

    def __init__(self, num_actions: int, config: LearnerConfig | None = None):
        super().__init__(num_actions, config)
        self.world: LightWorld | None = None
        self.belief: LightBelief | None = None
        self.rule = DEFAULT_RULE
        self.notes: list[str] = []  # contradictions and unmatched steps, for the log
        self.replans = 0
        self._visibility: np.ndarray | None = None  # (places, directions) the plan assumed
        self._explore: np.ndarray | None = None  # training's action values (the rule's plan)
        self._probe: np.ndarray | None = None  # the optimistic plan, for probe episodes
        self._probing = False  # this training episode follows the optimistic plan
        self._reached_goal = False  # the last episode ended at the goal
        self._loaded_evidence: np.ndarray | None = None
        self.plan_margin = 0.0  # of the threshold: lit enough to plan a step as detected

    def attach(
        self,
        world: LightWorld,
        index,
        rng: np.random.Generator,
        rule: str = DEFAULT_RULE,
        settings: BeliefSettings | None = None,
        plan_margin: float = 0.0,
    ) -> None:
        """Know the world: register every lattice place's state in ``index`` (a place's row is
        its place number), start the belief (drawing from ``rng``) and plan, a step taken as
        detected where a hypothesis lights it to (1 - plan_margin) x the threshold (through ROS
        the readings of one step spread by a few per cent). LightModelError when the index
        already numbers states otherwise or the actions differ."""
        if rule not in PLANNING_RULES:
            raise LightModelError(
                f'light-model rule: expected one of {", ".join(PLANNING_RULES)}, got {rule!r}'
            )
        if not 0.0 <= plan_margin < 1.0:
            raise LightModelError(f'light-model plan_margin: expected [0, 1), got {plan_margin}')
        model = world.model
        if model.num_actions != self.num_actions:
            raise LightModelError(
                f'light-model: the world has {model.num_actions} actions, the learner '
                f'{self.num_actions}'
            )
        for place, state in enumerate(model.states):
            if index.row(state) != place:
                raise LightModelError(
                    'light-model: the state index already numbers states otherwise (attach it '
                    'to a fresh index, or to the one saved with its table)'
                )
        self.ensure_rows(model.size)
        self.world, self.rule, self.plan_margin = world, rule, float(plan_margin)
        self.belief = LightBelief(world, rng, settings)
        if self._loaded_evidence is not None:
            for place, direction, low, high in self._loaded_evidence.tolist():
                self.belief.observe(StepEvidence(int(place), int(direction), low, high))
            self._loaded_evidence = None
            self.belief.fit()
        self._plan()

    # --- acting (exploration is the plan's: no random moves) -----------------------------------

    def act(self, s: int, rng: np.random.Generator, *, greedy: bool = False) -> int:
        """Training's action: the rule's plan (the table's, ``greedy``), or the optimistic
        plan's in a probe episode (module docstring)."""
        s = self._check_row(s)
        self.ensure_rows(s + 1)
        if greedy or self._explore is None or s >= self._explore.shape[0]:
            return argmax_random(self._q[s], rng)
        if self._probing:
            return argmax_random(self._probe_values()[s], rng)
        return argmax_random(self._explore[s], rng)

    def _probe_values(self) -> np.ndarray:
        if self._probe is None:
            self._probe = self._values('optimistic')[0]
        return self._probe

    # --- learning ------------------------------------------------------------------------------

    def update(self, s, a, r, s_next, terminated, a_next=None, rng=None) -> float:
        """Read the step's light off its reward, add it to the belief, and replan when it
        surprised the plan (mid-episode: a short search). Returns the surprise, in lights."""
        s, a, r = self._check_row(s), self._check_action(a), self._check_reward(r)
        if not terminated:
            if s_next is None:
                raise ValueError('a non-terminal update needs the next state')
            s_next = self._check_row(s_next)
        belief = self._attached()
        self.updates += 1
        model = belief.world.model
        if s >= model.size:
            return 0.0
        direction = a
        if not terminated and model.successors[s, a] != s_next:
            found = np.flatnonzero(model.successors[s] == s_next) if s_next < model.size else []
            if len(found) == 0:  # not a lattice step (through ROS: the pose strayed)
                self.notes.append(f'step from place {s} by action {a} left the lattice')
                return 0.0
            direction = int(found[0])
        evidence = evidence_of_step(belief.world, s, direction, r, bool(terminated))
        if terminated:
            self._reached_goal = math.isfinite(evidence.high)
        if evidence.exact and evidence.low >= belief.world.threshold:
            self.notes.append(
                f'an undetected step read light {evidence.low:.3f}, at or above the detection '
                f'threshold {belief.world.threshold}: the reward is not the law modelled'
            )
        belief.observe(evidence)
        assumed = float(self._visibility[s, direction])
        low, high = evidence.low, evidence.high
        surprise = max(low - assumed, assumed - high, 0.0)
        tolerance = belief.settings.abs_tol + belief.settings.rel_tol * low
        if surprise > tolerance and not terminated:
            belief.fit(SURPRISE_MOVES, polish=False)
            self._plan()
        return float(surprise)

    def end_episode(self) -> None:
        """Search the belief with the whole episode's evidence, report contradictions, replan."""
        super().end_episode()
        if self.belief is None:
            return
        self.belief.fit()
        self.notes.extend(self.belief.contradictions())
        self._plan()
        self._probing = self._gives_up_from_start() or (
            self._reached_goal and self._worth_probing()
        )
        self._reached_goal = False

    def _gives_up_from_start(self) -> bool:
        """Whether the rule's plan, followed from the start (the first of tied actions), never
        enters the goal within the step limit."""
        model = self._attached().world.model
        path = follow(model, lambda place: int(np.argmax(self._explore[place])))
        return not model.goal[path[-1]]

    def _worth_probing(self) -> bool:
        """Whether the next training episode should test the optimistic plan's route: the
        rule's plan reaches the goal, the optimistic plan promises a return more than
        PROBE_MARGIN of the goal reward above it (a shorter or darker route that some heavy
        particle lights: the expected plan would never walk it, so nothing would tell)."""
        world = self._attached().world
        start = world.model.start
        margin = PROBE_MARGIN * abs(world.scenario.rewards.goal_reward)
        return bool(self._probe_values()[start].max() > self._explore[start].max() + margin)

    # --- planning ------------------------------------------------------------------------------

    def _attached(self) -> LightBelief:
        if self.belief is None:
            raise LightModelError('light-model: attach(world, index, rng) before learning')
        return self.belief

    def planned_visibility(self, rule: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(probability each step is detected, the light it costs if not), (places,
        directions), by a planning rule (the learner's by default), with the steps taken set
        to what they said."""
        rule = self.rule if rule is None else rule
        belief = self._attached()
        threshold = belief.world.threshold * (1.0 - self.plan_margin)
        weights = belief.weights()
        if rule == 'thompson':
            chosen = int(belief.rng.choice(len(weights), p=weights))
            tables, weights = [belief.step_visibility(chosen)], np.ones(1)
        else:  # the particles that carry weight (each table costs a light field)
            kept = np.flatnonzero(weights >= MIN_WEIGHT)
            tables, weights = [belief.step_visibility(k) for k in kept], weights[kept]
            weights = weights / weights.sum()
        tables = [self._with_evidence(table) for table in tables]
        lit = np.stack([table >= threshold for table in tables])
        values = np.stack(tables)
        if rule in ('cautious', 'optimistic'):
            heavy = weights > 0.01
            agree = lit[heavy].any(axis=0) if rule == 'cautious' else lit[heavy].all(axis=0)
            light = np.where(lit[heavy], 0.0, values[heavy])
            light = light.max(axis=0) if rule == 'cautious' else light.min(axis=0)
            p_detected = agree.astype(np.float64)
        else:
            w = weights[:, None, None]
            p_detected = np.clip(np.sum(w * lit, axis=0), 0.0, 1.0)
            dark_weight = np.sum(w * ~lit, axis=0)
            light = np.divide(
                np.sum(w * np.where(lit, 0.0, values), axis=0),
                dark_weight,
                out=np.zeros_like(dark_weight),
                where=dark_weight > 0,
            )
        places, directions, share, dark = belief.observed.mixed_steps()
        if places.size:  # as often detected as they were, whatever a particle says
            p_detected[places, directions] = {'cautious': 1.0, 'optimistic': 0.0}.get(rule, share)
            light[places, directions] = dark
        return p_detected, light

    def _with_evidence(self, table: np.ndarray) -> np.ndarray:
        """A particle's step visibilities with the steps taken set to what they said."""
        places, directions, low, high = self._attached().observed.clamps()
        table = table.copy()
        table[places, directions] = np.clip(table[places, directions], low, high)
        return table

    def _plan(self) -> None:
        """Value iteration against the belief: the greedy plan (the table, what evaluations
        and a saved policy follow) by the posterior's expectation, and the plan training
        follows by the learner's rule (the same where the rule is ``expected``)."""
        greedy, assumed = self._values('expected')
        self._q[: greedy.shape[0]] = greedy
        self._explore = greedy if self.rule == 'expected' else self._values(self.rule)[0]
        self._probe = None
        self._visibility = assumed
        self.replans += 1

    def _values(self, rule: str) -> tuple[np.ndarray, np.ndarray]:
        """(action values, (places, directions) the light each step is assumed to meet) of
        value iteration on the lattice with the steps' detection and light by ``rule``."""
        world = self._attached().world
        model, weights = world.model, world.scenario.rewards
        p_detected, light = self.planned_visibility(rule)
        distance = model.distance[model.successors]
        at_goal = model.goal[model.successors]
        caught = detection_reward(distance, weights)
        safe = np.where(
            at_goal,
            success_reward(distance, world.task.goal.radius, weights),
            step_reward(light, distance, weights),
        )
        result = value_iteration(model, gamma=self.config.gamma, terms=(p_detected, caught, safe))
        assumed = np.where(p_detected >= 0.5, np.maximum(light, world.threshold), light)
        return result.q, assumed

    # --- saving --------------------------------------------------------------------------------

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The plan's table and the evidence (place, direction, low, high per step)."""
        arrays = super().to_arrays()
        evidence = [] if self.belief is None else self.belief.evidence
        arrays['evidence'] = np.array(
            [(e.place, e.direction, e.low, e.high) for e in evidence], dtype=np.float64
        ).reshape(-1, 4)
        if self.belief is not None:
            belief = self.belief_arrays()
            arrays['belief_lights'], arrays['belief_weights'] = belief['lights'], belief['weights']
        return arrays

    def belief_arrays(self) -> dict[str, np.ndarray]:
        """The belief as arrays: ``lights`` (k, 7): particle, x, y, direction (rad), fov (rad),
        beta (1/m^2), range (m) of every hypothesised light (k, 12 where lights move: and kind,
        a, b, period_bins, offset, ``light_world.hypothesis_light``); ``weights``
        (particles,)."""
        belief = self._attached()
        rows = [
            (k, *light.params)
            for k, particle in enumerate(belief.particles)
            for light in particle.lights
        ]
        columns = 7 if belief.world.timing is None else 12
        return {
            'lights': np.array(rows, dtype=np.float64).reshape(-1, columns),
            'weights': belief.weights(),
        }

    def to_meta(self) -> dict:
        return {**super().to_meta(), 'rule': self.rule}

    def _load_extra(self, arrays, rows: int) -> None:
        if 'evidence' not in arrays:
            raise ValueError('light-model policy file: the evidence array is missing')
        evidence = np.asarray(arrays['evidence'], dtype=np.float64)
        if evidence.ndim != 2 or evidence.shape[1] != 4:
            raise ValueError(f'light-model evidence: expected (steps, 4), got {evidence.shape}')
        self._loaded_evidence = evidence
