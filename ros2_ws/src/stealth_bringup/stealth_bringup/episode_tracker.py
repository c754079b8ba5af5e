"""Following a training run episode by episode: pairing the environment's EpisodeSummary with the
agent's AgentEpisodeInfo, the figures of the progress bar and the end criteria. No rclpy.

Both messages carry the episode number, counted from 0 in a run by the environment and by the
agent alike, so they are paired by it. An episode is complete when both have arrived, or when
the environment reports it ABORTED (the agent may never have seen it end).

Each episode is scored against value iteration's optimum when the tracker has a scorer
(``episode_scores``: the lattice nodes the robot was sent to, from the StepInfo reports given
to ``add_step``, and the continuous pose's figures beside them).

End criteria: the episode budget (every episode counts, greedy evaluations included), or K
greedy evaluation episodes in a row meeting the success criterion (``path_scores``: reached the
goal undetected on a path close enough to the optimum's in length and exposure; without a
scorer, reaching the goal); a greedy episode that does not resets the streak, the training
episodes in between do not count.
"""

from __future__ import annotations

from collections.abc import Iterable
import dataclasses
import itertools
import math

from stealth_core.reward import EpisodeOutcome

from stealth_bringup.episode_scores import UNSCORED, EpisodeScorer

# The names of the core's outcome enum, whose values are EpisodeSummary's constants.
OUTCOMES = tuple(outcome.name for outcome in EpisodeOutcome)
PROGRESS_WINDOW = 20  # episodes over which the progress bar's rates and means are taken


def outcome_name(value: int) -> str:
    try:
        return EpisodeOutcome(value).name
    except ValueError:
        return f'OUTCOME_{value}'


@dataclasses.dataclass(frozen=True)
class EpisodeRecord:
    """One finished episode: the environment's summary and the agent's report, joined."""

    episode: int
    outcome: str  # an EpisodeOutcome's name: SUCCESS, DETECTED, TIMEOUT or ABORTED
    steps: int
    total_reward: float
    peak_visibility: float
    accumulated_visibility: float
    path_length: float  # m
    final_distance_to_goal: float  # m
    greedy: bool  # a greedy evaluation episode (no exploration, no learning)
    epsilon: float  # nan when the agent did not report the episode
    alpha: float
    learner_episodes: int  # training episodes the learner had finished after it (-1: unknown)
    learner_updates: int
    table_states: int
    wall_time: float  # s from the start of the run to the episode's completion
    # Scores against the optimum (episode_scores.UNSCORED: unknown values): on the lattice
    # nodes the robot was sent to, then the continuous pose's beside them.
    lattice_outcome: str = UNSCORED['lattice_outcome']  # the lattice replay's own ending
    lattice_steps: int = UNSCORED['lattice_steps']
    lattice_path_length: float = UNSCORED['lattice_path_length']  # m
    lattice_peak_visibility: float = UNSCORED['lattice_peak_visibility']
    lattice_accumulated_visibility: float = UNSCORED['lattice_accumulated_visibility']
    path_over_optimum: float = UNSCORED['path_over_optimum']  # lattice path / the optimum's
    exposure_over_optimum: float = UNSCORED['exposure_over_optimum']  # lattice - the optimum's
    true_path_over_optimum: float = UNSCORED['true_path_over_optimum']  # true pose's / optimum's
    estimated_path_length: float = UNSCORED['estimated_path_length']  # m, the estimate's
    meets_criterion: bool = UNSCORED['meets_criterion']

    @property
    def success(self) -> bool:
        return self.outcome == EpisodeOutcome.SUCCESS.name

    def as_row(self) -> dict:
        return dataclasses.asdict(self)

    def brief(self) -> dict:
        """What summary.json tells of an episode."""
        return {
            'episode': self.episode,
            'outcome': self.outcome,
            'return': self.total_reward,
            'steps': self.steps,
            'path_length': self.path_length,
            'peak_visibility': self.peak_visibility,
            'accumulated_visibility': self.accumulated_visibility,
            'final_distance_to_goal': self.final_distance_to_goal,
            'lattice': {
                'outcome': self.lattice_outcome or None,
                'steps': self.lattice_steps if self.lattice_steps >= 0 else None,
                'path_length': self.lattice_path_length,
                'peak_visibility': self.lattice_peak_visibility,
                'accumulated_visibility': self.lattice_accumulated_visibility,
                'path_over_optimum': self.path_over_optimum,
                'exposure_over_optimum': self.exposure_over_optimum,
            },
            'true_path_over_optimum': self.true_path_over_optimum,
            'estimated_path_length': self.estimated_path_length,
            'meets_criterion': self.meets_criterion,
        }


