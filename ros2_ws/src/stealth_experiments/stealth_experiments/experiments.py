"""The experiment harness: scenarios x learners x seeds, trained in-process on the Gymnasium
environment, measured against value iteration's optimum and the planning baselines.

    python -m stealth_experiments.experiments --scenarios map1 lgfloor --learners qlearning dyna \
        --seeds 0 1 2 --out runs/eval          # or `make compare`; installed as its `experiments`

The runs go to a local Ray over ``--jobs`` CPUs (``sweep_engine``, the engine of `stealth
sweep`), or with ``--jobs 1`` one after another in this process. Each run (``harness``) trains
one learner (``stealth_agent``, driven through ``ProtocolAgent`` exactly as the ROS agent node
drives it) for a fixed budget of episodes, and every
``--eval-every`` episodes rolls out the greedy policy. Written to ``--out`` (``harness_report``,
through the report writer ``run_outputs`` that `stealth train` runs use too):

- ``results.md``: per scenario, one row per method (A*, Dark Path, value iteration, each
  learner over its seeds): outcome rates, returns, path length and accumulated visibility with
  their ratio and excess over the optimum's, whether the final greedy episode meets the success
  criterion (``--max-path-ratio``, ``--exposure-tolerance``: ``stealth_core.path_scores``),
  episodes until every greedy evaluation meets it, wall time;
- ``results.csv``: the same per run (one row per seed);
- ``learning_curves.png`` and ``curves_<scenario>.png``: greedy return against episodes, the
  mean over seeds with a min-max band, the training return faintly, the optimum, and where each
  learner meets the criterion for good (median over seeds);
- ``paths_<scenario>.png``: every method's path over the scenario's visibility picture;
  ``paths_<scenario>.gif`` where lights move: the optimum and each learner's greedy path walked
  step by step while the lights move;
- ``policies/<scenario>-<learner>-seed<k>.npz``: each final policy, a ``stealth_agent`` policy
  file the ROS agent node loads (``policy_file``, ``load_policy``/``evaluate``) unchanged.

What a return, a rate and "episodes to the criterion" are: ``harness``'s docstring.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
import sys

from stealth_agent.learners import (
    LEARNER_NAMES,
    OPTIMISTIC,
    LearnerConfig,
    canonical_learner_name,
)
from stealth_agent.schedules import Schedule
from stealth_bringup.run_arguments import add_criterion_options, criterion_of
from stealth_core.gym_env import lattice_model
from stealth_core.path_scores import DEFAULT_CRITERION, Criterion
from tqdm import tqdm

from stealth_experiments.harness import (
    DEFAULT_EVAL_EVERY,
    PLANNING_UPDATES,
    baselines,
    default_budget,
    grid_specs,
    run,
    scenario_argument,
    tuned_config,
)
from stealth_experiments.harness_report import write_results
from stealth_experiments.options import add_episodes_option, add_output_options

DEFAULT_SCENARIOS = (
    'simple-maze',
    'map1',
    'lgfloor',
    'floorplan',
    'simple-maze-moving',
    'map1-moving',
    'lgfloor-moving',
    'floorplan-moving',
    'simple-maze-exposure',
    'map1-exposure',
    'map1-bounce',
    'lgfloor-bounce',
)
DEFAULT_SEEDS = (0, 1, 2)
DEFAULT_OUT = Path('runs/eval')


def evaluate(
    scenarios: Sequence[str] = DEFAULT_SCENARIOS,
    learners: Sequence[str] = LEARNER_NAMES,
    seeds: Sequence[int] = DEFAULT_SEEDS,
    *,
    episodes: int | None = None,
    eval_every: int = DEFAULT_EVAL_EVERY,
    slip: float = 0.0,
    goal: str | None = None,
    out: Path = DEFAULT_OUT,
    jobs: int = 1,
    plots: bool = True,
    progress: bool = True,
    criterion: Criterion = DEFAULT_CRITERION,
) -> list[dict]:
    """Run the grid and write every report into ``out``; returns the CSV rows. Scenario paths
    are relative to the current directory (harness.scenario_argument), made absolute here."""
    scenarios = [scenario_argument(scenario, Path.cwd()) for scenario in scenarios]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    models = {scenario: lattice_model(scenario, goal) for scenario in scenarios}
    planned = {scenario: baselines(model, slip) for scenario, model in models.items()}
    results = run_grid(
        scenarios,
        learners,
        seeds,
        episodes=episodes,
        eval_every=eval_every,
        slip=slip,
        goal=goal,
        jobs=jobs,
        policy_dir=str(out / 'policies'),
        progress=progress,
        criterion=criterion,
    )
    budgets = ', '.join(
        f'{name} {episodes or default_budget(name)}'
        + (
            ''
            if episodes
            else f' ({default_budget(name, "simple-maze-moving")} where lights move)'
        )
        for name in learners
    )
    settings = (
        f'Seeds {", ".join(map(str, seeds))}; training episodes per run: {budgets}; greedy '
        f'evaluation every {eval_every} episodes; slip {slip:g}. Learner settings (all '
        f'learners but the planning updates): {_describe(tuned_config("qlearning", slip > 0))}.'
    )
    if any(canonical_learner_name(name) in OPTIMISTIC for name in learners):
        settings += (
            ' Prioritized sweeping explores by optimism instead, epsilon 0: a state-action its '
            'model has not seen is worth what the floor plan says with the lights dark; its '
            'greedy policy is the best way to the goal its model knows.'
        )
    settings += f' Success criterion: {criterion.describe()}.'
    return write_results(out, models, planned, results, settings, plots, criterion)


def run_grid(scenarios, learners, seeds, *, jobs: int = 1, progress: bool = True, **options):
    """Every run of the grid (``harness.grid_specs``: its ``options``, the criterion among
    them, in each RunSpec): on ``jobs`` CPUs of a local Ray (``sweep_engine.run_specs``, the
    engine of `stealth sweep`) or, with ``jobs`` 1, one after another in this process."""
    specs = grid_specs(scenarios, learners, seeds, **options)
    if jobs > 1:
        from stealth_experiments.sweep_engine import run_specs

        return run_specs(specs, jobs=jobs, progress=progress)
    return [run(spec) for spec in tqdm(specs, desc='runs', unit='run', disable=not progress)]


def _describe(config: LearnerConfig) -> str:
    def schedule(s: Schedule) -> str:
        if s.kind == 'constant':
            return f'{s.start:g}'
        return f'{s.kind} {s.start:g} to {s.final:g} over {s.decay:g} episodes'

    return (
        f'alpha {schedule(config.alpha)}, epsilon {schedule(config.epsilon)}, gamma '
        f'{config.gamma:g}, initial Q {config.initial_value:g}; planning updates per step: '
        f'dyna {PLANNING_UPDATES["dyna"]}, prioritized up to {PLANNING_UPDATES["prioritized"]} '
        f'(while a queued change exceeds theta {config.theta:g}), its untried pairs worth the '
        'floor plan with the lights dark'
    )


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='experiments',
        description='Train learners in-process on stealth-nav scenarios and compare them with '
        'A*, Dark Path and value iteration: results.md, results.csv, plots, policies.',
    )
    parser.add_argument(
        '--scenarios',
        nargs='+',
        default=list(DEFAULT_SCENARIOS),
        help='scenario names (on the scenario search path) or YAML paths (a relative path is '
        'relative to the current directory) (default: %(default)s)',
    )
    parser.add_argument(
        '--learners',
        nargs='+',
        default=list(LEARNER_NAMES),
        choices=LEARNER_NAMES,
        help='default: %(default)s',
    )
    parser.add_argument(
        '--seeds', nargs='+', type=int, default=list(DEFAULT_SEEDS), help='default: %(default)s'
    )
    add_episodes_option(parser, 'training episodes per run (default per learner: ')
    parser.add_argument(
        '--eval-every',
        type=int,
        default=DEFAULT_EVAL_EVERY,
        help='episodes between greedy evaluations (default: %(default)s)',
    )
    parser.add_argument(
        '--slip',
        type=float,
        default=0.0,
        help='probability of moving sideways (default: %(default)s)',
    )
    parser.add_argument('--goal', help="goal name (default: each scenario's default goal)")
    add_output_options(parser, 'runs', DEFAULT_OUT, 'the pictures')
    add_criterion_options(parser)
    args = parser.parse_args(argv)
    if (args.episodes is not None and args.episodes < 1) or args.eval_every < 1:
        parser.error('--episodes and --eval-every must be >= 1')
    if not 0.0 <= args.slip <= 1.0:
        parser.error('--slip must be a probability in [0, 1]')
    criterion = criterion_of(args)
    try:
        evaluate(
            args.scenarios,
            args.learners,
            args.seeds,
            episodes=args.episodes,
            eval_every=args.eval_every,
            slip=args.slip,
            goal=args.goal,
            out=args.out,
            jobs=args.jobs,
            plots=not args.no_plots,
            criterion=criterion,
        )
    except (OSError, RuntimeError, ValueError) as error:
        print(f'experiments: {error}', file=sys.stderr)
        return 1
    except KeyboardInterrupt as stop:  # sweep_stop.Interrupted: SIGINT or SIGTERM
        print(f'experiments: interrupted; nothing written to {args.out}', file=sys.stderr)
        return getattr(stop, 'exit_code', 130)
    print(args.out / 'results.md')
    return 0


if __name__ == '__main__':
    sys.exit(main())
