"""`stealth train --resume RUN`: what the earlier part of a run left (its episodes, summary and
the number of its next episode), checked before anything starts, and the settings the
continuation runs with. Every problem is a RunConfigError with one line to print. No rclpy.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from stealth_core.path_scores import DEFAULT_CRITERION, Criterion, CriterionError

from stealth_bringup.run_arguments import (
    COMMAND_OF_MODE,
    DEFAULT_EPISODES,
    DEFAULT_EVAL_EVERY,
    DEFAULT_STREAK,
)
from stealth_bringup.run_config import (
    RunConfigError,
    check_goal,
    load_run_scenario,
    scenario_hashes,
)


@dataclasses.dataclass
class Continuation:
    """What the earlier part of a continued run left (stealth train --resume)."""

    records: list  # its episodes (EpisodeRecord), from its episodes.csv
    summary: dict  # its summary.json
    first_episode: int  # the number of the first episode of this part


def train_settings(
    args, continued: Continuation | None, default_episodes: int = DEFAULT_EPISODES
) -> tuple[int, int, int]:
    """(episode budget, eval_every, success streak) of a training run: the options given, else
    a continued run's own, else the defaults (the budget: default_episodes, the scenario's,
    episode_budget); RunConfigError when a continued run would stop at once."""
    if continued is None:
        return (
            default_episodes if args.episodes is None else args.episodes,
            DEFAULT_EVAL_EVERY if args.eval_every is None else args.eval_every,
            DEFAULT_STREAK if args.success_streak is None else args.success_streak,
        )
    saved = continued.summary
    episodes = _given(args.episodes, saved.get('episode_budget'), default_episodes)
    eval_every = _given(args.eval_every, saved.get('eval_every'), DEFAULT_EVAL_EVERY)
    streak = _given(args.success_streak, saved.get('success_streak'), DEFAULT_STREAK)
    from stealth_bringup.episode_scores import EpisodeScorer
    from stealth_bringup.episode_tracker import Tracker

    scorer = EpisodeScorer(None, None, criterion_setting(args, continued))  # for the streak
    tracker = Tracker(episodes, (streak if eval_every else 0) or None, scorer)
    tracker.load(continued.records)
    reason = tracker.stop_reason()
    where = f'--resume {args.resume}'
    if reason == 'budget':
        raise RunConfigError(
            f'{where}: the run has {tracker.episodes} episodes, its budget of {episodes} is '
            f'spent; give --episodes N, the new total (more than {tracker.episodes})'
        )
    if reason == 'streak':
        raise RunConfigError(
            f'{where}: the run ended on {tracker.streak} greedy evaluations in a row that met '
            f'the success criterion (its '
            f'--success-streak {streak}); give a larger --success-streak, or 0 to spend the '
            'budget'
        )
    return episodes, eval_every, streak


def criterion_setting(args, continued: Continuation | None) -> Criterion:
    """The success criterion of a run: each option given, else a continued run's own
    (summary.json's "criterion"), else the default; RunConfigError for a saved value out of
    range."""
    saved = {} if continued is None else continued.summary.get('criterion') or {}
    values = {}
    for name in ('max_path_ratio', 'exposure_tolerance'):
        given = getattr(args, name, None)
        kept = saved.get(name) if isinstance(saved, dict) else None
        values[name] = given if given is not None else kept
    values = {k: v for k, v in values.items() if v is not None}
    try:
        return Criterion(**{**dataclasses.asdict(DEFAULT_CRITERION), **values})
    except CriterionError as error:
        raise RunConfigError(f'--resume {args.resume}: summary.json criterion: {error}') from None


def _given(value, saved, default):
    """An option's value: given on the command line, else the run's saved one, else default."""
    if value is not None:
        return value
    return saved if isinstance(saved, int) and not isinstance(saved, bool) else default


def continued_run(args):
    """(Continuation, scenario, goal, params dir) of `stealth train --resume RUN`;
    RunConfigError saying why RUN cannot be continued."""
    from stealth_bringup.run_outputs import read_episodes_csv, read_run_summary

    run = Path(args.resume)
    where = f'--resume {run}'
    if not run.is_dir():
        raise RunConfigError(f'{where}: no such directory')
    for option in ('name', 'scenario', 'goal'):
        if getattr(args, option) is not None:
            raise RunConfigError(f'{where}: a continued run keeps its {option}; drop --{option}')
    if not (run / 'summary.json').is_file():
        raise RunConfigError(
            f'{where}: not a run directory (it has no summary.json, which stealth train writes '
            'as a run starts)'
        )
    summary = read_run_summary(run)
    if not summary:
        raise RunConfigError(f'{where}: its summary.json is not a JSON object stealth train wrote')
    if summary.get('mode') != 'train':
        raise RunConfigError(
            f'{where}: a run of stealth {COMMAND_OF_MODE.get(summary.get("mode"), "?")}, not a '
            'training run; only '
            'stealth train runs can be continued'
        )
    if not (run / 'params').is_dir():
        raise RunConfigError(f'{where}: it has no params/ directory (not a complete run)')
    saved = summary.get('scenario') or {}
    path = saved.get('path')
    if not isinstance(path, str) or not Path(path).is_file():
        raise RunConfigError(f'{where}: its scenario file {path} is not there any more')
    scenario = load_run_scenario(path)
    for key, now in scenario_hashes(scenario).items():
        then = saved.get(key)
        if then is not None and then != now:
            what = 'scenario file' if key == 'sha256' else 'map'
            changed = scenario.path if key == 'sha256' else scenario.map_path
            raise RunConfigError(
                f'{where}: its {what} {changed} changed since the run started (SHA-256 '
                f'{then[:12]}... then, {now[:12]}... now); the policy was learned on the old '
                'one: restore it, or start a new run'
            )
    goal = check_goal(scenario, summary.get('goal'))
    csv_path = run / 'episodes.csv'
    records = read_episodes_csv(csv_path) if csv_path.is_file() else []
    first = max((r.episode for r in records), default=-1) + 1
    params_dir = args.params_dir or str(run / 'params')
    if not (run / 'params' / 'recorder.yaml').is_file():
        args.no_record = True  # the run was not recorded (--no-record): nor is its continuation
    return Continuation(records, summary, first), scenario, goal, params_dir
