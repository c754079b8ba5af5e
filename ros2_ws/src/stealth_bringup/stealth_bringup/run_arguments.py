"""The command lines of `stealth train` and `stealth rollout` (argparse) and their defaults: what
a user can ask for, checked for form only; what it means is run_plan's. No rclpy.
"""

from __future__ import annotations

import argparse
import dataclasses

from stealth_core.floor_plan_prior import PRIORS
from stealth_core.path_scores import (
    DEFAULT_CRITERION,
    OPTION_FLAGS,
    OPTION_RANGES,
    Criterion,
    CriterionError,
    check_option,
)
from stealth_tools.commands.arguments import (
    non_negative_int,
    positive_float,
    positive_int,
)

from stealth_bringup.ros_domain import DISCOVERY_RANGES

DEFAULT_SCENARIO = 'simple-maze'
DEFAULT_GOAL = 'easy'  # of the default scenario; other scenarios default to their own goal
DEFAULT_EPISODES = 400  # the least; the scenario's state count sets more (episode_budget)
DEFAULT_EVAL_EVERY = 5
DEFAULT_STREAK = 3
DEFAULT_RESPAWN = 3  # restarts per node in stealth train (stealth rollout: 0)
DEFAULT_EVAL_EPISODES = 5
STARTUP_TIMEOUT = 60.0  # s for every node to appear on the graph
STALL_TIMEOUT = 120.0  # s without a step before the run is declared stuck
JOIN_TIMEOUT = 300.0  # s for a --remote node to join: someone has to start it on another host
# The recorder writes into the run directory, so it runs here.
REMOTE_NODES = ('simulator', 'environment', 'agent')
# The command that runs each mode: mode 'eval' (summary.json's "mode") is `stealth rollout`.
COMMAND_OF_MODE = {'train': 'train', 'eval': 'rollout'}


def prog_of(mode: str) -> str:
    """The name a mode's lines start with: `stealth train` or `stealth rollout`."""
    return f'stealth {COMMAND_OF_MODE[mode]}'


def criterion_option(name: str, low: float, high: float):
    """The argparse type of a criterion option: a number in [low, high], else the error line
    naming the range (argparse adds the option's name)."""

    def parse(text: str) -> float:
        try:
            return check_option(name, text, low, high)
        except CriterionError as error:
            raise argparse.ArgumentTypeError(str(error).split(': ', 1)[1]) from None

    return parse


# The criterion's options: (field of Criterion, metavar, what the option bounds); their ranges
# and flags are path_scores'.
CRITERION_OPTIONS = (
    (
        'max_path_ratio',
        'R',
        "a greedy path on the lattice at most R times as long as value iteration's optimum",
    ),
    (
        'exposure_tolerance',
        'E',
        "the greedy path's accumulated exposure (visibility summed over its steps) at most "
        "the optimum's + E",
    ),
)


def add_criterion_options(parser: argparse.ArgumentParser, resumable: bool = False) -> None:
    """--max-path-ratio, --exposure-tolerance: the success criterion (stealth_core.path_scores)
    greedy episodes are judged by (stealth train's streak counts them, the harness settles on
    them); None when not given (``criterion_of``: the defaults; --resume: the run's)."""
    resumed = ", with --resume the run's" if resumable else ''
    for name, metavar, bound in CRITERION_OPTIONS:
        low, high = OPTION_RANGES[name]
        parser.add_argument(
            OPTION_FLAGS[name],
            type=criterion_option(name, low, high),
            metavar=metavar,
            help=f'success criterion: {bound} ([{low:g}, {high:g}]; default: '
            f'{getattr(DEFAULT_CRITERION, name):g}{resumed})',
        )


def criterion_of(args: argparse.Namespace) -> Criterion:
    """The criterion the options ask for: each given option over the defaults."""
    given = {
        name: getattr(args, name)
        for name, *_ in CRITERION_OPTIONS
        if getattr(args, name, None) is not None
    }
    return dataclasses.replace(DEFAULT_CRITERION, **given)


