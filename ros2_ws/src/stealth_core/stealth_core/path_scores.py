"""Path and exposure scores of an episode against value iteration's optimum, and the success
criterion on them: what "the learner found a good covert path" means everywhere (the harness,
`stealth train`'s stop, sweeps, the benchmark, path.png). No rclpy.

A return does not say it: the goal reward (1000) dominates it, so almost any undetected route
is within 5 % of the optimum's, and through ROS the goal reward depends on the continuous
pose's distance to the goal point, so a learned path can "beat" the optimum. The scores are
the figures a reader judges a covert path by, each measured as the task judges a step
(``StealthTask.judge`` through ``planners.walk`` on the lattice, or the environment's
``EpisodeStats`` on the true pose):

- steps: actions taken (waits and turns included);
- path length (m): the straight distances between consecutive poses, summed;
- peak exposure: the most light (total visibility, unitless) of any step;
- accumulated exposure: every step's visibility summed (unitless), as ``EpisodeStats`` sums
  it: the light the reward charges ``visibility_weight`` for.

``Criterion``: an episode meets it when it reached the goal undetected (outcome SUCCESS), its
path is at most ``max_path_ratio`` times the optimum's, and its accumulated exposure at most
the optimum's plus ``exposure_tolerance``. Through ROS the ratios are taken on the lattice
nodes the robot was sent to (``replay_actions``: the episode's actions from the start on
``lattice_model.LatticeModel``, judged as value iteration judges its own path), the continuous
pose's figures reported beside them; the outcome is the environment's (the true pose's).

The optimum is undiscounted (``OPTIMUM_GAMMA``), as the task's return is, and the learners
learn at that gamma too (the harness's settings, `stealth train`'s agent.yaml): a learner
discounting at 0.99 converges to the discounted optimum, which on the moving-light scenarios
saves a wait step by walking through more light (floorplan-moving: 191 steps and exposure 1.826
against 192 and 0.659; simple-maze-moving: 85 and 0.899 against 86 and 0.785), so even a
converged learner failed the criterion there. Judging against the discounted optimum instead
would call that route "the best possible" and pass 2.8x the light.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import dataclasses
import math

from stealth_core.lattice_model import LatticeModel
from stealth_core.planners import PathResult, follow, value_iteration, walk
from stealth_core.reward import EpisodeOutcome

DEFAULT_MAX_PATH_RATIO = 1.1
DEFAULT_EXPOSURE_TOLERANCE = 0.1  # unitless: total visibility summed over the steps
# The discount of the optimum the criterion compares with, and of the learners' defaults: none.
OPTIMUM_GAMMA = 1.0
EPSILON = 1e-9  # rounding allowed at a bound (1.1 x 5.0 m is 5.500000000000001 m)
# Validated ranges: (low, high), both included.
MAX_PATH_RATIO_RANGE = (1.0, 10.0)
EXPOSURE_TOLERANCE_RANGE = (0.0, 100.0)
OPTION_RANGES = {
    'max_path_ratio': MAX_PATH_RATIO_RANGE,
    'exposure_tolerance': EXPOSURE_TOLERANCE_RANGE,
}
# Each option's name on a command line, for the one line that names it.
OPTION_FLAGS = {
    'max_path_ratio': '--max-path-ratio',
    'exposure_tolerance': '--exposure-tolerance',
}


class CriterionError(ValueError):
    """A criterion option out of its range: one line naming the option and the range."""


@dataclasses.dataclass(frozen=True)
class PathScores:
    """One episode's (or path's) figures."""

    outcome: EpisodeOutcome | None  # None: the path ended before anything ended the episode
    steps: int
    path_length: float  # m
    peak_exposure: float  # unitless
    accumulated_exposure: float  # unitless

    @property
    def detected(self) -> bool:
        return self.outcome is EpisodeOutcome.DETECTED

    @property
    def reached(self) -> bool:
        """Reached the goal undetected."""
        return self.outcome is EpisodeOutcome.SUCCESS

    @classmethod
    def of_path(cls, result: PathResult) -> PathScores:
        """The scores of a path walked through the lattice model (``planners.walk``)."""
        return cls(
            result.outcome,
            int(result.steps),
            float(result.path_length),
            float(result.peak_visibility),
            float(result.accumulated_visibility),
        )

    @classmethod
    def of_summary(cls, summary: Mapping) -> PathScores:
        """The scores of an EpisodeSummary's fields (``EpisodeSummaryFields._asdict()``, the
        harness's ``final``, an episodes.csv row): outcome, steps, path_length,
        peak_visibility, accumulated_visibility. The outcome may be an EpisodeOutcome, its
        value or its name."""
        return cls(
            _outcome(summary['outcome']),
            int(summary['steps']),
            float(summary['path_length']),
            float(summary['peak_visibility']),
            float(summary['accumulated_visibility']),
        )


def _outcome(value) -> EpisodeOutcome | None:
    if value is None or value == '':
        return None
    if isinstance(value, str):
        return EpisodeOutcome[value]
    return EpisodeOutcome(int(value))


def mean_scores(tries: Sequence[PathScores]) -> PathScores:
    """Several rollouts of one policy (with slip) as one: the mean figures, the peak the
    largest; the outcome SUCCESS only when every one reached the goal, else DETECTED when any
    was seen, else the first one that was not a success."""
    if not tries:
        raise ValueError('mean_scores: expected at least one rollout')
    outcomes = [t.outcome for t in tries]
    if all(o is EpisodeOutcome.SUCCESS for o in outcomes):
        outcome = EpisodeOutcome.SUCCESS
    elif EpisodeOutcome.DETECTED in outcomes:
        outcome = EpisodeOutcome.DETECTED
    else:
        outcome = next(o for o in outcomes if o is not EpisodeOutcome.SUCCESS)
    count = len(tries)
    return PathScores(
        outcome,
        round(sum(t.steps for t in tries) / count),
        sum(t.path_length for t in tries) / count,
        max(t.peak_exposure for t in tries),
        sum(t.accumulated_exposure for t in tries) / count,
    )


def _ratio(value: float, reference: float) -> float:
    """value / reference; 1 when both are 0, inf when only the reference is."""
    if reference == 0.0:
        return 1.0 if value == 0.0 else math.inf
    return value / reference


@dataclasses.dataclass(frozen=True)
class Comparison:
    """Scores against the optimum's: ratios (1 = the optimum's figure) and the exposure
    excess (accumulated exposure minus the optimum's, unitless)."""

    steps_ratio: float
    path_ratio: float
    peak_ratio: float
    exposure_ratio: float
    exposure_excess: float

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def compare(scores: PathScores, optimum: PathScores) -> Comparison:
    return Comparison(
        _ratio(scores.steps, optimum.steps),
        _ratio(scores.path_length, optimum.path_length),
        _ratio(scores.peak_exposure, optimum.peak_exposure),
        _ratio(scores.accumulated_exposure, optimum.accumulated_exposure),
        scores.accumulated_exposure - optimum.accumulated_exposure,
    )


def check_option(name: str, value, low: float, high: float) -> float:
    """``value`` as a float in [low, high]; CriterionError naming the option otherwise."""
    flag = OPTION_FLAGS.get(name, name)
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool) or not low <= number <= high:
        raise CriterionError(f'{flag}: expected a number in [{low:g}, {high:g}], got {value!r}')
    return number


