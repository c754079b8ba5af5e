"""The benchmark's methods, and one benchmark trial: a method on one scenario and goal, on each
of its tracks, as result rows. No Ray, no rclpy.

The tracks (``TRACKS``): ``full``, the robot knows the lights (today's task), and ``sensed``,
it knows the floor plan only and senses the light in its line of sight (``stealth_core.sensing``,
the Gym env's ``track='sensed'``), each a row of one episode; and ``learning``, for the learners
only, how much experience one needs to meet the success criterion and what it pays on the way
(``benchmark_learning``: episodes to the criterion, 3 in a row, detections, steps and wall time
before it, the median over LEARNING_SEEDS seeds; a greedy evaluation after every episode). The
learning track is not a default (``DEFAULT_TRACKS``): it trains every learner on several seeds
and evaluates after every episode, several times the default benchmark's work. Which method
runs on which track (``METHODS``), and why:

- ``value iteration``: the oracle, full knowledge, on both tracks (on the sensed track it is
  the same optimum: what a robot that knew the lights could do; every row's ``vi_return`` is
  its return).
- ``A*``: the shortest route, ignoring the lights; it needs only the floor plan, so it runs on
  both tracks, alike.
- ``Dark Path``: needs the lights (it plans around them): full track only.
- ``replan (unknown dark)``, ``replan (unknown lit)`` (``stealth_core.replanning``): sensed
  track only. On the full track they would see every light from the start and plan Dark Path's
  way on it (with static lights their first plan is Dark Path's route), so they add nothing
  there.
- the learners (``stealth_agent.learners.LEARNER_NAMES``: ``qlearning``, ``sarsa``, ``dyna``,
  ``prioritized`` and any learner registered there): on the full track trained per scenario
  (``harness.run``) for a stated budget of episodes, then one greedy episode; on the learning
  track trained on each seed for the budget with a greedy evaluation after every episode. Not
  on the sensed track (their state is the full track's; the sensed track's observation is not a
  table key).
- ``policy``: a learned policy file (``--policy``, ``stealth_agent.policy_store``) played
  greedily: full track only for now (a tabular file's state is the full track's).
- ``generalist``: the lights-known generalist of ``stealth_learn`` (``--policy-file``, default
  the shipped ``generalist-full.npz``), trained on generated buildings, never on these; each
  decision from its parameters (``stealth_learn.generalist_agent``): on the full track the value
  map of the lights as they stand, on the sensed track of what was sensed so far (never sensed:
  dark, as ``replan (unknown dark)``). It needs the learning extra (``make learn``);
  without it its rows fail with the one line saying so, and the other methods run. Moving
  lights need time-aware weights (``generalist-moving.npz``, or ``generalist-sensed.npz``
  trained for the sensed track: the phased grid, the wait; sensed, the phased belief of what
  was sensed at each phase); static weights given moving lights, or time-aware weights given
  static lights or another cycle, are refused in the row, naming the weights and the scenario.
- its twins, the same network played the same way, nothing learned (``TWINS``): ``generalist
  (hand-set)``, the scenario's reward written into its weights
  (``GeneralistPolicy.hand_set``); ``generalist (dark steps)``, -1 a move and -1e4 a lit one
  written in instead; ``generalist (untrained)``, its initialisation (its plans capped at the
  step limit's backups: its reward pays for a cycle, so its values never settle, and
  Bellman-Ford's bound took minutes a decision on 50 x 40 m buildings). The baselines a trained
  generalist must beat: where it does not beat its hand-set twin, learning bought nothing.
  ``generalist (cycle rule)`` (full track): the static network, hand-set, reading the cycle's
  brightest light field and never waiting (``GeneralistAgent(brightest=True)``): the naive rule
  a time-aware network must beat on moving lights (on static lights it is the hand-set twin).

Every row is measured the same way: one episode (a planner's path walked through the task,
``planners.walk``, or an episode on the Gym env), its outcome, return (undiscounted, the
rewards after the first state), path length (m) and exposure: the accumulated visibility, the
sum over the episode's steps of the judge's step visibility (the most light along each move,
``StealthTask.step_visibility``), as EpisodeSummary's ``accumulated_visibility``.
"""