def _common_options(parser: argparse.ArgumentParser, evaluating: bool = False) -> None:
    add_criterion_options(parser, resumable=not evaluating)
    parser.add_argument(
        '--runs-dir',
        default='runs',
        metavar='DIR',
        help='where run directories go (default: %(default)s)'
        + ('; with --run the evaluation goes into the run directory' if evaluating else ''),
    )
    parser.add_argument(
        '--name',
        metavar='RUN',
        help='name of the new directory (default: '
        + ('eval-<UTC time> in the run, else eval-<scenario>-<goal>-<UTC time>)'
           if evaluating else '<scenario>-<goal>-<UTC time>)'),
    )  # fmt: skip
    parser.add_argument(
        '--seed',
        type=non_negative_int,
        metavar='S',
        help='seed of the simulator, the environment and the agent (default: their files)',
    )
    parser.add_argument(
        '--params-dir',
        metavar='DIR',
        help='take <node>.yaml (recorder, simulator, environment, agent) from DIR where it '
        'exists instead of the installed defaults (share/stealth_bringup/config)'
        + ("; default with --run: the run's params/" if evaluating else ''),
    )
    parser.add_argument(
        '--set',
        dest='overrides',
        action='append',
        default=[],
        metavar='NODE.PARAM=VALUE',
        help='override one parameter, e.g. --set agent.epsilon=0.2 (repeatable; values as '
        'in -p name:=value)',
    )
    parser.add_argument('--no-record', action='store_true', help='do not start the recorder')
    parser.add_argument(
        '--compose',
        action='store_true',
        help='run the simulator and the environment in one process (stealth_bringup sim_env), '
        'the environment calling the simulator directly: the same episodes, 1.2-1.6x the '
        "steps per second of a training run (2x the bare RL loop's); the same topics and "
        'services for everyone else (not with '
        '--watch, or with the simulator or the environment --remote or replaced by --executable)',
    )
    parser.add_argument(
        '--watch',
        action='store_true',
        help='simulate in real time (simulator real_time_factor 1, publish_rate 10) and serve '
        'the run to the Foxglove app: connect to ws://localhost:8765 (the bridge node; '
        '--set bridge.port=N for another port)',
    )
    parser.add_argument(
        '--startup-timeout',
        type=positive_float,
        default=STARTUP_TIMEOUT,
        metavar='S',
        help='seconds for every node to come up (default: %(default)s)',
    )
    parser.add_argument(
        '--stall-timeout',
        type=positive_float,
        default=STALL_TIMEOUT,
        metavar='S',
        help='give up when no step happens for S seconds (default: %(default)s)',
    )
    parser.add_argument(
        '--executable',
        action='append',
        default=[],
        metavar='NODE=PATH',
        help='run PATH instead of the installed node (e.g. your own rl_msgs agent)',
    )
    parser.add_argument(
        '--discovery',
        choices=tuple(DISCOVERY_RANGES),
        default='localhost',
        help='where the nodes of the run find each other (ROS_AUTOMATIC_DISCOVERY_RANGE): '
        'localhost, or subnet for nodes on other hosts (--remote) (default: %(default)s)',
    )
    parser.add_argument(
        '--remote',
        action='append',
        default=[],
        choices=REMOTE_NODES,
        metavar='NODE',
        help=f'do not start NODE ({", ".join(REMOTE_NODES)}) here: print the command that '
        'starts it on another host, wait for it to join the run, then supervise it through the '
        'ROS graph (repeatable; with --discovery subnet for another host)',
    )
    parser.add_argument(
        '--respawn',
        type=non_negative_int,
        default=0 if evaluating else DEFAULT_RESPAWN,
        metavar='N',
        help='restart a node that dies up to N times (each after a longer wait: 0.5, 1, 2, 4, '
        '8 s), in the same domain with the same parameters; the agent resumes from its '
        'checkpoint, the episode in progress counts as ABORTED (0 = a dead node ends the run; '
        'default: %(default)s)',
    )
    parser.add_argument(
        '--join-timeout',
        type=positive_float,
        default=JOIN_TIMEOUT,
        metavar='S',
        help='seconds a --remote node has to join the run (default: %(default)s)',
    )


