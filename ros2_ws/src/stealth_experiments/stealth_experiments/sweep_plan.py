"""A sweep file, checked and laid out as trials before anything starts. No rclpy, no Ray.

A sweep file (YAML; docs/sweeps/example.yaml) names what to train and how::

    name: example                 # default: the file's stem
    scenarios:                    # names, or YAML paths relative to this file; or
                                  # {scenario: map1, goal: easy}
      - simple-maze
    goal: easy                    # default goal of every scenario listed by name only
    learners: [qlearning, dyna]
    seeds: [0, 1]
    episodes: 300                 # per run; or {qlearning: 600, dyna: 200}
    eval_every: 10                # episodes between greedy evaluations
    slip: 0.0
    mode: gym                     # gym: in-process (Gymnasium); ros: `stealth train`
    search: grid                  # grid | random | optuna
    trials: 6                     # random, optuna: samples per scenario x learner
    seed: 0                       # random, optuna: the sampler's seed
    params:                       # harness.PARAMETERS
      alpha: [0.5, 1.0]           # a list: these values
      epsilon: {low: 0.05, high: 0.3, log: false}   # a range (random, optuna)
    extra:                        # single trials added as they are (any mode)
      - {mode: ros, scenario: simple-maze, goal: easy, learner: dyna, seed: 0, episodes: 40}

A trial is one configuration (scenario, goal, learner, settings, mode) on its seeds: grid and
random trials have one seed each; an optuna trial evaluates its configuration on every seed (its
objective is the mean over them, ``sweep_trials.objective``). Grid and random trials, and extra
ones, are laid out here with ids that depend only on their settings, so a resumed sweep knows
which are done; optuna trials are suggested by the search as it goes. Every problem is one
SweepError naming the file, the field and what was expected: a value listed twice (a learner, a
seed, a scenario, a parameter value) too, and a sweep of more than MAX_TRIALS trials (counted
from the lists, before any trial is laid out).

Scenario paths (anything with a '/' or a .yaml ending; harness.scenario_argument) are relative to
the sweep file's directory and made absolute here, once: the trials get them as they are, in
whatever directory Ray starts them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from stealth_agent.learners import canonical_learner_name

from stealth_experiments.harness import (
    DEFAULT_EVAL_EVERY,
    PARAMETERS,
    PRIOR_PARAMETER,
    configured,
    prior_of,
    scenario_argument,
    scenario_label,
)

MODES = ('gym', 'ros')
SEARCHES = ('grid', 'random', 'optuna')
INTEGER_PARAMETERS = ('n_planning',)
TOP_LEVEL = (
    'name', 'scenarios', 'goal', 'learners', 'seeds', 'episodes', 'eval_every', 'slip', 'mode',
    'search', 'trials', 'seed', 'params', 'extra', 'cpus_per_trial', 'max_failures',
)  # fmt: skip
EXTRA_FIELDS = ('mode', 'scenario', 'goal', 'learner', 'seed', 'episodes', 'params')
# Trials a sweep may have: a grid of more is refused before Ray starts (Tune lays every trial
# out in the driver's memory first; 300,000 took minutes and a gigabyte before the first ran).
MAX_TRIALS = 10_000


class SweepError(ValueError):
    """A sweep file that cannot make a sweep; the message is one line naming where and why."""


@dataclasses.dataclass(frozen=True)
class Range:
    """A parameter range for random or optuna search: uniform (or log-uniform) in [low, high]."""

    low: float
    high: float
    log: bool = False


@dataclasses.dataclass(frozen=True)
class Group:
    """The trials of one scenario and learner: what optuna searches over, together."""

    scenario: str
    goal: str | None
    learner: str
    episodes: int

    @property
    def label(self) -> str:
        goal = f'-{self.goal}' if self.goal else ''
        return f'{scenario_label(self.scenario)}{goal}-{self.learner}'


@dataclasses.dataclass(frozen=True)
class SweepPlan:
    path: Path
    name: str
    groups: tuple[Group, ...]
    seeds: tuple[int, ...]
    eval_every: int
    slip: float
    mode: str
    search: str
    trials: int
    seed: int
    params: dict[str, list | Range]
    extra: tuple[dict, ...]
    cpus_per_trial: float
    max_failures: int

    def trial_count(self) -> tuple[int, str]:
        """(trials, how that count is made) from the lists alone, without laying them out."""
        groups = f'{len(self.groups)} scenario x learner group(s)'
        if self.search == 'grid':
            combos = math.prod(len(values) for values in self.params.values())
            count = len(self.groups) * combos * len(self.seeds)
            how = f'{groups} x {combos:,} parameter combination(s) x {len(self.seeds)} seed(s)'
        elif self.search == 'random':
            count = len(self.groups) * self.trials * len(self.seeds)
            how = f'{groups} x {self.trials:,} sample(s) x {len(self.seeds)} seed(s)'
        else:
            count = len(self.groups) * self.trials
            how = f'{groups} x {self.trials:,} trial(s)'
        if self.extra:
            how += f' + {len(self.extra)} extra'
        return count + len(self.extra), how

    def fixed_trials(self) -> list[dict]:
        """Every trial laid out in advance: grid or random ones, then the extra ones."""
        found = []
        if self.search != 'optuna':
            for group in self.groups:
                for params in self._samples(group):
                    found += [self.trial(group, params, [seed]) for seed in self.seeds]
        return found + list(self.extra)

    def _samples(self, group: Group) -> list[dict]:
        names = sorted(self.params)
        if self.search == 'grid':
            values = [self.params[name] for name in names]
            return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*values)]
        key = [self.seed, *hashlib.sha1(group.label.encode()).digest()[:4]]
        rng = np.random.default_rng(key)
        return [
            {name: sample(self.params[name], name, rng) for name in names}
            for _ in range(self.trials)
        ]

    def trial(self, group: Group, params: dict, seeds: list[int], mode: str | None = None):
        return make_trial(
            mode or self.mode, group.scenario, group.goal, group.learner, seeds,
            group.episodes, self.eval_every, self.slip, params,
        )  # fmt: skip

    def optuna_space(self) -> dict:
        """The search space in Ray Tune's terms (OptunaSearch converts it for Optuna)."""
        from ray import tune

        space = {}
        for name, spec in self.params.items():
            if isinstance(spec, list):
                space[name] = tune.choice(spec)
            elif name in INTEGER_PARAMETERS:
                space[name] = (tune.lograndint if spec.log else tune.randint)(
                    int(spec.low), int(spec.high) + 1
                )
            else:
                space[name] = (tune.loguniform if spec.log else tune.uniform)(spec.low, spec.high)
        return space


