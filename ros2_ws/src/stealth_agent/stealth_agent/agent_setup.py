"""The agent's core for an environment, built from the agent's parameters (no rclpy).

A fresh table, or the one in the policy file (evaluate, load_policy) once it is checked against
the environment, or a policy plugin's policy (``agent: generalist``: ``policy_plugins``, greedy,
no table); the seeded random generator (a resumed learning run continues the file's
random stream); and the log line saying what was built, so that a run's log tells how it
started. An unusable policy file leaves the agent without a core: it must not act, nor
overwrite the file. The light model (``light-model``) learning is attached to the world of its
``world_file`` (the scenario without its lights, ``stealth_core.world_file``), checked to be the
environment's lattice; any problem with it leaves the agent without a core too.
"""

from collections.abc import Mapping
from dataclasses import dataclass
import pathlib

import numpy as np
from stealth_core.light_belief import BeliefSettings
from stealth_core.light_world import UnmodelledLawError
from stealth_core.world_file import WorldFileError, load_world

from .agent_parameters import learner_config
from .grid_agent import GridPolicyAgent
from .learners import canonical_learner_name, make_learner
from .light_model import LightModelError, LightModelLearner
from .policy_plugins import PluginError, is_plugin
from .policy_plugins import load_policy as load_plugin_policy
from .policy_store import PolicyFileError, check_compatible, load_policy
from .protocol import EnvDescription, ProtocolAgent, parse_description
from .state_index import StateIndex, mapping_from_description


@dataclass(frozen=True)
class AgentSetup:
    """What set_up_agent built, and what to log about it (the warnings first)."""

    core: ProtocolAgent | None  # None: the agent is not usable, `error` says why
    warnings: tuple[str, ...] = ()
    error: str = ''
    summary: str = ''  # the line that says what was built


def set_up_agent(description: EnvDescription, values: Mapping) -> AgentSetup:
    """The core for this environment from the parameter values (agent_parameters)."""
    mapping, warnings = mapping_from_description(
        description.min_state_range,
        description.max_state_range,
        nstates=values['nstates'],
        resolution=values['state_resolution'],
    )
    warnings = list(warnings)
    if is_plugin(values['agent']):
        return _plugin_agent(description, values, StateIndex(mapping), tuple(warnings))
    learner_name = canonical_learner_name(values['agent'])
    evaluate = values['evaluate']
    path = pathlib.Path(values['policy_file']) if values['policy_file'] else None
    seed = values['seed']
    rng = np.random.default_rng(seed)
    source = 'a fresh table'
    policy = None
    if evaluate or values['load_policy']:
        if not path.exists() and not evaluate:
            warnings.append(f'no policy file at {path} yet; starting with a fresh table')
        else:
            try:
                policy = load_policy(path)
                check_compatible(
                    policy,
                    num_actions=description.num_actions,
                    state_dim=mapping.dim,
                    learner=None if evaluate else learner_name,
                    scenario_title=description.title,
                    mapping=mapping,
                )
            except PolicyFileError as error:
                return AgentSetup(None, tuple(warnings), error=str(error))
    if policy is not None:
        learner, index = policy.learner, policy.index
        source = f'{path} ({learner.episodes} episodes, {len(index)} states)'
        if not evaluate:
            learner.set_config(learner_config(values))
            saved_rng = policy.restored_rng()
            if saved_rng is not None:
                rng = saved_rng
                source += ', continuing its random stream'
    else:
        learner = make_learner(learner_name, description.num_actions, learner_config(values))
        index = StateIndex(mapping)
    if isinstance(learner, LightModelLearner) and not evaluate:
        settings = BeliefSettings(pose_jitter=values['pose_jitter'])
        problem = attach_world(
            learner, index, rng, values['world_file'], description, settings, values['plan_margin']
        )
        if problem is not None:
            return AgentSetup(None, tuple(warnings), error=problem)
        source += f'; the world of {values["world_file"]} (no lights)'
    core = ProtocolAgent(learner, index, rng, learning=not evaluate)
    core.episode = values['first_episode']
    config = learner.config
    if evaluate:
        settings = f'greedy, ties broken with seed {seed}'
    elif isinstance(learner, LightModelLearner):  # it plans: no alpha, epsilon, n
        jitter = learner.belief.settings.pose_jitter
        settings = (
            f'gamma {config.gamma}, planning rule {learner.rule}, pose jitter {jitter:g} m, '
            f'plan margin {learner.plan_margin:g}, seed {seed}'
        )
    else:
        settings = (
            f'gamma {config.gamma}, alpha {learner.alpha} ({config.alpha.kind}), '
            f'epsilon {learner.epsilon} ({config.epsilon.kind}), '
            f'initial {config.initial_value}, n {config.n_planning}, '
            + (f'theta {config.theta}, ' if learner.name == 'prioritized' else '')
            + f'seed {seed}'
        )
    summary = (
        f'environment {description.title!r}: {description.num_actions} actions, state '
        f'ranges {list(description.min_state_range)}..{list(description.max_state_range)}; '
        f'learner {learner.name} ({settings}); states {index.mapping.describe()}; '
        f'from {source}; ' + ('evaluating (no learning)' if evaluate else 'learning')
    )
    return AgentSetup(core, tuple(warnings), summary=summary)


