"""Each episode of a ROS run scored against value iteration's optimum
(``stealth_core.path_scores``) and judged by the success criterion, from what the orchestrator
already receives. No rclpy.

Through ROS the return is not comparable to the optimum's (the goal reward depends on the
continuous pose's distance to the goal point), so the scores are taken where they are: on the
**lattice** nodes the robot was sent to (the episode's actions, StepInfo.action, replayed from
the start on ``lattice_model.LatticeModel`` and judged as value iteration judges its own path:
``path_scores.replay_actions``), the figures the criterion compares; beside them the
continuous pose's, labelled: the **true** pose's path length (EpisodeSummary.path_length, its
ratio to the optimum's) and the **estimate**'s (StepInfo.estimated_pose, from the start). The
episode's outcome is the environment's (the true pose's): the criterion asks that it reached
the goal undetected, that the lattice path was not seen either (a robot sent through a lit node
that got away with it does not count), and that the lattice path is at most
``max_path_ratio`` x the optimum's with at most the optimum's accumulated exposure +
``exposure_tolerance``.

Lattice time: where lights move, the replay steps at the scenario's ``step_seconds`` (the
model's bins), which matches the ROS run only as far as the simulator's step times do.
"""

from __future__ import annotations

import dataclasses
import math

from stealth_core.lattice_model import LatticeModel
from stealth_core.path_scores import (
    DEFAULT_CRITERION,
    Criterion,
    PathScores,
    optimum_path,
    polyline_length,
    replay_actions,
    score_columns,
)
from stealth_core.planners import PathResult
from stealth_core.reward import EpisodeOutcome
from stealth_core.task import StealthTask

# EpisodeRecord's score fields and their values when unknown (no scorer, steps missing, a run
# written before they existed).
UNSCORED = {
    'lattice_outcome': '',
    'lattice_steps': -1,
    'lattice_path_length': math.nan,  # m
    'lattice_peak_visibility': math.nan,
    'lattice_accumulated_visibility': math.nan,
    'path_over_optimum': math.nan,  # lattice path length / the optimum's
    'exposure_over_optimum': math.nan,  # lattice accumulated visibility - the optimum's
    'true_path_over_optimum': math.nan,  # the true pose's path length / the optimum's
    'estimated_path_length': math.nan,  # m, the localisation estimate's, from the start
    'meets_criterion': False,
}


class EpisodeScorer:
    """Scores a run's episodes against the optimum of its scenario and goal; the lattice model
    and the optimum are built on first use (seconds on the largest scenarios)."""

    def __init__(self, scenario, goal: str | None, criterion: Criterion = DEFAULT_CRITERION):
        self.scenario, self.goal, self.criterion = scenario, goal, criterion
        self._model: LatticeModel | None = None
        self._optimum: PathResult | None = None
        self.error: str | None = None  # why the optimum could not be had (then no scores)

    @property
    def model(self) -> LatticeModel:
        if self._model is None:
            self._model = LatticeModel.build(StealthTask(self.scenario, self.goal))
        return self._model

    @property
    def optimum(self) -> PathResult:
        """Value iteration's path on the lattice, walked (``planners.optimal_path``'s)."""
        if self._optimum is None:
            self._optimum = optimum_path(self.model)
        return self._optimum

    def score(self, summary: dict, moves: list[tuple[int, float, float]]) -> dict:
        """The score fields (UNSCORED's keys) of an episode: ``summary`` its EpisodeSummary
        fields (episode_tracker.summary_fields), ``moves`` (action, estimated x, estimated y)
        of each step in order. The lattice figures stay unknown when the steps do not add up
        to the summary's (a step not received) or an action is not the scenario's; every
        score when the optimum cannot be had (``error`` says why: a score must not cost the
        run its episodes)."""
        fields = dict(UNSCORED)
        if self.error is not None:
            return fields
        try:
            optimum = PathScores.of_path(self.optimum)
        except Exception as error:  # noqa: BLE001 - e.g. a scenario the lattice cannot judge
            self.error = f'no value-iteration optimum to score episodes against: {error}'
            return fields
        length = optimum.path_length
        fields['true_path_over_optimum'] = summary['path_length'] / length if length else math.nan
        start = self.scenario.start[:2]
        points = [tuple(start), *((x, y) for _, x, y in moves)]
        fields['estimated_path_length'] = polyline_length(points)
        if len(moves) != summary['steps']:
            return fields
        try:
            walked = replay_actions(self.model, [action for action, _, _ in moves])
        except ValueError:
            return fields
        lattice = PathScores.of_path(walked)
        outcome = summary['outcome']
        if walked.outcome is EpisodeOutcome.DETECTED:  # seen on the lattice: not covert
            outcome = EpisodeOutcome.DETECTED.name
        judged = dataclasses.replace(
            lattice,
            outcome=EpisodeOutcome[outcome] if outcome in EpisodeOutcome.__members__ else None,
        )
        fields.update(
            lattice_outcome='' if walked.outcome is None else walked.outcome.name,
            lattice_steps=lattice.steps,
            lattice_path_length=lattice.path_length,
            lattice_peak_visibility=lattice.peak_exposure,
            lattice_accumulated_visibility=lattice.accumulated_exposure,
            **score_columns(judged, optimum, self.criterion),
        )
        return fields
