"""The experiment harness: scenarios x learners x seeds, trained in-process on the Gymnasium
environment, measured against value iteration's optimum and the planning baselines.

    experiments --scenarios map1 lgfloor --learners qlearning dyna --seeds 0 1 2 --out runs/eval

Each run trains one learner (``stealth_agent``, driven through ``ProtocolAgent`` exactly as the
ROS agent node drives it) for a fixed budget of episodes, and every ``--eval-every`` episodes
rolls out the greedy policy. Written to ``--out``:

- ``results.md``: per scenario, one row per method (A*, Dark Path, value iteration, each
  learner over its seeds): outcome rates, returns, path length, accumulated visibility,
  episodes until the greedy policy stays within 5 % of the optimal return, wall time;
- ``results.csv``: the same per run (one row per seed);
- ``learning_curves.png`` and ``curves_<scenario>.png``: greedy return against episodes, the
  mean over seeds with a min-max band, the training return faintly, the optimum and the 5 % line;
- ``paths_<scenario>.png``: every method's path over the scenario's visibility picture;
- ``policies/<scenario>-<learner>-seed<k>.npz``: each final policy, a ``stealth_agent`` policy
  file the ROS agent node loads (``policy_file``, ``load_policy``/``evaluate``) unchanged.

Definitions. A return sums the rewards after the first state, undiscounted; the optimum is
``planners.value_iteration``'s (undiscounted, exact, with the step limit). Rates count the
training episodes' outcomes. "Episodes to 5 %" is the first evaluation point from which every
later greedy return of the run is at least ``optimum - 0.05 * |optimum|`` (it stays there, not
just touches it); a run that never settles is reported as not within 5 % in its budget.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
import csv
import dataclasses
import math
import os
from pathlib import Path
import sys
import time

from matplotlib.figure import Figure
import numpy as np
from stealth_agent.learners import (
    LEARNER_NAMES,
    LearnerConfig,
    canonical_learner_name,
    make_learner,
)
from stealth_agent.policy_store import save_policy
from stealth_agent.protocol import ProtocolAgent, parse_description
from stealth_agent.schedules import Schedule
from stealth_agent.state_index import StateIndex
from tqdm import tqdm

from stealth_env.gym_env import StealthNavEnv, lattice_model
from stealth_env.planners import (
    LatticeModel,
    astar,
    dark_path,
    follow,
    value_iteration,
    walk,
)
from stealth_env.render import render_scenario
from stealth_env.reward import Outcome

DEFAULT_SCENARIOS = ('simple-maze', 'map1', 'lgfloor', 'floorplan')
DEFAULT_SEEDS = (0, 1, 2)
# Training episodes per run, per learner: each well past where every seed settled within 5 %
# (README); Dyna-Q's 20 planning updates make its episodes ~5x dearer and it needs ~1/6 as many.
DEFAULT_EPISODES = {'qlearning': 1500, 'sarsa': 1500, 'dyna': 500}
DEFAULT_EVAL_EVERY = 10
DEFAULT_OUT = Path('runs/eval')
WITHIN = 0.05  # of the optimal return
BASELINES = ('A*', 'Dark Path', 'value iteration')
OUTCOMES = ('SUCCESS', 'DETECTED', 'TIMEOUT')


def tuned_config(learner: str, stochastic: bool = False) -> LearnerConfig:
    """The settings the harness trains with: the same for all three learners, so that only the
    algorithm differs, chosen by measurement (the README's evaluation section).

    alpha 1 on the deterministic lattice (one sample of a transition is its expectation, so the
    first good update is final; 0.5 and 0.3 took 1.5-2x the episodes); 0.3 with slip, to average
    the noise. Q starts at 0, which with step costs below 0 is already optimistic: unvisited
    actions look best, and exploration is systematic (an optimistic start at the goal reward
    made every run wander to the step limit for hundreds of episodes). epsilon decays from 0.1
    to 0 with a time constant of 100 episodes: SARSA learns the value of its own epsilon-greedy
    policy, and with a detection penalty of 1000 a 10 % chance of a random step next to a lit
    cell makes hovering in the dark look better than the door to the goal (with epsilon fixed at
    0.1 its greedy policy timed out instead of reaching the goal). Dyna-Q plans 20 updates per
    step.
    """
    canonical_learner_name(learner)
    return LearnerConfig(
        alpha=Schedule.fixed(0.3 if stochastic else 1.0),
        epsilon=Schedule('exponential', 0.1, 0.0, 100.0),
        n_planning=20,
    )


# --- one run ------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class RunSpec:
    scenario: str
    learner: str
    seed: int
    episodes: int = 1000
    eval_every: int = DEFAULT_EVAL_EVERY
    slip: float = 0.0
    goal: str | None = None
    policy_dir: str | None = None  # where to save the final policy, if anywhere


@dataclasses.dataclass
class RunResult:
    spec: RunSpec
    optimum: float
    train_returns: np.ndarray  # (episodes,)
    train_outcomes: np.ndarray  # (episodes,) Outcome values
    eval_at: np.ndarray  # episodes trained before each greedy evaluation
    eval_returns: np.ndarray  # mean greedy return at each
    episodes_to_within: int | None
    final: dict  # the last greedy evaluation: EpisodeSummary's figures and the path
    seconds: float
    env_steps: int


def default_budget(learner: str) -> int:
    return DEFAULT_EPISODES[canonical_learner_name(learner)]


def play_episode(env: StealthNavEnv, agent: ProtocolAgent, seed: int | None = None):
    """One episode of the rl_msgs protocol on the Gym env: (EpisodeResult, last info)."""
    observation, info = env.reset(seed=seed)
    action = agent.first_action(observation)
    while True:
        observation, reward, terminated, truncated, info = env.step(action)
        if terminated:
            return agent.last_action(reward), info
        if truncated:
            return agent.truncate(reward, observation), info
        action = agent.next_action(reward, observation)


def settled_within(eval_at, eval_returns, optimum: float, within: float = WITHIN) -> int | None:
    """The first evaluation point from which every greedy return is within ``within`` of the
    optimum, or None."""
    good = np.asarray(eval_returns) >= optimum - within * abs(optimum)
    if good.size == 0 or not good[-1]:
        return None
    bad = np.flatnonzero(~good)
    return int(eval_at[0] if bad.size == 0 else eval_at[bad[-1] + 1])


def run(spec: RunSpec) -> RunResult:
    """Train one learner on one scenario with one seed, evaluating greedily as it goes."""
    started = time.perf_counter()
    env = StealthNavEnv(spec.scenario, spec.goal, spec.slip)
    evaluator = StealthNavEnv(spec.scenario, spec.goal, spec.slip)
    optimum = value_iteration(env.model, slip=spec.slip).optimal_return
    learner = make_learner(
        spec.learner, env.action_space.n, tuned_config(spec.learner, spec.slip > 0)
    )
    index = StateIndex()
    rng = np.random.default_rng(spec.seed)
    agent = ProtocolAgent(learner, index, rng)
    greedy = ProtocolAgent(learner, index, np.random.default_rng([spec.seed, 1]), learning=False)
    rollouts = 1 if spec.slip == 0 else 10
    returns, outcomes, eval_at, eval_returns = [], [], [], []
    steps = 0
    final: dict = {}
    for episode in range(spec.episodes):
        result, info = play_episode(env, agent, seed=spec.seed if episode == 0 else None)
        returns.append(result.reward)
        outcomes.append(Outcome[info['outcome']])
        steps += result.actions
        if (episode + 1) % spec.eval_every == 0 or episode + 1 == spec.episodes:
            tries = [_greedy_rollout(evaluator, greedy, spec.seed + k) for k in range(rollouts)]
            eval_at.append(episode + 1)
            eval_returns.append(float(np.mean([t['total_reward'] for t in tries])))
            final = tries[0]
    if spec.policy_dir:
        save_policy(
            policy_path(spec),
            learner,
            index,
            scenario=parse_description(**env.task.description(spec.slip > 0)).identity(),
            rng=rng,
            extra={'harness': dataclasses.asdict(spec)},
        )
    return RunResult(
        spec,
        optimum,
        np.array(returns),
        np.array(outcomes, dtype=np.int8),
        np.array(eval_at),
        np.array(eval_returns),
        settled_within(eval_at, eval_returns, optimum),
        final,
        time.perf_counter() - started,
        steps,
    )


def _greedy_rollout(env: StealthNavEnv, greedy: ProtocolAgent, seed: int) -> dict:
    _, info = play_episode(env, greedy, seed=seed)
    summary = env.stats.summary(Outcome[info['outcome']])
    return {**summary._asdict(), 'points': env.trajectory}


def policy_path(spec: RunSpec) -> Path:
    goal = f'-{spec.goal}' if spec.goal else ''
    name = f'{scenario_label(spec.scenario)}{goal}-{spec.learner}-seed{spec.seed}.npz'
    return Path(spec.policy_dir) / name


def scenario_label(scenario: str) -> str:
    """A scenario's name for tables and file names: 'map1' for 'map1' or 'x/map1.yaml'."""
    return Path(scenario).stem


# --- baselines ----------------------------------------------------------------------------------


@dataclasses.dataclass
class Baseline:
    name: str
    summary: dict  # as RunResult.final
    seconds: float


def baselines(model: LatticeModel, slip: float = 0.0) -> tuple[float, list[Baseline]]:
    """(optimal return, [A*, Dark Path, value iteration]) on one scenario's model.

    Each path is judged as walked without slip; value iteration's return is its optimal
    expected return (equal to its path's return without slip).
    """
    timed = {}
    for name, plan in (
        ('A*', lambda: astar(model)),
        ('Dark Path', lambda: dark_path(model)),
        ('value iteration', lambda: value_iteration(model, slip=slip)),
    ):
        started = time.perf_counter()
        timed[name] = (plan(), time.perf_counter() - started)
    optimum = timed['value iteration'][0]
    paths = {
        'A*': timed['A*'][0],
        'Dark Path': timed['Dark Path'][0],
        'value iteration': follow(model, lambda i: int(optimum.policy[i])),
    }
    found = []
    for name in BASELINES:
        path, seconds = paths[name], timed[name][1]
        if path is None:
            found.append(Baseline(name, {'outcome': None}, seconds))
            continue
        walked = walk(model, path)
        summary = {
            'outcome': walked.outcome,
            'steps': walked.steps,
            'total_reward': walked.total_reward,
            'peak_visibility': walked.peak_visibility,
            'accumulated_visibility': walked.accumulated_visibility,
            'path_length': walked.path_length,
            'points': walked.points,
        }
        if name == 'value iteration':
            summary['total_reward'] = optimum.optimal_return
        found.append(Baseline(name, summary, seconds))
    return optimum.optimal_return, found


# --- the grid -----------------------------------------------------------------------------------


def run_grid(
    scenarios: Sequence[str],
    learners: Sequence[str],
    seeds: Sequence[int],
    *,
    episodes: int | None = None,
    eval_every: int = DEFAULT_EVAL_EVERY,
    slip: float = 0.0,
    goal: str | None = None,
    jobs: int = 1,
    policy_dir: str | None = None,
    progress: bool = True,
) -> list[RunResult]:
    """Every scenario x learner x seed, in ``jobs`` processes; results in grid order.
    episodes: per run, None for each learner's DEFAULT_EPISODES."""
    specs = [
        RunSpec(
            scenario,
            learner,
            seed,
            episodes or default_budget(learner),
            eval_every,
            slip,
            goal,
            policy_dir,
        )
        for scenario in scenarios
        for learner in learners
        for seed in seeds
    ]
    bar = tqdm(total=len(specs), desc='runs', unit='run', disable=not progress)
    results: list[RunResult | None] = [None] * len(specs)
    if jobs <= 1:
        for i, spec in enumerate(specs):
            results[i] = run(spec)
            bar.update()
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(run, spec): i for i, spec in enumerate(specs)}
            for future in as_completed(futures):
                results[futures[future]] = future.result()
                bar.update()
    bar.close()
    return results