@dataclasses.dataclass(frozen=True)
class Criterion:
    """The success criterion's options (module docstring), validated on construction
    (CriterionError naming the option and its range)."""

    max_path_ratio: float = DEFAULT_MAX_PATH_RATIO
    exposure_tolerance: float = DEFAULT_EXPOSURE_TOLERANCE

    def __post_init__(self) -> None:
        for name, (low, high) in OPTION_RANGES.items():
            object.__setattr__(self, name, check_option(name, getattr(self, name), low, high))

    def describe(self) -> str:
        """The criterion in words, for reports."""
        return (
            f"reached the goal undetected, path <= {self.max_path_ratio:g}x the optimum's and "
            f"accumulated exposure <= the optimum's + {self.exposure_tolerance:g}"
        )

    def short(self) -> str:
        """The criterion in a few words, for table headers and legends."""
        return f'path <= {self.max_path_ratio:g}x, exposure <= opt + {self.exposure_tolerance:g}'


DEFAULT_CRITERION = Criterion()


def failures(
    scores: PathScores, optimum: PathScores, options: Criterion = DEFAULT_CRITERION
) -> list[str]:
    """Why ``scores`` do not meet the criterion against ``optimum`` (empty when they do)."""
    reasons = []
    if scores.outcome is not EpisodeOutcome.SUCCESS:
        name = 'unfinished' if scores.outcome is None else scores.outcome.name.lower()
        reasons.append(name)
    path = _ratio(scores.path_length, optimum.path_length)
    if not scores.path_length <= options.max_path_ratio * optimum.path_length + EPSILON:
        reasons.append(f'path {path:.2f}x > {options.max_path_ratio:g}x')
    excess = scores.accumulated_exposure - optimum.accumulated_exposure
    if not excess <= options.exposure_tolerance + EPSILON:
        reasons.append(f'exposure +{excess:.3f} > +{options.exposure_tolerance:g}')
    return reasons