CSV_FIELDS = tuple(f.name for f in dataclasses.fields(EpisodeRecord))
# Columns an episodes.csv written before the scores existed lacks (read as unknown).
SCORE_FIELDS = tuple(UNSCORED)


def summary_fields(msg) -> dict:
    """The fields of a stealth_interfaces/EpisodeSummary used here."""
    return {
        'episode': int(msg.episode),
        'outcome': outcome_name(int(msg.outcome)),
        'steps': int(msg.steps),
        'total_reward': float(msg.total_reward),
        'peak_visibility': float(msg.peak_visibility),
        'accumulated_visibility': float(msg.accumulated_visibility),
        'path_length': float(msg.path_length),
        'final_distance_to_goal': float(msg.final_distance_to_goal),
    }


def unfinished_fields(episode: int, steps: list, start: tuple[float, float]) -> dict:
    """EpisodeSummary fields of an episode whose environment died before summarising it
    (ABORTED), rebuilt from its StepInfo reports: `steps` holds (reward, visibility,
    distance_to_goal, x, y) of each, the true pose last; `start` is the scenario's start."""
    points = [tuple(start), *((x, y) for *_, x, y in steps)]
    return {
        'episode': int(episode),
        'outcome': EpisodeOutcome.ABORTED.name,
        'steps': len(steps),
        'total_reward': float(sum(step[0] for step in steps)),
        'peak_visibility': float(max((step[1] for step in steps), default=0.0)),
        'accumulated_visibility': float(sum(step[1] for step in steps)),
        'path_length': float(sum(math.dist(a, b) for a, b in itertools.pairwise(points))),
        'final_distance_to_goal': float(steps[-1][2]) if steps else math.nan,
    }


def agent_fields(msg) -> dict:
    """The fields of a stealth_interfaces/AgentEpisodeInfo used here."""
    return {
        'greedy': bool(msg.greedy),
        'epsilon': float(msg.epsilon),
        'alpha': float(msg.alpha),
        'learner_episodes': int(msg.learner_episodes),
        'learner_updates': int(msg.learner_updates),
        'table_states': int(msg.table_states),
    }


UNREPORTED = {
    'greedy': False,
    'epsilon': math.nan,
    'alpha': math.nan,
    'learner_episodes': -1,
    'learner_updates': -1,
    'table_states': -1,
}