def sample(spec, name: str, rng: np.random.Generator):
    """One random value of a parameter: a list's element or a point of a range."""
    if isinstance(spec, list):
        return spec[int(rng.integers(len(spec)))]
    if spec.log:
        value = float(math.exp(rng.uniform(math.log(spec.low), math.log(spec.high))))
    else:
        value = float(rng.uniform(spec.low, spec.high))
    return int(round(value)) if name in INTEGER_PARAMETERS else round(value, 6)


def make_trial(mode, scenario, goal, learner, seeds, episodes, eval_every, slip, params) -> dict:
    """A trial as plain data (it travels to the Ray workers), with an id made of its settings."""
    trial = {
        'mode': mode,
        'scenario': scenario,
        'goal': goal,
        'learner': learner,
        'seeds': [int(s) for s in seeds],
        'episodes': int(episodes),
        'eval_every': int(eval_every),
        'slip': float(slip),
        'params': dict(sorted(params.items())),
    }
    digest = hashlib.sha1(json.dumps(trial, sort_keys=True).encode()).hexdigest()[:8]
    goal_part = f'-{goal}' if goal else ''
    seed_part = f'-s{seeds[0]}' if len(seeds) == 1 else ''
    trial['id'] = f'{scenario_label(scenario)}{goal_part}-{learner}{seed_part}-{mode}-{digest}'
    return trial


# --- reading the file ---------------------------------------------------------------------------


def load_plan(
    path: str | Path, base: str | Path | None = None, name: str | None = None
) -> SweepPlan:
    """The checked plan of a sweep file; SweepError naming the field otherwise. ``base``: the
    directory its scenario paths are relative to (default: the file's own), ``name``: its name
    when the file gives none (default: the file's stem); --resume reads a copy, whose paths are
    relative to where the original was and whose stem is not the sweep's name."""
    path = Path(path)
    try:
        import yaml

        data = yaml.safe_load(path.read_text(encoding='utf-8'))
    except OSError as error:
        raise SweepError(f'sweep file {path}: cannot read it ({error.strerror})') from None
    except yaml.YAMLError as error:
        where = getattr(error, 'problem_mark', None)
        line = f' (line {where.line + 1})' if where is not None else ''
        raise SweepError(f'sweep file {path}: not valid YAML{line}') from None
    return parse_plan(data, path, base, name)