# --- reports ------------------------------------------------------------------------------------

CSV_FIELDS = (
    'scenario',
    'goal',
    'method',
    'seed',
    'episodes',
    'optimal_return',
    'success_rate',
    'detection_rate',
    'timeout_rate',
    'train_mean_return',
    'greedy_outcome',
    'greedy_return',
    'greedy_over_optimum',
    'steps',
    'path_length_m',
    'peak_visibility',
    'accumulated_visibility',
    'episodes_to_within_5pct',
    'wall_seconds',
    'env_steps',
)


def _outcome_name(value) -> str:
    return '' if value is None else Outcome(value).name


def run_row(result: RunResult, goal: str) -> dict:
    final, spec = result.final, result.spec
    rates = {name: float(np.mean(result.train_outcomes == Outcome[name])) for name in OUTCOMES}
    return {
        'scenario': scenario_label(spec.scenario),
        'goal': goal,
        'method': spec.learner,
        'seed': spec.seed,
        'episodes': spec.episodes,
        'optimal_return': result.optimum,
        'success_rate': rates['SUCCESS'],
        'detection_rate': rates['DETECTED'],
        'timeout_rate': rates['TIMEOUT'],
        'train_mean_return': float(result.train_returns.mean()),
        'greedy_outcome': _outcome_name(final['outcome']),
        'greedy_return': float(result.eval_returns[-1]),
        'greedy_over_optimum': float(result.eval_returns[-1]) / result.optimum,
        'steps': final['steps'],
        'path_length_m': final['path_length'],
        'peak_visibility': final['peak_visibility'],
        'accumulated_visibility': final['accumulated_visibility'],
        'episodes_to_within_5pct': result.episodes_to_within,
        'wall_seconds': result.seconds,
        'env_steps': result.env_steps,
    }