from __future__ import annotations

import functools
import importlib.util
import time

import numpy as np
from stealth_agent.learners import LEARNER_NAMES
from stealth_agent.policy_store import check_compatible, load_policy
from stealth_agent.protocol import ProtocolAgent
from stealth_core.gym_env import StealthNavEnv, lattice_model
from stealth_core.lattice_model import LatticeModel
from stealth_core.planners import astar, dark_path, follow, value_iteration, walk
from stealth_core.replanning import SensedReplanner, play
from stealth_core.reward import EpisodeOutcome, detection_reward

from stealth_experiments.benchmark_learning import LEARNING_COLUMNS, learning_row
from stealth_experiments.harness import RunSpec, default_budget, play_episode, run

EPISODE_TRACKS = ('full', 'sensed')  # a row is one episode of the method
TRACKS = (*EPISODE_TRACKS, 'learning')
DEFAULT_TRACKS = EPISODE_TRACKS  # the learning track is asked for by name (module docstring)
ORACLE = 'value iteration'
# method -> the tracks it runs on (module docstring)
METHODS = {
    ORACLE: EPISODE_TRACKS,
    'A*': EPISODE_TRACKS,
    'Dark Path': ('full',),
    'replan (unknown dark)': ('sensed',),
    'replan (unknown lit)': ('sensed',),
    **dict.fromkeys(LEARNER_NAMES, ('full', 'learning')),
    'policy': ('full',),
    'generalist': EPISODE_TRACKS,
    'generalist (hand-set)': EPISODE_TRACKS,
    'generalist (dark steps)': EPISODE_TRACKS,
    'generalist (untrained)': EPISODE_TRACKS,
    'generalist (cycle rule)': ('full',),
}
# the generalist's twins: method -> GeneralistPolicy's weights ('env', 'dark-steps': hand-set)
TWINS = {
    'generalist (hand-set)': 'env',
    'generalist (dark steps)': 'dark-steps',
    'generalist (untrained)': 'untrained',
    'generalist (cycle rule)': 'cycle-rule',
}
GENERALISTS = ('generalist', *TWINS)  # the methods that need the learning extra
LEARNERS = tuple(LEARNER_NAMES)
REPLANNERS = {'replan (unknown dark)': 'dark', 'replan (unknown lit)': 'lit'}
# Names accepted by --methods for methods whose names have spaces or symbols.
ALIASES = {
    'vi': ORACLE,
    'value-iteration': ORACLE,
    'astar': 'A*',
    'dark-path': 'Dark Path',
    'replan-dark': 'replan (unknown dark)',
    'replan-lit': 'replan (unknown lit)',
    'generalist-hand-set': 'generalist (hand-set)',
    'generalist-dark-steps': 'generalist (dark steps)',
    'generalist-untrained': 'generalist (untrained)',
    'generalist-cycle-rule': 'generalist (cycle rule)',
}
COLUMNS = (
    'scenario', 'goal', 'track', 'method', 'status', 'success', 'detected', 'outcome',
    'return', 'vi_return', 'floor', 'regret', 'path_length', 'vi_path_length', 'exposure',
    'vi_exposure', 'steps', 'budget', *LEARNING_COLUMNS, 'seconds', 'file', 'error',
)  # fmt: skip


def method_name(name: str) -> str:
    """A method's name from --methods (its own name or an ALIASES key); ValueError else."""
    if name in METHODS:
        return name
    if name in ALIASES:
        return ALIASES[name]
    known = ', '.join(list(ALIASES) + [m for m in METHODS if ' ' not in m and m != 'A*'])
    raise ValueError(f'--methods: unknown method {name!r} (expected one of {known})')


def floor_of(model: LatticeModel) -> float:
    """The regret's floor: the return of being detected at the first step, the lowest over the
    start's moves (the detection reward of the distance to the goal still to go)."""
    weights = model.task.scenario.rewards
    distances = model.distance[model.successors[model.start]]
    return float(min(detection_reward(float(d), weights) for d in distances))