def parse_plan(
    data: Any, path: Path, base: str | Path | None = None, name: str | None = None
) -> SweepPlan:
    base = Path(path).parent if base is None else Path(base)

    def fail(field: str, problem: str):
        raise SweepError(f'sweep file {path}: {field}: {problem}')

    if not isinstance(data, dict):
        raise SweepError(f'sweep file {path}: expected a mapping of {", ".join(TOP_LEVEL)}')
    for key in data:
        if key not in TOP_LEVEL:
            fail(key, f'unknown field (expected one of {", ".join(TOP_LEVEL)})')
    learners = _list(data.get('learners'), 'learners', fail)
    try:
        learners = [canonical_learner_name(name) for name in learners]
    except ValueError as error:
        fail('learners', str(error))
    _unique(learners, 'learners', fail)
    seeds = _list(data.get('seeds', [0]), 'seeds', fail)
    if not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds):
        fail('seeds', f'expected whole numbers >= 0, got {seeds}')
    _unique(seeds, 'seeds', fail)
    mode = data.get('mode', 'gym')
    if mode not in MODES:
        fail('mode', f'expected one of {", ".join(MODES)}, got {mode!r}')
    search = data.get('search', 'grid')
    if search not in SEARCHES:
        fail('search', f'expected one of {", ".join(SEARCHES)}, got {search!r}')
    eval_every = _whole(data.get('eval_every', DEFAULT_EVAL_EVERY), 'eval_every', fail, 1)
    trials = _whole(data.get('trials', 1), 'trials', fail, 1)
    slip = data.get('slip', 0.0)
    if not isinstance(slip, int | float) or not 0 <= slip <= 1:
        fail('slip', f'expected a probability in [0, 1], got {slip!r}')
    params = _params(data.get('params') or {}, search, mode, fail)
    episodes = data.get('episodes', 300)
    scenarios = [
        _scenario(entry, data.get('goal'), f'scenarios[{i}]', fail, base)
        for i, entry in enumerate(_list(data.get('scenarios'), 'scenarios', fail))
    ]
    _unique(scenarios, 'scenarios', fail, lambda s: f'{s[0]}{f" (goal {s[1]})" if s[1] else ""}')
    groups = tuple(
        Group(scenario, goal, learner, _budget(episodes, learner, fail))
        for scenario, goal in scenarios
        for learner in learners
    )
    plan = SweepPlan(
        path=path,
        name=str(data.get('name') or name or path.stem),
        groups=groups,
        seeds=tuple(seeds),
        eval_every=eval_every,
        slip=float(slip),
        mode=mode,
        search=search,
        trials=trials,
        seed=_whole(data.get('seed', 0), 'seed', fail, 0),
        params=params,
        extra=(),
        cpus_per_trial=float(data.get('cpus_per_trial', 1)),
        max_failures=_whole(data.get('max_failures', 2), 'max_failures', fail, 0),
    )
    if not plan.cpus_per_trial > 0:
        fail('cpus_per_trial', f'expected a number > 0, got {data["cpus_per_trial"]!r}')
    extra = data.get('extra') or []
    if not isinstance(extra, list):
        fail('extra', f'expected a list of trials, got {extra!r}')
    count, how = dataclasses.replace(plan, extra=tuple(extra)).trial_count()
    if count > MAX_TRIALS:
        raise SweepError(
            f'sweep file {path}: {count:,} trials ({how}), more than the {MAX_TRIALS:,} a sweep '
            'may have: list fewer scenarios, learners, seeds or parameter values (or fewer '
            'trials), or split it into several sweep files'
        )
    extra = [_extra(entry, plan, f'extra[{i}]', fail, base) for i, entry in enumerate(extra)]
    return dataclasses.replace(plan, extra=tuple(extra))


def _unique(values: list, field: str, fail, show=repr) -> None:
    """A value listed twice would run the same trials twice (and report them once)."""
    seen = set()
    for value in values:
        key = repr(value)  # a mapping where a value belongs is the next check's to refuse
        if key in seen:
            fail(field, f'{show(value)} is listed twice (list each once)')
        seen.add(key)


def _list(value, field, fail) -> list:
    if isinstance(value, str | int):
        value = [value]
    if not isinstance(value, list) or not value:
        fail(field, f'expected a non-empty list, got {value!r}')
    return value


