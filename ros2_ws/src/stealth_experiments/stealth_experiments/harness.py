"""The experiment harness's runs: one learner trained in-process on one scenario with one seed,
and the planning baselines it is measured against. No rclpy.

Each run trains a learner (``stealth_agent``, driven through ``ProtocolAgent`` exactly as the
ROS agent node drives it) on the Gymnasium environment for a fixed budget of episodes, and every
``eval_every`` episodes rolls out the greedy policy.

Definitions. A return sums the rewards after the first state, undiscounted; the optimum is
``planners.value_iteration``'s (undiscounted, exact, with the step limit). Rates count the
training episodes' outcomes. A greedy evaluation *meets the criterion* when its episode does
(``stealth_core.path_scores.meets_criterion`` against value iteration's path: reached the goal
undetected, path <= ``max_path_ratio`` x the optimum's, accumulated exposure <= the optimum's +
``exposure_tolerance``; with slip, the mean of its rollouts). "Episodes to the criterion" is the
first evaluation point from which every later greedy evaluation of the run meets it (it stays
there, not just touches it); a run that never settles is reported as not meeting it in its
budget. "Episodes to the criterion, STREAK in a row" (``first_streak``, ``RunResult.cost``;
issue 41's measure, the bench's and the benchmark's learning track) is the first evaluation of
the first STREAK consecutive evaluations that meet it: it asks less than settling (a later
failure does not undo it) but more than one lucky evaluation. What learning cost until then
(``LearningCost``): the training episodes that ended DETECTED, the environment steps and the
wall time until the evaluation after it (the greedy evaluations included: a learner may do its
planning when it acts greedily, light-model and prioritized sweeping's known way do).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
import time

import numpy as np
from stealth_agent.learners import (
    OPTIMISTIC,
    LearnerConfig,
    canonical_learner_name,
    make_learner,
)
from stealth_agent.light_model import LightModelLearner
from stealth_agent.policy_store import save_policy
from stealth_agent.protocol import ProtocolAgent, parse_description
from stealth_agent.schedules import Schedule
from stealth_agent.state_index import StateIndex
from stealth_core.floor_plan_prior import PRIORS, floor_plan_prior
from stealth_core.gym_env import StealthNavEnv, lattice_model
from stealth_core.lattice_model import LatticeModel
from stealth_core.light_world import LightWorld
from stealth_core.path_scores import (
    DEFAULT_CRITERION,
    OPTIMUM_GAMMA,
    Criterion,
    PathScores,
    mean_scores,
    meets_criterion,
    optimum_path,
)
from stealth_core.planners import astar, dark_path, follow, value_iteration, walk
from stealth_core.replanning import SensedReplanner, play
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import content_identity

# Training episodes per run, per learner: each well past where every seed settled (README);
# Dyna-Q's 20 planning updates make its episodes ~5x dearer and it needs ~1/6 as many;
# prioritized sweeping, exploring from the floor plan, settled on every seed of every static
# scenario by episode 70 (map1-exposure; bench_learners, 2026-11-28).
DEFAULT_EPISODES = {
    'qlearning': 1500, 'sarsa': 1500, 'dyna': 500, 'prioritized': 300, 'light-model': 12,
}  # fmt: skip
# Scenarios with the phase in the state (moving lights) have phase_bins times the states: each
# learner gets a larger budget there (README: Q-learning settled at 2580 on simple-maze-moving,
# 5730 on lgfloor-moving and 11,610-11,740 on floorplan-moving, where 6000 never reached the
# goal; Dyna-Q at 1110 on lgfloor-moving and 1810 on floorplan-moving, where 1000 was too few;
# prioritized sweeping, at gamma 1 and exploring from the floor plan, met the success criterion
# from 300 on simple-maze-moving, 240 on map1-moving, 190 on lgfloor-moving and 1010 on
# floorplan-moving, seed 0; with the goal reward as its optimism 250, 320, 610 and 790; before
# optimism 270, 280, 600 (seed 1; seed 0 settled on a 1.12x path) and 690).
MOVING_EPISODES = {
    'qlearning': 15000, 'sarsa': 15000, 'dyna': 3000, 'prioritized': 1500, 'light-model': 300,
}  # fmt: skip
DEFAULT_EVAL_EVERY = 10
WITHIN = 0.05  # of the optimal return: the old criterion, kept for settled_within only
STREAK = 3  # evaluations in a row that meet the criterion (first_streak)
BASELINES = ('A*', 'Dark Path', 'value iteration')
# The unknown-light track's baselines (stealth_core.replanning), by the rule for unsensed places.
SENSED_BASELINES = {'replan (unknown dark)': 'dark', 'replan (unknown lit)': 'lit'}
# Settings a sweep may vary (RunSpec.params), over tuned_config's: alpha (constant), epsilon (its
# start; it decays exponentially to 0 with time constant epsilon_decay episodes), gamma,
# initial_value (initial Q), n_planning (Dyna-Q's and prioritized sweeping's planning updates
# per step), theta (prioritized sweeping's priority threshold) and prior (PRIOR_PARAMETER).
PARAMETERS = (
    'alpha', 'epsilon', 'epsilon_decay', 'gamma', 'initial_value', 'n_planning', 'theta', 'prior',
)  # fmt: skip
# Planning updates per real step: Dyna-Q's, and prioritized sweeping's at most (it stops when
# its queue runs dry, so a larger cap costs only where values still change).
PLANNING_UPDATES = {'dyna': 20, 'prioritized': 200}
# Where a run's table starts (RunSpec.params 'prior', a sweep setting too): 'floor_plan', each
# state's action values with the lights dark (floor_plan_prior), or 'none', initial_value
# everywhere. Absent: floor_plan for the OPTIMISTIC learners, none for the others.
PRIOR_PARAMETER = 'prior'
# The success criterion's options (stealth_core.path_scores.Criterion), carried in
# RunSpec.params beside the learner's settings so that they travel with a run to any worker;
# absent, the defaults.
CRITERION_PARAMETERS = ('max_path_ratio', 'exposure_tolerance')


def tuned_config(
    learner: str, stochastic: bool = False, goal_reward: float | None = None
) -> LearnerConfig:
    """The settings the harness trains with: the same for the one-step learners and Dyna-Q, so
    that only the algorithm differs, chosen by measurement (the README's evaluation section);
    prioritized sweeping explores by optimism instead (below, given the task's ``goal_reward``).

    alpha 1 on the deterministic lattice (one sample of a transition is its expectation, so the
    first good update is final; 0.5 and 0.3 took 1.5-2x the episodes); 0.3 with slip, to average
    the noise. Q starts at 0, which with step costs below 0 is already optimistic: unvisited
    actions look best, and exploration is systematic (an optimistic start at the goal reward
    made every run wander to the step limit for hundreds of episodes). epsilon decays from 0.1
    to 0 with a time constant of 100 episodes: SARSA learns the value of its own epsilon-greedy
    policy, and with a detection penalty of 1000 a 10 % chance of a random step next to a lit
    cell makes hovering in the dark look better than the door to the goal (with epsilon fixed at
    0.1 its greedy policy timed out instead of reaching the goal). Dyna-Q plans 20 updates per
    step; prioritized sweeping up to 200, while a queued change exceeds theta 0.01. gamma 1
    (``path_scores.OPTIMUM_GAMMA``): the return and the optimum the criterion judges by are
    undiscounted, and at 0.99 a converged learner takes more light to save a step on the
    moving-light scenarios (path_scores' docstring); on map1 prioritized sweeping settled at
    episodes 70/60/60 (seeds 0-2) at gamma 1 against 50/60/60 at 0.99.

    Prioritized sweeping, given the task's ``goal_reward``, explores as Moore and Atkeson's
    does, by optimism in the face of uncertainty (R-max style): a state-action its model has
    never seen is worth what the floor plan says (``run`` starts each new state's row at
    floor_plan_prior's values, an upper bound on the true ones; PRIOR_PARAMETER), or the goal
    reward where no prior is given, until tried once; epsilon is 0 (OPTIMISTIC). The floor plan
    spares the pairs that lead away from the goal: on map1 the constant needed 70 episodes
    (seed 0), the floor plan 40. The greedy route then leaves the first route found for
    every untried pair that could still lie on a cheaper one, and settles on the optimum once
    none is left. Q 0 is optimistic only until the goal is found: the first route found stood,
    and on the exposure and bounce variants it was 1.03-1.54x long or more exposed than the
    optimum for good (bench_learners). The optimism is not the largest return (goal reward +
    goal_distance_weight x goal_radius, 1050, RLEnvDescription's max_reward): that bonus for
    stopping nearer the goal point is more than most routes cost, so every untried pair looked
    better than reaching the goal and simple-maze-exposure explored for all its 300 episodes
    (245 detections) without settling; the criterion does not judge that bonus.
    """
    name = canonical_learner_name(learner)
    optimistic = name in OPTIMISTIC and goal_reward is not None
    return LearnerConfig(
        gamma=OPTIMUM_GAMMA,
        alpha=Schedule.fixed(0.3 if stochastic else 1.0),
        # Optimism explores; the decay constant stays for a sweep that sets 'epsilon'.
        epsilon=Schedule('exponential', 0.0 if optimistic else 0.1, 0.0, 100.0),
        initial_value=float(goal_reward) if optimistic else 0.0,
        n_planning=PLANNING_UPDATES.get(name, 20),
        theta=0.01,
    )


def configured(
    learner: str, stochastic: bool = False, params=(), goal_reward: float | None = None
) -> LearnerConfig:
    """tuned_config with the settings in ``params`` ((name, value) pairs of PARAMETERS)
    instead; ValueError naming a setting that is unknown or out of range."""
    config = tuned_config(learner, stochastic, goal_reward)
    values = {
        k: v
        for k, v in dict(params).items()
        if k not in CRITERION_PARAMETERS and k != PRIOR_PARAMETER
    }
    unknown = sorted(set(values) - set(PARAMETERS))
    if unknown:
        raise ValueError(
            f'unknown parameter {unknown[0]!r} (expected one of {", ".join(PARAMETERS)})'
        )
    epsilon = config.epsilon
    if 'epsilon' in values or 'epsilon_decay' in values:
        epsilon = Schedule(
            'exponential',
            float(values.get('epsilon', epsilon.start)),
            0.0,
            float(values.get('epsilon_decay', epsilon.decay)),
        )
    n_planning = values.get('n_planning', config.n_planning)
    if isinstance(n_planning, float) and n_planning.is_integer():
        n_planning = int(n_planning)
    return LearnerConfig(
        gamma=float(values.get('gamma', config.gamma)),
        alpha=Schedule.fixed(values['alpha']) if 'alpha' in values else config.alpha,
        epsilon=epsilon,
        initial_value=float(values.get('initial_value', config.initial_value)),
        n_planning=n_planning,
        theta=float(values.get('theta', config.theta)),
    )


def prior_of(learner: str, params=()) -> str:
    """The prior a run's table starts from (PRIOR_PARAMETER in ``params``, else the learner's
    default); ValueError naming a value that is not one of floor_plan_prior.PRIORS."""
    default = 'floor_plan' if canonical_learner_name(learner) in OPTIMISTIC else 'none'
    value = dict(params).get(PRIOR_PARAMETER, default)
    if value not in PRIORS:
        raise ValueError(f'{PRIOR_PARAMETER}: expected one of {", ".join(PRIORS)}, got {value!r}')
    return value


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
    params: tuple = ()  # (name, value) pairs: PARAMETERS over tuned_config, CRITERION_PARAMETERS
    # Stop training once STREAK evaluations in a row met the criterion (first_streak): the
    # learning cost is then known, and the rest of the budget would only add to the wall time.
    stop_at_streak: bool = False

    def __post_init__(self):
        # The command lines check these; a script that builds a RunSpec gets the same line.
        if self.episodes < 1 or self.eval_every < 1:
            raise ValueError(
                f'RunSpec: episodes and eval_every must be >= 1, got episodes {self.episodes}, '
                f'eval_every {self.eval_every}'
            )
        if not 0.0 <= self.slip <= 1.0:
            raise ValueError(f'RunSpec: slip must be a probability in [0, 1], got {self.slip}')

    @property
    def criterion(self) -> Criterion:
        """What a greedy evaluation must meet: the defaults, or the options in params
        (CriterionError naming one out of range)."""
        return Criterion(**{k: v for k, v in self.params if k in CRITERION_PARAMETERS})


def criterion_params(criterion: Criterion) -> tuple:
    """The (name, value) pairs of RunSpec.params that ask for ``criterion``: none for the
    default one (so a default run's trial id is what it was)."""
    return tuple(
        (name, getattr(criterion, name))
        for name in CRITERION_PARAMETERS
        if getattr(criterion, name) != getattr(DEFAULT_CRITERION, name)
    )


def grid_specs(
    scenarios,
    learners,
    seeds,
    *,
    episodes: int | None = None,
    eval_every: int = DEFAULT_EVAL_EVERY,
    slip: float = 0.0,
    goal: str | None = None,
    policy_dir: str | None = None,
    criterion: Criterion = DEFAULT_CRITERION,
) -> list[RunSpec]:
    """Every scenario x learner x seed as a RunSpec (episodes None: each learner's budget)."""
    return [
        RunSpec(
            scenario,
            learner,
            seed,
            episodes or default_budget(learner, scenario),
            eval_every,
            slip,
            goal,
            policy_dir,
            criterion_params(criterion),
        )
        for scenario in scenarios
        for learner in learners
        for seed in seeds
    ]


@dataclasses.dataclass(frozen=True)
class LearningCost:
    """What learning cost a run until it met the criterion STREAK times in a row (None fields
    when it never did in its budget): training episodes, the detections among them, their
    environment steps and their wall time (s, with the greedy evaluations after them)."""

    episodes: int | None
    detections: int | None
    steps: int | None
    seconds: float | None

    @property
    def met(self) -> bool:
        return self.episodes is not None


@dataclasses.dataclass
class RunResult:
    spec: RunSpec
    optimum: float
    train_returns: np.ndarray  # (episodes,)
    train_outcomes: np.ndarray  # (episodes,) EpisodeOutcome values
    eval_at: np.ndarray  # episodes trained before each greedy evaluation
    eval_returns: np.ndarray  # mean greedy return at each
    episodes_to_criterion: int | None  # settled(eval_at, eval_met)
    final: dict  # the last greedy evaluation: EpisodeSummary's figures and the path
    seconds: float
    env_steps: int
    eval_met: np.ndarray | None = None  # (evaluations,) bool: each met the criterion
    optimum_scores: PathScores | None = None  # value iteration's path (no slip)
    train_steps: np.ndarray | None = None  # (episodes,) environment steps of each
    # (episodes,) wall time of each, with the greedy evaluation after it (if any)
    train_seconds: np.ndarray | None = None

    @property
    def episodes_to_within(self) -> int | None:
        """The former name of episodes_to_criterion (sweep_trials reads it)."""
        return self.episodes_to_criterion

    @property
    def episodes_to_streak(self) -> int | None:
        """Training episodes until the first of STREAK evaluations in a row that met the
        criterion (first_streak), or None."""
        if self.eval_met is None:
            return None
        return first_streak(self.eval_at, self.eval_met)

    @property
    def cost(self) -> LearningCost:
        """What learning cost until episodes_to_streak (module docstring)."""
        return learning_cost(
            self.episodes_to_streak, self.train_outcomes, self.train_steps, self.train_seconds
        )

    @property
    def detections(self) -> np.ndarray:
        """The cumulative count of training episodes that ended DETECTED, per episode: the
        regret curve of Qi et al. (observed captures against episodes)."""
        return np.cumsum(self.train_outcomes == int(EpisodeOutcome.DETECTED))


def default_budget(learner: str, scenario: str | None = None) -> int:
    """Training episodes per run of a learner (on a scenario: more where lights move)."""
    name = canonical_learner_name(learner)
    if scenario is not None and lattice_model(scenario).cycle_bins > 1:
        return MOVING_EPISODES[name]
    return DEFAULT_EPISODES[name]


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


def settled(eval_at, passed) -> int | None:
    """The first evaluation point from which every greedy evaluation passed, or None."""
    good = np.asarray(passed, dtype=bool)
    if good.size == 0 or not good[-1]:
        return None
    bad = np.flatnonzero(~good)
    return int(eval_at[0] if bad.size == 0 else eval_at[bad[-1] + 1])


def first_streak(eval_at, passed, streak: int = STREAK) -> int | None:
    """The evaluation point (episodes trained) of the first of the first ``streak``
    consecutive evaluations that passed, or None: a streak cut short by a failure or by the end
    of the run does not count."""
    if streak < 1:
        raise ValueError(f'streak must be at least 1, got {streak}')
    run = 0
    for k, good in enumerate(np.asarray(passed, dtype=bool)):
        run = run + 1 if good else 0
        if run == streak:
            return int(eval_at[k - streak + 1])
    return None


def learning_cost(episodes: int | None, outcomes, steps, seconds) -> LearningCost:
    """LearningCost of the first ``episodes`` training episodes (their outcomes, environment
    steps and wall times, one per episode); all None for ``episodes`` None."""
    if episodes is None:
        return LearningCost(None, None, None, None)
    if episodes > len(outcomes):
        raise ValueError(f'{episodes} episodes asked for, {len(outcomes)} trained')
    detected = np.asarray(outcomes[:episodes]) == int(EpisodeOutcome.DETECTED)
    return LearningCost(
        episodes,
        int(np.count_nonzero(detected)),
        None if steps is None else int(np.sum(steps[:episodes])),
        None if seconds is None else float(np.sum(seconds[:episodes])),
    )


def settled_within(eval_at, eval_returns, optimum: float, within: float = WITHIN) -> int | None:
    """The old return criterion (greedy return >= optimum - within * |optimum|, settled): only
    for runs that kept no scores (sweep_trials' ROS trials read it from the returns)."""
    return settled(eval_at, np.asarray(eval_returns) >= optimum - within * abs(optimum))


def run(spec: RunSpec) -> RunResult:
    """Train one learner on one scenario with one seed, evaluating greedily as it goes."""
    started = time.perf_counter()
    env = StealthNavEnv(spec.scenario, spec.goal, spec.slip)
    evaluator = StealthNavEnv(spec.scenario, spec.goal, spec.slip)
    optimum = value_iteration(env.model, slip=spec.slip).optimal_return
    reference = PathScores.of_path(optimum_path(env.model))
    criterion = spec.criterion
    config = configured(
        spec.learner, spec.slip > 0, spec.params, goal_reward=env.task.scenario.rewards.goal_reward
    )
    learner = make_learner(spec.learner, env.action_space.n, config)
    prior = (
        floor_plan_prior(env.model)
        if prior_of(spec.learner, spec.params) == 'floor_plan'
        else None
    )
    index = StateIndex()
    rng = np.random.default_rng(spec.seed)
    if isinstance(learner, LightModelLearner):  # it knows the floor plan, never the lights
        learner.attach(LightWorld(env.task.scenario, spec.goal), index, rng)
        prior = None
    agent = ProtocolAgent(learner, index, rng, prior=prior)
    greedy = ProtocolAgent(
        learner, index, np.random.default_rng([spec.seed, 1]), learning=False, prior=prior
    )
    rollouts = 1 if spec.slip == 0 else 10
    returns, outcomes, eval_at, eval_returns, eval_met = [], [], [], [], []
    episode_steps, episode_seconds = [], []
    final: dict = {}
    for episode in range(spec.episodes):
        began = time.perf_counter()
        result, info = play_episode(env, agent, seed=spec.seed if episode == 0 else None)
        returns.append(result.reward)
        outcomes.append(EpisodeOutcome[info['outcome']])
        episode_steps.append(result.actions)
        if (episode + 1) % spec.eval_every == 0 or episode + 1 == spec.episodes:
            tries = [_greedy_rollout(evaluator, greedy, spec.seed + k) for k in range(rollouts)]
            eval_at.append(episode + 1)
            eval_returns.append(float(np.mean([t['total_reward'] for t in tries])))
            scores = mean_scores([PathScores.of_summary(t) for t in tries])
            eval_met.append(meets_criterion(scores, reference, criterion))
            final = tries[0]
        episode_seconds.append(time.perf_counter() - began)
        if spec.stop_at_streak and eval_met and first_streak(eval_at, eval_met) is not None:
            break
    if spec.policy_dir:
        save_policy(
            policy_path(spec),
            learner,
            index,
            scenario={
                **parse_description(**env.task.description(spec.slip > 0)).identity(),
                **content_identity(env.task.scenario),  # what stealth rollout compares
            },
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
        settled(eval_at, eval_met),
        final,
        time.perf_counter() - started,
        int(sum(episode_steps)),
        np.array(eval_met, dtype=bool),
        reference,
        np.array(episode_steps, dtype=np.int64),
        np.array(episode_seconds),
    )


def _greedy_rollout(env: StealthNavEnv, greedy: ProtocolAgent, seed: int) -> dict:
    _, info = play_episode(env, greedy, seed=seed)
    summary = env.stats.summary(EpisodeOutcome[info['outcome']])
    return {**summary._asdict(), 'points': env.trajectory}


def policy_path(spec: RunSpec) -> Path:
    goal = f'-{spec.goal}' if spec.goal else ''
    name = f'{scenario_label(spec.scenario)}{goal}-{spec.learner}-seed{spec.seed}.npz'
    return Path(spec.policy_dir) / name


def scenario_argument(entry: str, base: Path) -> str:
    """A scenario as a trial takes it, wherever it runs (Ray starts trials in a directory of its
    own): a name (no '/', no .yaml) stays a name, looked up on the scenario search path; a path
    relative to ``base`` becomes absolute. The one rule of `experiments` and `stealth sweep`:
    ``base`` is the current directory on the command line, the sweep file's inside one."""
    path = Path(entry)
    if path.suffix not in ('.yaml', '.yml') and len(path.parts) == 1:
        return str(entry)
    return str((Path(base) / path).resolve())  # an absolute path stays itself


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


def sensed_baselines(scenario: str, goal: str | None = None, seed: int = 0) -> list[Baseline]:
    """The unknown-light baselines (SENSED_BASELINES): each played as one episode on the Gym
    env's sensed track, its summary as ``RunResult.final`` (value iteration with full knowledge
    stays the oracle: ``baselines``)."""
    found = []
    for name, unknown in SENSED_BASELINES.items():
        started = time.perf_counter()
        env = StealthNavEnv(scenario, goal, track='sensed')
        summary = play(env, SensedReplanner(env.model, unknown).act, seed=seed)
        summary['outcome'] = EpisodeOutcome(summary['outcome'])
        found.append(Baseline(name, summary, time.perf_counter() - started))
    return found