def regret(value: float, vi_return: float, floor: float) -> float:
    """Normalised regret ``(vi_return - value) / (vi_return - floor)``: 0 at the optimum, 1 at
    the floor (more for returns below it); NaN when the optimum is the floor."""
    span = vi_return - floor
    return float('nan') if span <= 0 else (vi_return - value) / span


def run_case(trial: dict) -> list[dict]:
    """One benchmark trial: ``trial['method']`` on ``trial['scenario']`` and ``trial['goal']``
    on each of ``trial['tracks']``; one row per track, a failed row (with its error) where the
    method raised. Keys of ``trial``: id, scenario, goal, method, tracks, file (the scenario
    file, for the rows), episodes (learners' budget, None: the harness's default), seed,
    learning_seeds (the learning track's seeds from ``seed`` on, None: LEARNING_SEEDS), policy
    (a policy file's path, for method 'policy'), policy_file (the generalist's weights, None:
    the shipped ones)."""
    rows = []
    for track in trial['tracks']:
        started = time.perf_counter()
        base = {
            'trial': trial['id'],
            'scenario': trial['label'],
            'goal': trial['goal'] or '',
            'track': track,
            'method': trial['method'],
            'file': trial['file'],
        }
        try:
            row = _measure(trial, track)
        except Exception as error:  # a method that fails is a failed row; the benchmark goes on
            text = f'{type(error).__name__}: {error}'.strip().splitlines()[0][:300]
            rows.append(failed_row(base, text, seconds=time.perf_counter() - started))
            continue
        rows.append({**base, 'status': 'ok', 'error': '', **row,
                     'seconds': time.perf_counter() - started})  # fmt: skip
    return rows


def failed_row(base: dict, error: str, status: str = 'failed', seconds=None) -> dict:
    """A row whose method did not run to the end (status 'failed' or 'interrupted')."""
    return {**base, 'status': status, 'error': error, 'seconds': seconds}


def _measure(trial: dict, track: str) -> dict:
    if track == 'learning':
        if track not in METHODS[trial['method']]:
            raise ValueError(f'{trial["method"]} does not run on the learning track')
        return learning_row(trial)
    model = lattice_model(trial['scenario'], trial['goal'])
    optimum = value_iteration(model)
    vi_walk = walk(model, follow(model, lambda i: int(optimum.policy[i])))
    summary, budget = _episode(trial, track, model, optimum, vi_walk)
    outcome = summary['outcome']
    name = 'NONE' if outcome is None else EpisodeOutcome(outcome).name
    floor = floor_of(model)
    value = float(summary['total_reward'])
    return {
        'success': name == 'SUCCESS',
        'detected': name == 'DETECTED',
        'outcome': name.lower(),
        'return': value,
        'vi_return': optimum.optimal_return,
        'floor': floor,
        'regret': regret(value, optimum.optimal_return, floor),
        'path_length': float(summary['path_length']),
        'vi_path_length': float(vi_walk.path_length),
        'exposure': float(summary['accumulated_visibility']),
        'vi_exposure': float(vi_walk.accumulated_visibility),
        'steps': int(summary['steps']),
        'budget': budget,
    }


def _walked(model: LatticeModel, path) -> dict:
    if path is None:  # no route at all: nothing walked, the episode never began
        return {'outcome': None, 'total_reward': float('nan'), 'path_length': 0.0,
                'accumulated_visibility': 0.0, 'steps': 0}  # fmt: skip
    result = walk(model, path)
    return {
        'outcome': result.outcome,
        'total_reward': result.total_reward,
        'path_length': result.path_length,
        'accumulated_visibility': result.accumulated_visibility,
        'steps': result.steps,
    }