def baseline_row(scenario: str, goal: str, optimum: float, baseline: Baseline) -> dict:
    summary = baseline.summary
    outcome = summary['outcome']
    found = outcome is not None
    return {
        'scenario': scenario,
        'goal': goal,
        'method': baseline.name,
        'seed': '',
        'episodes': '',
        'optimal_return': optimum,
        'success_rate': float(outcome == Outcome.SUCCESS),
        'detection_rate': float(outcome == Outcome.DETECTED),
        'timeout_rate': float(outcome == Outcome.TIMEOUT),
        'train_mean_return': '',
        'greedy_outcome': _outcome_name(outcome) if found else 'no path',
        'greedy_return': summary.get('total_reward', ''),
        'greedy_over_optimum': summary['total_reward'] / optimum if found else '',
        'steps': summary.get('steps', ''),
        'path_length_m': summary.get('path_length', ''),
        'peak_visibility': summary.get('peak_visibility', ''),
        'accumulated_visibility': summary.get('accumulated_visibility', ''),
        'episodes_to_within_5pct': '',
        'wall_seconds': baseline.seconds,
        'env_steps': '',
    }


def write_csv(path: Path, rows: Sequence[dict]) -> None:
    with open(path, 'w', newline='', encoding='utf-8') as stream:
        writer = csv.DictWriter(stream, fieldnames=CSV_FIELDS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _csv_value(v) for k, v in row.items()})


