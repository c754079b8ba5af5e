"""Rewards: what one step pays, whether it ends the episode, and why the weights are sane.

With d the distance from the robot to the goal point (m), v the total visibility there
(unitless) and w the ``RewardWeights``, a step ends in one of three ways, checked in this order:

- detected (``v >= detection_threshold``, or in 'probabilistic' mode with probability
  ``1 - 2**(-v/detection_threshold)``, i.e. 1/2 at the threshold): terminal, paying
  ``-(detection_penalty + detection_distance_weight * d)``; being seen on the goal is still
  being seen;
- goal reached (``d <= goal_radius``): terminal, paying
  ``goal_reward + goal_distance_weight * (goal_radius - d)``, more the closer to the point;
- otherwise ``-(visibility_weight * v + distance_weight * d + time_cost)``, terminal (TIMEOUT)
  only when the caller says the step limit is hit.

The original paid ``-100*v + 50/d`` on detection, a *positive* reward for being caught near the
goal. Here every weight is >= 0, so detection always costs and the goal always pays, and
``check_well_posed`` proves the rest for a given map and step limit (see its docstring).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
import enum
import math
from typing import NamedTuple

import numpy as np

DETECTION_MODES = ('threshold', 'probabilistic')


class RewardError(ValueError):
    """Reward weights or step inputs that are invalid or make the task ill-posed."""


class EpisodeOutcome(enum.IntEnum):
    """How an episode ended; the values are stealth_interfaces/EpisodeSummary's constants."""

    SUCCESS = 0
    DETECTED = 1
    TIMEOUT = 2
    ABORTED = 3


@dataclass(frozen=True)
class RewardWeights:
    """Every weight of the reward (the scenario YAML's ``rewards:`` keys); all >= 0.

    Units: goal_reward, detection_penalty and time_cost are reward units; goal_distance_weight,
    detection_distance_weight and distance_weight are reward per metre; visibility_weight is
    reward per unit of total visibility.
    """

    goal_reward: float = 1000.0
    goal_distance_weight: float = 100.0
    detection_penalty: float = 1000.0
    detection_distance_weight: float = 10.0
    visibility_weight: float = 1.0
    distance_weight: float = 0.05
    time_cost: float = 0.0

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, bool) or not isinstance(value, int | float | np.number):
                raise RewardError(
                    f'reward weight {item.name!r}: expected a finite number >= 0, got {value!r}'
                )
            number = float(value)
            if not math.isfinite(number) or number < 0.0:
                raise RewardError(
                    f'reward weight {item.name!r}: expected a finite number >= 0, got {value!r}'
                )
            object.__setattr__(self, item.name, number)
        for name in ('goal_reward', 'detection_penalty'):
            if getattr(self, name) == 0.0:
                raise RewardError(f'reward weight {name!r}: expected a number > 0, got 0.0')


class StepResult(NamedTuple):
    reward: float
    terminal: bool
    outcome: EpisodeOutcome | None  # None while the episode goes on


def success_reward(distance: float, goal_radius: float, weights: RewardWeights) -> float:
    """Reward for arriving within goal_radius, distance (m) from the goal point."""
    return weights.goal_reward + weights.goal_distance_weight * (goal_radius - distance)


def detection_reward(distance: float, weights: RewardWeights) -> float:
    """Reward (negative) for being detected with distance (m) still to go."""
    return -(weights.detection_penalty + weights.detection_distance_weight * distance)


def step_reward(visibility: float, distance: float, weights: RewardWeights) -> float:
    """Reward (<= 0) of an ordinary, undetected step."""
    return -(
        weights.visibility_weight * visibility
        + weights.distance_weight * distance
        + weights.time_cost
    )


def detection_probability(visibility: float, detection_threshold: float) -> float:
    """Probability of being seen in 'probabilistic' mode: 0 in the dark, 1/2 at the threshold."""
    return 1.0 - 2.0 ** (-visibility / detection_threshold)


def is_detected(
    visibility: float,
    detection_threshold: float,
    detection_mode: str = 'threshold',
    rng: np.random.Generator | None = None,
) -> bool:
    if detection_mode == 'threshold':
        return visibility >= detection_threshold
    if detection_mode == 'probabilistic':
        if rng is None:
            raise RewardError("detection_mode 'probabilistic' needs a np.random.Generator rng")
        return bool(rng.random() < detection_probability(visibility, detection_threshold))
    raise RewardError(f'detection_mode: expected one of {DETECTION_MODES}, got {detection_mode!r}')