def meets_criterion(
    scores: PathScores, optimum: PathScores, options: Criterion = DEFAULT_CRITERION
) -> bool:
    """Whether ``scores`` meet the success criterion against the optimum's (module
    docstring). The one test every caller uses."""
    return not failures(scores, optimum, options)


def score_columns(
    scores: PathScores, optimum: PathScores, options: Criterion = DEFAULT_CRITERION
) -> dict:
    """The score columns every report writes of a path against the optimum's (episodes.csv,
    the harness's runs.csv): path_over_optimum (path length ratio), exposure_over_optimum
    (accumulated exposure excess) and meets_criterion."""
    versus = compare(scores, optimum)
    return {
        'path_over_optimum': versus.path_ratio,
        'exposure_over_optimum': versus.exposure_excess,
        'meets_criterion': meets_criterion(scores, optimum, options),
    }


def optimum_path(model: LatticeModel) -> PathResult:
    """Value iteration's path on the model (no slip, undiscounted: ``OPTIMUM_GAMMA``), walked:
    what the criterion compares an episode against (``planners.optimal_path`` of the model)."""
    optimum = value_iteration(model, gamma=OPTIMUM_GAMMA)
    return walk(model, follow(model, lambda i: int(optimum.policy[i])))


def replay_actions(model: LatticeModel, actions: Sequence[int]) -> PathResult:
    """The episode the actions make on the lattice from the start (no slip), walked and judged
    as ``planners.walk`` judges value iteration's own path: through ROS, the lattice nodes the
    robot was sent to. It stops where the lattice episode ends (goal, detection, step limit);
    ValueError for an action the scenario does not have."""
    path = [model.start]
    for action in actions:
        if not 0 <= int(action) < model.num_actions:
            raise ValueError(
                f'action {action!r}: the scenario has actions 0-{model.num_actions - 1}'
            )
        path.append(int(model.successors[path[-1], int(action)]))
    return walk(model, path)


def polyline_length(points) -> float:
    """The length (m) of a path of (x, y, ...) points: the straight distances between
    consecutive points, summed (as EpisodeStats sums the true pose's)."""
    pairs = zip(points, points[1:], strict=False)
    return float(sum(math.dist(a[:2], b[:2]) for a, b in pairs))


def describe(scores: PathScores, optimum: PathScores | None = None) -> str:
    """Scores in a few words (a legend's), with their ratios to the optimum's when given."""
    outcome = 'unfinished' if scores.outcome is None else scores.outcome.name.lower()
    text = f'{outcome}, {scores.steps} steps, {scores.path_length:.1f} m'
    if optimum is not None:
        text += f' ({_ratio(scores.path_length, optimum.path_length):.2f}x)'
    text += f', exposure {scores.accumulated_exposure:.2f}'
    if optimum is not None:
        excess = scores.accumulated_exposure - optimum.accumulated_exposure
        text += f' ({excess:+.2f})'
    return text + f', peak {scores.peak_exposure:.2f}'