def train_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='stealth train',
        description='Train the agent on a scenario: start simulator, environment, agent and '
        "recorder as separate processes (--compose: the simulator in the environment's) in a "
        'private ROS domain, show progress, stop on the '
        'episode budget or when the greedy policy met the success criterion K evaluations in a '
        "row (reached the goal undetected, its path and exposure close to the optimum's), "
        'and leave runs/<name>/ with the recording, parameters, policy, summary and plots.',
    )
    parser.add_argument(
        '--scenario',
        metavar='NAME|PATH',
        help=f'scenario name (scenarios/) or YAML path (default: {DEFAULT_SCENARIO})',
    )
    parser.add_argument(
        '--goal',
        help=f'goal: easy, medium or hard (default: {DEFAULT_GOAL} for {DEFAULT_SCENARIO}, '
        "else the scenario's default_goal)",
    )
    parser.add_argument(
        '--episodes',
        type=positive_int,
        metavar='N',
        help='episode budget, greedy evaluations included (default: one per 6 of the '
        "scenario's state-actions, at least "
        f'{DEFAULT_EPISODES}: {DEFAULT_EPISODES} on simple-maze, 4000 on simple-maze-moving); '
        "with --resume the new total, the run's earlier episodes included (default: the run's "
        'budget)',
    )
    parser.add_argument(
        '--eval-every',
        type=non_negative_int,
        metavar='M',
        help='every M-th episode is a greedy evaluation, no exploration and no learning '
        f"(0 = never; default: {DEFAULT_EVAL_EVERY}, with --resume the run's)",
    )
    parser.add_argument(
        '--success-streak',
        type=non_negative_int,
        metavar='K',
        help='stop once K greedy evaluations in a row met the success criterion (reached the '
        'goal undetected, --max-path-ratio, --exposure-tolerance) (0 = run the whole '
        f"budget; default: {DEFAULT_STREAK}, with --resume the run's)",
    )
    parser.add_argument(
        '--resume',
        metavar='RUN',
        help='continue the training run in directory RUN (stopped, crashed or finished): its '
        'scenario, goal, parameters (RUN/params/, or --params-dir) and settings unless given '
        'here, the agent from RUN/policy.npz, the episode numbers, episodes.csv and the streak '
        'where they were; appends to episodes.csv and summary.json, redraws the plots and '
        'records into the next RUN/recording_<n>.mcap',
    )
    parser.add_argument(
        '--prior',
        choices=PRIORS,
        help="where the agent's table starts: floor_plan, every state-action at what the floor "
        'plan says it is worth with the lights dark (an upper bound: optimism that spares the '
        "moves leading away from the goal); none, the agent's initialvalue. Default: "
        'floor_plan where a new table of prioritized sweeping (the default learner) can take '
        'it, none otherwise (--resume, another learner, a plugin, the sensed track)',
    )
    parser.add_argument(
        '--learner',
        metavar='NAME',
        help="the agent's learner: qlearning, sarsa, dyna, prioritized or light-model (infers "
        'the searchlights from its rewards; static lights, threshold detection; the agent is '
        "given the scenario without its lights, RUN/world.yaml) (default: agent.yaml's, "
        "prioritized; with --resume the run's)",
    )
    _common_options(parser)
    return parser


def rollout_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='stealth rollout',
        description="Run a saved policy's greedy episodes through ROS, without learning (agent "
        'evaluate), on its scenario and record them: runs/<run>/eval-<time>/ for --run, else a '
        'new run directory.',
    )
    source = parser.add_mutually_exclusive_group()
    source.add_argument('--run', metavar='DIR', help='a training run directory (runs/<name>)')
    source.add_argument(
        '--policy',
        metavar='FILE',
        help="a policy file (.npz; with --learner: the plugin's weights)",
    )
    parser.add_argument(
        '--learner',
        metavar='NAME',
        help='a policy plugin instead of a saved table (stealth_agent.policy_plugins: '
        'generalist, the lights-known generalist, needs make learn) on any --scenario its '
        'weights can play: static lights with the shipped ones, moving lights with the '
        'time-aware generalist-moving.npz; its weights --policy (default: the static ones it '
        'ships); the environment sends it the grid observation (observation_layout grid)',
    )
    parser.add_argument(
        '--scenario',
        metavar='NAME|PATH',
        help="scenario (default: the run's, or the one named in the policy file)",
    )
    parser.add_argument('--goal', help="goal (default: the run's or the policy file's)")
    parser.add_argument(
        '--episodes',
        type=positive_int,
        default=DEFAULT_EVAL_EPISODES,
        metavar='N',
        help='episodes to run (default: %(default)s)',
    )
    _common_options(parser, evaluating=True)
    return parser


def check_rollout_source(parser, args) -> None:
    """One of --run, --policy, --learner (argparse's group cannot say 'or --learner'); exits
    2 with parser.error otherwise."""
    if args.run is None and args.policy is None and args.learner is None:
        parser.error('one of the arguments --run --policy --learner is required')
    if args.learner is not None and args.run is not None:
        parser.error('argument --learner: not allowed with argument --run')