def _csv_value(value):
    if isinstance(value, float):
        return f'{value:.6g}'
    return '' if value is None else value


def _mean(rows, key) -> float:
    return float(np.mean([row[key] for row in rows]))


def _episodes_text(rows) -> str:
    reached = sorted(
        row['episodes_to_within_5pct']
        for row in rows
        if row['episodes_to_within_5pct'] is not None
    )
    budget = rows[0]['episodes']
    if not reached:
        return f'**not within 5 % in {budget}**'
    median = int(np.median(reached))
    if len(reached) == len(rows):
        return f'{median} ({reached[0]}-{reached[-1]})'
    listed = ', '.join(map(str, reached))
    return f'**{len(reached)}/{len(rows)} seeds** ({listed}); the rest not in {budget}'


def markdown_table(rows: Sequence[dict]) -> str:
    """One table for all scenarios: baselines first, then learners averaged over seeds."""
    header = (
        '| scenario | method | success | detected | timeout | train return | greedy return '
        '| of optimum | path (m) | steps | acc. visibility | episodes to 5 % | wall (s) |\n'
        '| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n'
    )
    lines = []
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row['scenario'], row['method']), []).append(row)
    for (scenario, method), group in groups.items():
        first = group[0]
        if method in BASELINES:
            found = first['greedy_outcome'] != 'no path'
            lines.append(
                f'| {scenario} | {method} | {first["greedy_outcome"].lower()} | | | '
                f'| {first["greedy_return"]:.1f} | {first["greedy_over_optimum"]:.3f} '
                f'| {first["path_length_m"]:.1f} | {first["steps"]} '
                f'| {first["accumulated_visibility"]:.3f} | | {first["wall_seconds"]:.3f} |'
                if found
                else f'| {scenario} | {method} | no path | | | | | | | | | | |'
            )
            continue
        greedy = [row['greedy_return'] for row in group]
        outcomes = sorted({row['greedy_outcome'].lower() for row in group})
        lines.append(
            f'| {scenario} | {method} ({len(group)} seeds) | {_mean(group, "success_rate"):.2f} '
            f'| {_mean(group, "detection_rate"):.2f} | {_mean(group, "timeout_rate"):.2f} '
            f'| {_mean(group, "train_mean_return"):.1f} '
            f'| {np.mean(greedy):.1f} ± {np.std(greedy):.1f} ({"/".join(outcomes)}) '
            f'| {_mean(group, "greedy_over_optimum"):.3f} | {_mean(group, "path_length_m"):.1f} '
            f'| {_mean(group, "steps"):.0f} | {_mean(group, "accumulated_visibility"):.3f} '
            f'| {_episodes_text(group)} | {_mean(group, "wall_seconds"):.1f} |'
        )
    return header + '\n'.join(lines) + '\n'