def _finite(name: str, value: float, positive: bool = False) -> float:
    number = float(value)
    if not math.isfinite(number) or number < 0.0 or (positive and number == 0.0):
        expected = 'a finite number > 0' if positive else 'a finite number >= 0'
        raise RewardError(f'{name}: expected {expected}, got {value!r}')
    return number


def step_outcome(
    visibility: float,
    distance: float,
    *,
    goal_radius: float,
    detection_threshold: float,
    weights: RewardWeights,
    detection_mode: str = 'threshold',
    rng: np.random.Generator | None = None,
    timed_out: bool = False,
) -> StepResult:
    """Judge the state a step led to: (reward, terminal, outcome)."""
    visibility = _finite('visibility', visibility)
    distance = _finite('distance to goal', distance)
    goal_radius = _finite('goal_radius', goal_radius, positive=True)
    detection_threshold = _finite('detection_threshold', detection_threshold, positive=True)
    if is_detected(visibility, detection_threshold, detection_mode, rng):
        return StepResult(detection_reward(distance, weights), True, EpisodeOutcome.DETECTED)
    if distance <= goal_radius:
        return StepResult(
            success_reward(distance, goal_radius, weights), True, EpisodeOutcome.SUCCESS
        )
    reward = step_reward(visibility, distance, weights)
    if timed_out:
        return StepResult(reward, True, EpisodeOutcome.TIMEOUT)
    return StepResult(reward, False, None)


def undetected_visibility_bound(
    detection_mode: str, detection_threshold: float, n_lights: int, bounced: float = 0.0
) -> float:
    """Largest total visibility an undetected step can have.

    Below the threshold in 'threshold' mode; in 'probabilistic' mode anything a robot can meet,
    and every light gives at most 1, so the number of lights, plus ``bounced``, a bound of the
    light bounced off walls (``bounce.bounce_bound``).
    """
    if detection_mode == 'threshold':
        return float(detection_threshold)
    if detection_mode == 'probabilistic':
        return float(n_lights) + float(bounced)
    raise RewardError(f'detection_mode: expected one of {DETECTION_MODES}, got {detection_mode!r}')


def check_well_posed(
    weights: RewardWeights,
    *,
    max_distance: float,
    max_visibility: float,
    max_steps: int | None = None,
) -> None:
    """Raise RewardError unless getting caught is never worth it and the goal is the best.

    max_distance: the largest distance to the goal a robot can be at (the map's diagonal);
    max_visibility: see ``undetected_visibility_bound``; max_steps: the episode step limit.

    Guarantees, for every distance d in [0, max_distance] and visibility v in
    [0, max_visibility]:

    1. (same place) ``detection_reward(d) < step_reward(v, d)``: being detected is worse than
       any undetected step from the same place. Both sides are linear in d, so checking
       d = 0 and d = max_distance at v = max_visibility is exact.
    2. (goal best) every success reward (>= goal_reward > 0) beats every step reward (<= 0)
       and every detection reward (< 0); it holds for any valid weights.
    3. (whole episode, when max_steps is given) the return of any episode that ends in
       detection, at most ``-detection_penalty``, is below the return of any undetected
       episode, at least ``-max_steps * worst step cost``: detection_penalty must exceed
       ``max_steps * (visibility_weight*max_visibility + distance_weight*max_distance +
       time_cost)``. So no policy gains by getting caught to stop paying step costs.
    """
    max_distance = _finite('max_distance', max_distance)
    max_visibility = _finite('max_visibility', max_visibility)
    for d in (0.0, max_distance):
        caught = detection_reward(d, weights)
        worst_step = step_reward(max_visibility, d, weights)
        if not caught < worst_step:
            raise RewardError(
                f'ill-posed rewards: being detected at distance {d:g} m pays {caught:g}, not less'
                f' than an undetected step there with visibility {max_visibility:g}'
                f' ({worst_step:g}); raise detection_penalty or detection_distance_weight'
            )
    if max_steps is None:
        return
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise RewardError(f'max_steps: expected an integer >= 1, got {max_steps!r}')
    worst_episode = -max_steps * step_reward(max_visibility, max_distance, weights)
    if not weights.detection_penalty > worst_episode:
        raise RewardError(
            f'ill-posed rewards: an undetected episode of {max_steps} steps can cost up to'
            f' {worst_episode:g}, not less than detection_penalty {weights.detection_penalty:g};'
            ' getting caught could end a bad episode cheaply. Raise detection_penalty above'
            f' {worst_episode:g} or lower the per-step weights'
        )