class Tracker:
    """Joins the two reports of each episode and keeps the run's figures."""

    def __init__(
        self,
        budget: int | None = None,
        streak_goal: int | None = None,
        scorer: EpisodeScorer | None = None,
    ):
        self.budget = budget
        self.streak_goal = streak_goal
        self.scorer = scorer
        self._moves: dict[int, list[tuple[int, float, float]]] = {}  # by episode
        self.records: list[EpisodeRecord] = []
        self._summaries: dict[int, dict] = {}
        self._agent: dict[int, dict] = {}
        self._done: set[int] = set()
        self.streak = 0  # greedy episodes in a row that met the criterion so far
        self.streak_start: int | None = None  # episode of the first of the streak
        self.greedy_count = 0

    # --- input ------------------------------------------------------------------------------

    def add_summary(self, fields: dict, wall_time: float) -> list[EpisodeRecord]:
        episode = fields['episode']
        if episode in self._done:
            return []
        self._summaries[episode] = fields
        if fields['outcome'] == EpisodeOutcome.ABORTED.name and episode not in self._agent:
            return self._complete(episode, UNREPORTED, wall_time)
        return self._try(episode, wall_time)

    def add_step(
        self, episode: int, action: int, x: float, y: float, wall_time: float
    ) -> list[EpisodeRecord]:
        """One StepInfo report: the action and the estimated pose (x, y) after it. With a
        scorer an episode waits for its last step (the reports of two topics may arrive in
        either order): this one may complete it, or, of a later episode, those before."""
        if episode in self._done:
            return []
        self._moves.setdefault(episode, []).append((int(action), float(x), float(y)))
        completed = []
        for waiting in sorted(e for e in self._summaries if e <= episode):
            completed += self._try(waiting, wall_time)
        return completed

    def add_agent_info(self, episode: int, fields: dict, wall_time: float) -> list[EpisodeRecord]:
        if episode in self._done:
            return []
        self._agent[episode] = fields
        return self._try(episode, wall_time)

    def _try(self, episode: int, wall_time: float) -> list[EpisodeRecord]:
        if episode in self._summaries and episode in self._agent and self._stepped(episode):
            return self._complete(episode, self._agent.pop(episode), wall_time)
        return []

    def _stepped(self, episode: int) -> bool:
        """Every step of the episode is in (or none will come: no scorer, or a later episode
        has begun), so that its scores can be taken."""
        if self.scorer is None:
            return True
        if len(self._moves.get(episode, ())) >= self._summaries[episode]['steps']:
            return True
        return any(later > episode for later in self._moves)

    def load(self, records: Iterable[EpisodeRecord]) -> None:
        """Take in the episodes of an earlier part of the run (a continued run's episodes.csv),
        streak and all, as if they had been followed here."""
        for record in sorted(records, key=lambda r: r.episode):
            if record.episode not in self._done:
                self._count(record)

    def _complete(self, episode: int, agent: dict, wall_time: float) -> list[EpisodeRecord]:
        summary = self._summaries.pop(episode)
        self._agent.pop(episode, None)
        moves = self._moves.pop(episode, [])
        scores = {} if self.scorer is None else self.scorer.score(summary, moves)
        record = EpisodeRecord(**summary, **agent, wall_time=wall_time, **scores)
        self._count(record)
        return [record]

    def _count(self, record: EpisodeRecord) -> None:
        self._done.add(record.episode)
        self.records.append(record)
        if record.greedy:
            self.greedy_count += 1
            if self.qualifies(record):
                if self.streak == 0:
                    self.streak_start = record.episode
                self.streak += 1
            else:
                self.streak, self.streak_start = 0, None

    def qualifies(self, record: EpisodeRecord) -> bool:
        """Whether a greedy episode counts towards the streak: it met the criterion (without
        a scorer: it reached the goal)."""
        return record.meets_criterion if self.scorer is not None else record.success

    # --- figures ----------------------------------------------------------------------------

    @property
    def episodes(self) -> int:
        return len(self.records)

    def recent(self, window: int = PROGRESS_WINDOW) -> list[EpisodeRecord]:
        return self.records[-window:]

    def success_rate(self, window: int = PROGRESS_WINDOW) -> float:
        recent = self.recent(window)
        return sum(r.success for r in recent) / len(recent) if recent else 0.0

    def mean_return(self, window: int = PROGRESS_WINDOW) -> float:
        recent = self.recent(window)
        return sum(r.total_reward for r in recent) / len(recent) if recent else 0.0

    @property
    def epsilon(self) -> float:
        """The exploration rate of the latest training episode (nan before any)."""
        for record in reversed(self.records):
            if not record.greedy and not math.isnan(record.epsilon):
                return record.epsilon
        return math.nan

    def last_greedy(self) -> EpisodeRecord | None:
        for record in reversed(self.records):
            if record.greedy:
                return record
        return None

    def outcome_counts(self, records: Iterable[EpisodeRecord] | None = None) -> dict[str, int]:
        counts = dict.fromkeys(OUTCOMES, 0)
        for record in self.records if records is None else records:
            counts[record.outcome] = counts.get(record.outcome, 0) + 1
        return counts

    # --- end criteria -----------------------------------------------------------------------

    def stop_reason(self) -> str | None:
        """'streak' or 'budget' once an end criterion holds, else None."""
        if self.streak_goal and self.streak >= self.streak_goal:
            return 'streak'
        if self.budget is not None and self.episodes >= self.budget:
            return 'budget'
        return None

    def end_message(self, reason: str, evaluating: bool = False) -> str:
        """Why the run ended, for a stop_reason() answer; an evaluation runs its whole budget."""
        if reason == 'streak':
            episodes = [r.episode for r in self.records if r.greedy][-self.streak_goal :]
            return (
                f'the greedy policy {self._criterion_words()} in {self.streak_goal} evaluations '
                f'in a row (episodes {", ".join(map(str, episodes))})'
            )
        if evaluating:
            reached = self.outcome_counts()[EpisodeOutcome.SUCCESS.name]
            message = f'{self.budget} greedy episodes: {reached} reached the goal'
            if self.scorer is not None:
                met = sum(r.meets_criterion for r in self.records if r.greedy)
                message += f', {met} met the success criterion ({self.scorer.criterion.short()})'
            return message
        message = f'episode budget of {self.budget} spent'
        if self.streak_goal:
            message += (
                f' before {self.streak_goal} greedy evaluations in a row '
                f'{self._criterion_words()} (streak at the end: {self.streak})'
            )
        return message

    def _criterion_words(self) -> str:
        if self.scorer is None:
            return 'reached the goal undetected'
        return f'met the success criterion ({self.scorer.criterion.short()})'

    def postfix(self) -> str:
        """The progress bar's figures."""
        epsilon = self.epsilon
        parts = [
            f'success {self.success_rate():.0%}',
            f'return {self.mean_return():.1f}',
            'eps -' if math.isnan(epsilon) else f'eps {epsilon:.3f}',
        ]
        if self.streak_goal:
            parts.append(f'greedy streak {self.streak}/{self.streak_goal}')
        return ', '.join(parts)