# --- plots --------------------------------------------------------------------------------------

COLUMNS = (
    'Returns are undiscounted sums of the rewards after the first state. success / detected / '
    'timeout: outcome rates over all training episodes (planners: their one path). train '
    'return: mean over training episodes. greedy return: the final greedy policy, mean ± sd '
    "over seeds, and its outcomes. of optimum: greedy return / value iteration's optimal "
    'return. path, steps, acc. visibility: of the final greedy episode (visibility summed over '
    'the poses after each step). episodes to 5 %: from when on every greedy evaluation stayed '
    'within 5 % of the optimum, median (min-max) over seeds. wall: seconds per run.'
)
PATH_SHIFT = 0.08  # of a step, between the lines of two methods
COLOURS = {'qlearning': '#0571b0', 'sarsa': '#d01c8b', 'dyna': '#018571'}


def plot_curves(ax, results: Sequence[RunResult], optimum: float, title: str) -> None:
    """Greedy return (mean over seeds, min-max band) and training return (faint) per learner."""
    by_learner: dict[str, list[RunResult]] = {}
    for result in results:
        by_learner.setdefault(result.spec.learner, []).append(result)
    for learner, runs in by_learner.items():
        colour = COLOURS.get(learner)
        x = runs[0].eval_at
        greedy = np.array([r.eval_returns for r in runs])
        ax.plot(x, greedy.mean(axis=0), color=colour, linewidth=1.6, label=f'{learner} (greedy)')
        ax.fill_between(x, greedy.min(axis=0), greedy.max(axis=0), color=colour, alpha=0.2)
        window = max(len(runs[0].train_returns) // 40, 1)
        kernel = np.ones(window) / window
        train = np.array([np.convolve(r.train_returns, kernel, mode='valid') for r in runs])
        episodes = np.arange(window, window + train.shape[1])
        ax.plot(
            episodes,
            train.mean(axis=0),
            color=colour,
            linewidth=0.8,
            alpha=0.45,
            linestyle=':',
            label=f'{learner} (training, mean of {window})',
        )
    ax.axhline(optimum, color='black', linewidth=1.0, label=f'optimum {optimum:.1f}')
    ax.axhline(
        optimum - WITHIN * abs(optimum),
        color='black',
        linewidth=0.8,
        linestyle='--',
        label='5 % below the optimum',
    )
    ax.set_title(title)
    ax.set_xlabel('training episodes')
    ax.set_ylabel('return (undiscounted)')
    ax.grid(alpha=0.3)


def write_curves(out: Path, results: Sequence[RunResult], optima: dict[str, float]) -> list[Path]:
    scenarios = list(dict.fromkeys(r.spec.scenario for r in results))
    written = []
    columns = min(2, len(scenarios))
    rows = math.ceil(len(scenarios) / columns)
    combined = Figure(figsize=(7 * columns, 4.5 * rows), dpi=100)
    for k, scenario in enumerate(scenarios):
        mine = [r for r in results if r.spec.scenario == scenario]
        single = Figure(figsize=(8, 5), dpi=100)
        for ax in (single.add_subplot(), combined.add_subplot(rows, columns, k + 1)):
            plot_curves(ax, mine, optima[scenario], scenario_label(scenario))
        single.axes[0].legend(fontsize=7, loc='lower right')
        single.tight_layout()
        written.append(out / f'curves_{scenario_label(scenario)}.png')
        single.savefig(written[-1])
    combined.axes[0].legend(fontsize=7, loc='lower right')
    combined.tight_layout()
    written.append(out / 'learning_curves.png')
    combined.savefig(written[-1])
    return written


def write_paths(out: Path, model: LatticeModel, found: list[Baseline], results) -> Path:
    """The scenario picture with every method's path (learners: their first seed's)."""
    paths, labels = [], []
    for baseline in found:
        if baseline.summary.get('points') is not None:
            paths.append(baseline.summary['points'])
            labels.append(
                f'{baseline.name} ({_outcome_name(baseline.summary["outcome"]).lower()})'
            )
    seen = set()
    for result in results:
        if result.spec.learner in seen:
            continue
        seen.add(result.spec.learner)
        paths.append(result.final['points'])
        outcome = _outcome_name(result.final['outcome']).lower()
        labels.append(f'{result.spec.learner} seed {result.spec.seed} ({outcome})')
    task = model.task
    # Methods often share stretches of path: shift each line a few centimetres so all show.
    shift = PATH_SHIFT * task.scenario.step_distance
    shifted = [np.asarray(p) + (k - (len(paths) - 1) / 2) * shift for k, p in enumerate(paths)]
    return render_scenario(
        task.scenario,
        out / f'paths_{task.scenario.name}.png',
        paths=shifted,
        path_labels=labels,
        goal=task.goal.name,
        title=f'{task.title}: paths (drawn slightly apart where they coincide)',
    )


# --- the command --------------------------------------------------------------------------------


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
) -> list[dict]:
    """Run the grid and write every report into ``out``; returns the CSV rows."""
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
    )
    rows = []
    for scenario, model in models.items():
        optimum, found = planned[scenario]
        goal_name = model.task.goal.name
        label = scenario_label(scenario)
        rows += [baseline_row(label, goal_name, optimum, baseline) for baseline in found]
        rows += [run_row(r, goal_name) for r in results if r.spec.scenario == scenario]
    write_csv(out / 'results.csv', rows)
    budgets = ', '.join(f'{name} {episodes or default_budget(name)}' for name in learners)
    settings = (
        f'Seeds {", ".join(map(str, seeds))}; training episodes per run: {budgets}; greedy '
        f'evaluation every {eval_every} episodes; slip {slip:g}. Learner settings (all '
        f'learners): {_describe(tuned_config(learners[0], slip > 0))}.'
    )
    text = f'# stealth-nav evaluation\n\n{settings}\n\n{COLUMNS}\n\n{markdown_table(rows)}'
    if plots:
        optima = {scenario: planned[scenario][0] for scenario in scenarios}
        images = write_curves(out, results, optima)
        for scenario, model in models.items():
            mine = [r for r in results if r.spec.scenario == scenario]
            images.append(write_paths(out, model, planned[scenario][1], mine))
        text += '\n' + '\n'.join(f'![{p.stem}]({p.name})' for p in images) + '\n'
    (out / 'results.md').write_text(text, encoding='utf-8')
    return rows


