"""The agent node's parameters (agent_node declares them), importable without rclpy: an
orchestrator checks parameter names against them before it starts the node. Here too what
their values must be, at startup and when set at runtime, and the learner settings they make.
"""

from collections.abc import Iterable, Mapping

from stealth_node_kit import rl_contract
from stealth_node_kit.param_table import Param

from .learners import LEARNER_NAMES, LearnerConfig, canonical_learner_name
from .policy_plugins import is_plugin, plugin_names
from .schedules import SCHEDULE_KINDS, Schedule

PARAMETERS = {
    'agent': Param(
        'qlearning',
        'Learner: qlearning (rl_agent qlearner), sarsa, dyna, prioritized (prioritized '
        'sweeping; also spelled prioritized_sweeping) or light-model (infers the lights; needs '
        'world_file); or a policy plugin (policy_plugins: '
        'generalist, from stealth_learn), greedy and not learning, its weights policy_file '
        "('' = the ones it ships), its input the environment's rl_env/observation.",
        read_only=True,
    ),
    'seed': Param(
        1,
        'Seed of the random generator (exploration, tie-breaking, Dyna planning).',
        bounds=(0, 2**31 - 1),
        read_only=True,
    ),
    'gamma': Param(0.99, 'Discount factor.', bounds=(0.0, 1.0)),
    'alpha': Param(0.3, 'Learning rate; the start of the alpha schedule.', bounds=(0.0, 1.0)),
    'epsilon': Param(
        0.1, 'Exploration rate of epsilon-greedy; the start of its schedule.', bounds=(0.0, 1.0)
    ),
    'initialvalue': Param(0.0, 'Initial Q value of every new state-action.', read_only=True),
    'n': Param(
        10,
        'Dyna-Q and prioritized sweeping: planning updates from the learned model per real step '
        '(prioritized sweeping makes fewer when its queue runs dry).',
        bounds=(0, 1_000_000),
    ),
    'theta': Param(
        0.01,
        'Prioritized sweeping: a state-action is queued for planning only when its expected '
        'update would change its value by more than this (reward units).',
        bounds=(0.0, 1e12),
    ),
    'epsilon_schedule': Param('constant', 'constant, linear or exponential (over episodes).'),
    'epsilon_final': Param(0.01, 'Epsilon the schedule decays to.', bounds=(0.0, 1.0)),
    'epsilon_decay_episodes': Param(
        1000.0,
        'Linear: episodes to reach epsilon_final; exponential: time constant (episodes); > 0.',
        bounds=(0.0, 1e12),
    ),
    'alpha_schedule': Param('constant', 'constant, linear or exponential (over episodes).'),
    'alpha_final': Param(0.05, 'Alpha the schedule decays to.', bounds=(0.0, 1.0)),
    'alpha_decay_episodes': Param(
        1000.0,
        'Linear: episodes to reach alpha_final; exponential: time constant (episodes); > 0.',
        bounds=(0.0, 1e12),
    ),
    'nstates': Param(
        0,
        'rl_agent --nstates: bins per state feature over the description ranges; '
        '0 = one table row per distinct state vector.',
        bounds=(0, 1_000_000_000),
        read_only=True,
    ),
    'state_resolution': Param(
        0.0,
        'Bin width of every state feature (state units, e.g. the map cell in m); '
        'overrides nstates; 0 = off.',
        bounds=(0.0, 1e12),
        read_only=True,
    ),
    'state_features': Param(
        0,
        "Key the table on the state's first this many features only; 0 = all. The "
        "environment's sensed track sends the full track's state first (x, y, any phase and "
        'heading), then thousands of sensed values no table can key on: stealth train sets this '
        "to the full state's length for environment.track sensed.",
        bounds=(0, 1_000_000),
        read_only=True,
    ),
    'policy_file': Param(
        '',
        "Policy file (.npz) to save to and load from; empty = none (a policy plugin's: its "
        'shipped weights).',
        read_only=True,
    ),
    'world_file': Param(
        '',
        'light-model: the scenario as the agent may know it, every light removed (a scenario '
        'YAML with lights: [] and the goal as default_goal; stealth train writes '
        'runs/<name>/world.yaml); required to learn with light-model, unused otherwise.',
        read_only=True,
    ),
    'pose_jitter': Param(
        0.15,
        "light-model: how far (m) the environment's judged pose may stand off its lattice node "
        '(the true pose stops a few cm off it: median 5 cm, at most 31 cm on floorplan-moving); '
        "a step's light is expected anywhere in its range over the node and that far around "
        'it, so a step near a beam edge may read dark once and lit once. 0 = on the node.',
        bounds=(0.0, 1.0),
        read_only=True,
    ),
    'plan_margin': Param(
        0.0,
        'light-model: plan a step as detected where a hypothesis lights it to (1 - plan_margin) '
        "x the detection threshold (through ROS one step's readings spread by a few per cent). "
        '0 = on the threshold; 0.1 measured through ROS: map1-moving met on 2 seeds of 3, '
        'lgfloor-moving slower with more timeouts (docs/running.md).',
        bounds=(0.0, 0.9),
        read_only=True,
    ),
    'grid_sha256': Param(
        '',
        "SHA-256 of the scenario's occupancy grid (stealth train sets it): saved with the "
        'policy, for stealth rollout to check it runs on the same map; empty = not saved.',
        read_only=True,
    ),
    'lights_sha256': Param(
        '',
        "SHA-256 of the scenario's lights (stealth train sets it): saved with the policy, for "
        'stealth rollout to check it runs under the same lights; empty = not saved.',
        read_only=True,
    ),
    'save_every': Param(
        100,
        'Save the policy every this many episodes (0 = only at shutdown).',
        bounds=(0, 2**31 - 1),
    ),
    'load_policy': Param(False, 'Resume learning from policy_file if it exists.', read_only=True),
    'first_episode': Param(
        0,
        "Number of the first episode this agent runs (a respawned or resumed run's next one); "
        "later numbers follow the environment's EpisodeSummary.",
        bounds=(0, 2**31 - 1),
        read_only=True,
    ),
    'evaluate': Param(
        False,
        'Greedy, no learning: run the policy in policy_file (rl_agent savedpolicy).',
        read_only=True,
    ),
    'log_every': Param(
        10, 'Log progress every this many episodes (0 = never).', bounds=(0, 2**31 - 1)
    ),
    'eval_every': Param(
        0,
        'Every this many episodes one greedy evaluation episode (epsilon 0, no learning, the '
        'schedules stand still): episodes eval_every-1, 2*eval_every-1, ...; 0 = never.',
        bounds=(0, 2**31 - 1),
    ),
    'episode_summary_topic': Param(
        rl_contract.EPISODE_SUMMARY,
        'stealth_interfaces/EpisodeSummary topic: how each episode ended (a TIMEOUT is '
        'learned as a truncation, an ABORTED episode not at all) and named outcomes in the '
        'progress log; optional, an rl_msgs environment without it gets terminal states '
        'only; empty = off.',
        read_only=True,
    ),
    'timeout_is_terminal': Param(
        False,
        "Learn a TIMEOUT episode's last state as terminal, as rl_agent does (biased: timing "
        'out looks cheap); false = bootstrap through the time limit.',
    ),
    'summary_wait': Param(
        5.0,
        'Seconds between warnings while a terminal state waits for its EpisodeSummary. It '
        'waits as long as a summary publisher (the environment) exists, so a late summary '
        'never changes what is learned; with none left it is learned as terminal.',
        bounds=(0.01, 3600.0),
        read_only=True,
    ),
}