def _episode(trial: dict, track: str, model, optimum, vi_walk) -> tuple[dict, int | None]:
    """(the method's episode as EpisodeSummary's figures, its training budget or None)."""
    method = trial['method']
    if track not in METHODS[method]:
        raise ValueError(f'{method} does not run on the {track} track')
    if method == ORACLE:
        # its return is the optimum itself (the walk's sum may differ in the last digit)
        return {**vi_walk._asdict(), 'total_reward': optimum.optimal_return}, None
    if method == 'A*':
        return _walked(model, astar(model)), None
    if method == 'Dark Path':
        return _walked(model, dark_path(model)), None
    if method in REPLANNERS:
        env = StealthNavEnv(trial['scenario'], trial['goal'], track='sensed')
        replanner = SensedReplanner(env.model, REPLANNERS[method])
        return play(env, replanner.act, seed=trial['seed']), None
    if method in LEARNERS:
        budget = trial['episodes'] or default_budget(method, trial['scenario'])
        spec = RunSpec(
            trial['scenario'], method, trial['seed'], budget, budget, goal=trial['goal']
        )
        return run(spec).final, budget
    if method == 'policy':
        return _play_policy(trial), None
    if method in GENERALISTS:
        return _play_generalist(trial, track), None
    raise ValueError(f'unknown method {method!r}')


def _play_policy(trial: dict) -> dict:
    """One greedy episode of the policy file on the full track (unseen states: the learner's
    first row's defaults, as a fresh table row)."""
    saved = load_policy(trial['policy'])
    env = StealthNavEnv(trial['scenario'], trial['goal'])
    check_compatible(saved, num_actions=int(env.action_space.n))
    rng = saved.restored_rng() or np.random.default_rng(trial['seed'])
    agent = ProtocolAgent(saved.learner, saved.index, rng, learning=False)
    _, info = play_episode(env, agent, seed=trial['seed'])
    return env.stats.summary(EpisodeOutcome[info['outcome']])._asdict()


def _play_generalist(trial: dict, track: str) -> dict:
    """One greedy episode of the generalist or one of its twins (``trial['method']``) on
    ``track`` (its imports here: the learning extra's MissingExtraError, one line naming make
    learn, fails this row only)."""
    from stealth_learn.generalist_agent import GeneralistAgent

    env = StealthNavEnv(trial['scenario'], trial['goal'], track=track)
    policy = generalist_policy(trial.get('policy_file'))
    twin = TWINS.get(trial['method'])
    if twin is not None:
        policy = _twin(policy.header['architecture'], twin, env.scenario, env.model.task.goal.name)
    # the untrained reward pays for a cycle: its values never settle, so its plans stop at the
    # step limit's backups (k backups: the best k-step return) instead of Bellman-Ford's bound
    horizon = env.model.task.step_limit if twin == 'untrained' else None
    agent = GeneralistAgent(policy, env, brightest=twin == 'cycle-rule', horizon=horizon)
    return play(env, agent.act, seed=trial['seed'])


@functools.lru_cache(maxsize=2)
def generalist_policy(path: str | None):
    """The generalist's weights (None: the shipped ones), loaded once per process: its compiled
    network is reused by the trials that follow."""
    from stealth_learn.generalist_agent import load_policy

    return load_policy(path)


def _twin(architecture: dict, kind: str, scenario, goal: str):
    """The twin ``kind`` ('env', 'dark-steps': hand-set for this scenario's reward and goal;
    'untrained'; 'cycle-rule': the static network of the same sizes, hand-set 'env') of the
    weights of ``architecture``."""
    from stealth_learn.generalist import GeneralistPolicy
    from stealth_learn.hand_set import ScenarioReward

    if kind == 'untrained':
        return _untrained(tuple(sorted(architecture.items())))
    if kind == 'cycle-rule':
        kind = 'env'
        architecture = {k: v for k, v in architecture.items() if k not in ('layers', 'advance')}
    return GeneralistPolicy.hand_set(architecture, ScenarioReward.of(scenario, goal), kind)


@functools.lru_cache(maxsize=2)
def _untrained(architecture: tuple):
    from stealth_learn.generalist import GeneralistPolicy

    return GeneralistPolicy.untrained(dict(architecture))


def learning_extra() -> bool:
    """Whether the learning extra (jax, flax) is installed, without importing it."""
    return all(importlib.util.find_spec(name) is not None for name in ('jax', 'flax'))