def _whole(value, field, fail, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        fail(field, f'expected a whole number >= {least}, got {value!r}')
    return value


def _budget(episodes, learner: str, fail) -> int:
    if isinstance(episodes, dict):
        if learner not in episodes:
            fail('episodes', f'no budget for learner {learner!r} (it has: {", ".join(episodes)})')
        return _whole(episodes[learner], f'episodes.{learner}', fail, 1)
    return _whole(episodes, 'episodes', fail, 1)


def _scenario(entry, default_goal, field, fail, base: Path) -> tuple[str, str | None]:
    from stealth_core.scenario import load_scenario

    goal = default_goal
    if isinstance(entry, dict):
        unknown = set(entry) - {'scenario', 'goal'}
        if unknown or 'scenario' not in entry:
            fail(field, f'expected {{scenario: NAME, goal: GOAL}}, got {entry!r}')
        entry, goal = entry['scenario'], entry.get('goal', default_goal)
    given, entry = str(entry), scenario_argument(str(entry), base)
    try:
        scenario = load_scenario(entry)
    except (OSError, ValueError) as error:
        relative = entry != given and not Path(given).is_absolute()
        where = f" ({given} is relative to the sweep file's directory)" if relative else ''
        fail(field, f'{error}{where}')
    if goal is not None and goal not in scenario.goals:
        fail(f'{field}.goal', f'{scenario.name} has no goal {goal!r} (it has: '
             f'{", ".join(scenario.goals)})')  # fmt: skip
    return entry, goal


def _params(data, search: str, mode: str, fail) -> dict[str, list | Range]:
    if not isinstance(data, dict):
        fail('params', f'expected a mapping of {", ".join(PARAMETERS)} to values')
    params = {}
    for name, spec in data.items():
        field = f'params.{name}'
        if name not in PARAMETERS:
            fail(field, f'unknown parameter (expected one of {", ".join(PARAMETERS)})')
        if name == PRIOR_PARAMETER and mode == 'ros':
            fail(field, 'in-process trials only (mode gym): the agent node has no floor plan')
        if isinstance(spec, int | float | str) and not isinstance(spec, bool):
            spec = [spec]
        if isinstance(spec, list):
            if not spec:
                fail(field, 'empty list of values')
            _unique(spec, field, fail)
            values = spec
        elif isinstance(spec, dict):
            if search == 'grid':
                fail(field, 'a grid needs a list of values, not a range (or use search: random)')
            if set(spec) - {'low', 'high', 'log'} or not {'low', 'high'} <= set(spec):
                fail(field, f'expected {{low: L, high: H, log: false}}, got {spec!r}')
            low, high = spec['low'], spec['high']
            if not all(isinstance(v, int | float) for v in (low, high)) or not low < high:
                fail(field, f'empty range: expected low < high, got {low!r} and {high!r}')
            if spec.get('log') and low <= 0:
                fail(field, f'a log range needs low > 0, got {low!r}')
            values = [low, high]
            spec = Range(float(low), float(high), bool(spec.get('log', False)))
        else:
            fail(field, f'expected a list of values or {{low: L, high: H}}, got {spec!r}')
        for value in values:  # every value (a range's ends) must make a learner
            try:
                configured('qlearning', False, [(name, value)])
                prior_of('qlearning', [(name, value)])
            except (TypeError, ValueError) as error:
                fail(field, str(error))
        params[name] = spec
    return params


def _extra(entry, plan: SweepPlan, field, fail, base: Path) -> dict:
    if not isinstance(entry, dict):
        fail(field, f'expected a mapping of {", ".join(EXTRA_FIELDS)}, got {entry!r}')
    for key in entry:
        if key not in EXTRA_FIELDS:
            fail(f'{field}.{key}', f'unknown field (expected one of {", ".join(EXTRA_FIELDS)})')
    mode = entry.get('mode', plan.mode)
    if mode not in MODES:
        fail(f'{field}.mode', f'expected one of {", ".join(MODES)}, got {mode!r}')
    try:
        learner = canonical_learner_name(entry.get('learner', 'dyna'))
    except ValueError as error:
        fail(f'{field}.learner', str(error))
    scenario, goal = _scenario(
        {'scenario': entry.get('scenario', 'simple-maze'), 'goal': entry.get('goal')},
        None,
        f'{field}.scenario',
        fail,
        base,
    )
    params = _params(entry.get('params') or {}, 'grid', mode, lambda f, p: fail(f'{field}.{f}', p))
    seed = _whole(entry.get('seed', 0), f'{field}.seed', fail, 0)
    episodes = _whole(entry.get('episodes', 300), f'{field}.episodes', fail, 1)
    several = [name for name, values in params.items() if len(values) != 1]
    if several:
        fail(f'{field}.params.{several[0]}', 'an extra trial takes one value')
    single = {name: values[0] for name, values in params.items()}
    return make_trial(mode, scenario, goal, learner, [seed], episodes, plan.eval_every,
                      plan.slip, single)  # fmt: skip
