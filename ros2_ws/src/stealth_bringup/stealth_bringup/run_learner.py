"""What the agent's learner asks of a training run, decided before anything starts: --learner,
the floor plan's prior for a table that explores by optimism (``prior_policy``), and for the
light model the law it must be able to model and the world file it is given instead of the
scenario (``stealth_core.world_file``). Every problem is a RunConfigError with one line to
print. No rclpy.
"""

from __future__ import annotations

from stealth_agent.agent_parameters import PARAMETERS as AGENT_PARAMETERS
from stealth_agent.learners import OPTIMISTIC, canonical_learner_name
from stealth_agent.policy_plugins import is_plugin
from stealth_core.light_world import UnmodelledLawError, check_modelled

from stealth_bringup.run_config import RunConfigError


def run_prior(requested: str | None, continued, parameters: dict) -> str:
    """The prior a training run's table starts from: the one asked for (RunConfigError where it
    cannot apply), else floor_plan where a new table of a learner that explores by optimism
    takes it, as in the harness, and none otherwise."""
    if requested is not None:
        if requested != 'none':
            _check_prior(continued, parameters)
        return requested
    if table_learner(parameters) not in OPTIMISTIC:
        return 'none'
    try:
        _check_prior(continued, parameters)
    except RunConfigError:
        return 'none'
    return 'floor_plan'


def agent_value(parameters: dict, name: str):
    """An agent node parameter as the node will run with it: its file's, else its default."""
    return parameters['agent'].values.get(name, AGENT_PARAMETERS[name].default)


def table_learner(parameters: dict) -> str | None:
    """The agent's learner (a LEARNER_NAMES name); None for a policy plugin or a name the agent
    node will refuse itself."""
    try:
        return canonical_learner_name(agent_value(parameters, 'agent'))
    except ValueError:
        return None


def exploration_notes(parameters: dict) -> list[str]:
    """A note where a learner that does not explore by optimism runs with agent.yaml's
    epsilon 0 (set for prioritized sweeping)."""
    name = table_learner(parameters)
    planner = name in OPTIMISTIC or name == 'light-model'  # it explores by its plan
    if name is None or planner or agent_value(parameters, 'epsilon') != 0.0:
        return []
    return [
        f'agent {name} with epsilon 0 tries only what its initial values make look better than '
        'what it found (prioritized sweeping alone explores by optimism); --set '
        'agent.epsilon=0.2 to explore at random'
    ]


def _check_prior(continued, parameters: dict) -> None:
    """RunConfigError where --prior cannot apply: a resumed table, a plugin, the sensed track."""
    learner = agent_value(parameters, 'agent')
    if continued is not None:
        raise RunConfigError("--prior: not with --resume (the run's table goes on)")
    if table_learner(parameters) == 'light-model':
        raise RunConfigError(
            '--prior: light-model plans on the floor plan itself (every unknown place dark '
            'until a step says otherwise); give --prior none or no --prior'
        )
    if is_plugin(learner):
        raise RunConfigError(f'--prior: agent {learner!r} keeps no table')
    if parameters['environment'].values.get('track', 'full') != 'full':
        raise RunConfigError(
            '--prior: the full track only (on the sensed track the state holds what was sensed)'
        )


def asked_learner(name: str, overrides: dict) -> str:
    """--learner's learner (a LEARNER_NAMES name); RunConfigError for an unknown one or one
    --set agent.agent contradicts."""
    try:
        learner = canonical_learner_name(name)
    except ValueError as error:
        raise RunConfigError(f'--learner: {error}') from None
    if 'agent' in overrides.get('agent', {}):
        raise RunConfigError('--learner with --set agent.agent=...: give the learner once')
    return learner


def check_modelled_scenario(scenario) -> None:
    """RunConfigError (the one line) for a scenario whose light law light-model cannot model."""
    try:
        check_modelled(scenario)
    except UnmodelledLawError as error:
        raise RunConfigError(str(error)) from None