def attach_world(
    learner: LightModelLearner, index, rng, path: str, description, settings=None, margin=0.0
) -> str | None:
    """Attach the light model to the world of the file at ``path`` (the scenario without its
    lights), its belief searching by ``settings`` (BeliefSettings), planning with ``margin``
    (``LightModelLearner.attach``'s plan_margin): None, or the one line
    saying why it cannot be (unreadable, lights in it, a law it does not model, another
    lattice than the environment's)."""
    try:
        world = load_world(path)
    except (WorldFileError, UnmodelledLawError) as error:
        return str(error)
    problem = world_mismatch(world, description)
    if problem is not None:
        return f'world_file {path}: {problem}'
    try:
        learner.attach(world, index, rng, settings=settings, plan_margin=margin)
    except LightModelError as error:
        return f'world_file {path}: {error}'
    return None


def world_mismatch(world, description: EnvDescription) -> str | None:
    """What makes the world's lattice another environment than the one described (title,
    actions, states, state ranges), or None."""
    expected = parse_description(**world.task.description(False))
    for name in ('title', 'num_actions', 'num_states'):
        mine, theirs = getattr(expected, name), getattr(description, name)
        if mine != theirs:
            return f'its {name} is {mine!r}, the environment says {theirs!r}'
    for name in ('min_state_range', 'max_state_range'):
        mine, theirs = getattr(expected, name), getattr(description, name)
        # RLEnvDescription carries float32: equal to that precision
        if len(mine) != len(theirs) or not np.allclose(mine, theirs, rtol=1e-6, atol=1e-5):
            return f'its {name} is {list(mine)}, the environment says {list(theirs)}'
    return None


def _plugin_agent(description: EnvDescription, values: Mapping, index, warnings) -> AgentSetup:
    """A policy plugin's greedy agent, its weights from policy_file ('' the plugin's own)."""
    name, path = values['agent'], values['policy_file']
    try:
        policy = load_plugin_policy(name, path)
    except PluginError as error:
        return AgentSetup(None, warnings, error=str(error))
    if description.num_actions < 4:
        return AgentSetup(None, warnings, error=f'policy {name} moves up, down, left and right: '
                          f'the environment has {description.num_actions} actions')  # fmt: skip
    core = GridPolicyAgent(name, policy, index, np.random.default_rng(values['seed']))
    core.episode = values['first_episode']
    summary = (
        f'environment {description.title!r}: {description.num_actions} actions; policy {name} '
        f'(plugin, layout {policy.layout}) from {path or "its shipped weights"}; evaluating '
        '(no learning); its decisions need the grid on rl_env/observation (environment '
        'observation_layout grid)'
    )
    return AgentSetup(core, warnings, summary=summary)