def _describe(config: LearnerConfig) -> str:
    def schedule(s: Schedule) -> str:
        if s.kind == 'constant':
            return f'{s.start:g}'
        return f'{s.kind} {s.start:g} to {s.final:g} over {s.decay:g} episodes'

    return (
        f'alpha {schedule(config.alpha)}, epsilon {schedule(config.epsilon)}, gamma '
        f'{config.gamma:g}, initial Q {config.initial_value:g}, Dyna-Q planning updates per step '
        f'{config.n_planning}'
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
        help='scenario names or YAML paths (default: %(default)s)',
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
    parser.add_argument(
        '--episodes',
        type=int,
        help='training episodes per run (default per learner: '
        + ', '.join(f'{name} {budget}' for name, budget in DEFAULT_EPISODES.items())
        + ')',
    )
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
    parser.add_argument(
        '--jobs',
        type=int,
        default=os.cpu_count() or 1,
        help='worker processes (default: the CPU count, %(default)s)',
    )
    parser.add_argument(
        '--out', type=Path, default=DEFAULT_OUT, help='output directory (default: %(default)s)'
    )
    parser.add_argument('--no-plots', action='store_true', help='skip the pictures')
    args = parser.parse_args(argv)
    if (args.episodes is not None and args.episodes < 1) or args.eval_every < 1:
        parser.error('--episodes and --eval-every must be >= 1')
    if not 0.0 <= args.slip <= 1.0:
        parser.error('--slip must be a probability in [0, 1]')
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
        )
    except (OSError, ValueError) as error:
        print(f'experiments: {error}', file=sys.stderr)
        return 1
    print(args.out / 'results.md')
    return 0


if __name__ == '__main__':
    sys.exit(main())