# Learner settings that may change while running (applied to the live learner).
LIVE_LEARNER_PARAMETERS = {
    'gamma',
    'alpha',
    'epsilon',
    'n',
    'theta',
    'epsilon_schedule',
    'epsilon_final',
    'epsilon_decay_episodes',
    'alpha_schedule',
    'alpha_final',
    'alpha_decay_episodes',
}
STRING_CHOICES = {
    'epsilon_schedule': SCHEDULE_KINDS,
    'alpha_schedule': SCHEDULE_KINDS,
}


def learner_config(values: Mapping) -> LearnerConfig:
    """The learner settings of these parameter values; ValueError naming what is unusable."""
    return LearnerConfig(
        gamma=values['gamma'],
        alpha=Schedule(
            values['alpha_schedule'],
            values['alpha'],
            values['alpha_final'],
            values['alpha_decay_episodes'],
        ),
        epsilon=Schedule(
            values['epsilon_schedule'],
            values['epsilon'],
            values['epsilon_final'],
            values['epsilon_decay_episodes'],
        ),
        initial_value=values['initialvalue'],
        n_planning=values['n'],
        theta=values['theta'],
    )


def change_problem(changes: Iterable[tuple[str, object]], current: Mapping | None) -> str | None:
    """Why a change of parameters ((name, value) pairs) is refused, or None: each value on its
    own, then, when it touches the learner settings, the settings they make together with the
    `current` values (None while declaring: not every parameter exists yet, startup_problem
    checks the whole set after)."""
    values = {}
    for name, value in changes:
        if name == 'agent' and not is_plugin(value):
            try:
                canonical_learner_name(value)
            except ValueError:
                names = ', '.join((*LEARNER_NAMES, *plugin_names()))
                return f'unknown learner {value!r} (expected one of {names})'
        if name in STRING_CHOICES and value not in STRING_CHOICES[name]:
            choices = ', '.join(STRING_CHOICES[name])
            return f'{name} must be one of {choices}, got {value!r}'
        if name.endswith('_decay_episodes') and value <= 0:
            return f'{name} must be > 0, got {value}'
        values[name] = value
    if current is not None and LIVE_LEARNER_PARAMETERS & values.keys():
        try:
            learner_config({**current, **values})
        except ValueError as error:
            return str(error)
    return None


def startup_problem(values: Mapping) -> str | None:
    """Why the declared parameters cannot make a usable agent, or None."""
    plugin = is_plugin(values['agent'])
    if (values['evaluate'] or values['load_policy']) and not values['policy_file'] and not plugin:
        return 'evaluate and load_policy need policy_file'
    try:
        learner_config(values)
    except ValueError as error:
        return str(error)
    if learns(values) and is_light_model(values['agent']) and not values['world_file']:
        return (
            'agent light-model learns on the floor plan it is given: world_file is empty '
            '(stealth train --learner light-model writes runs/<name>/world.yaml; else --set '
            'agent.world_file=PATH, a scenario YAML with lights: [])'
        )
    return None


def is_light_model(name) -> bool:
    """Whether the agent parameter names the light model (any spelling)."""
    try:
        return canonical_learner_name(name) == 'light-model'
    except ValueError:
        return False


def learns(values: Mapping) -> bool:
    """Whether a run with these values learns: not evaluate, and a learner, not a policy."""
    return not values['evaluate'] and not is_plugin(values['agent'])
