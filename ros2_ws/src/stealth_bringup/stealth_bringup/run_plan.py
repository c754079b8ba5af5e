"""What `stealth train` and `stealth eval` are asked to do, checked before anything starts: the
command lines, the scenario and goal, the parameter files and --set, the executables, the policy
to evaluate, and the run directory laid out with every node's effective parameters (RunPlan).
Every problem is a RunConfigError with one line to print. No rclpy.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import contextlib
import dataclasses
import errno
import json
import math
import os
from pathlib import Path
import re
import shlex

from stealth_tools.bag_files import next_recording_file

from stealth_bringup.ros_domain import DISCOVERY_RANGES
from stealth_bringup.run_config import (
    NODE_ORDER,
    NODES,
    ROS_OWN_PARAMETERS,
    NodeParameters,
    RunConfigError,
    check_managed,
    check_parameter_names,
    effective_parameters,
    file_sha256,
    params_sources,
    parse_set,
    read_params_file,
    relative_to_cwd,
    run_directory,
    scenario_parameters,
    utc_stamp,
    write_params_file,
)

DEFAULT_SCENARIO = 'simple-maze'
DEFAULT_GOAL = 'easy'  # of the default scenario; other scenarios default to their own goal
DEFAULT_EPISODES = 400
DEFAULT_EVAL_EVERY = 5
DEFAULT_STREAK = 3
DEFAULT_RESPAWN = 3  # restarts per node in stealth train (stealth eval: 0)
DEFAULT_EVAL_EPISODES = 5
STARTUP_TIMEOUT = 60.0  # s for every node to appear on the graph
STALL_TIMEOUT = 120.0  # s without a step before the run is declared stuck
WATCH_PUBLISH_RATE = 10.0  # Hz of odom, ground_truth, scan, clock under --watch
# environment.robot_interface topics (issue 13): the environment drives the simulator over
# cmd_vel/odom, one control step per odom message, so simulated time must flow between moves:
# 20x wall time in ticks of 10 ms (0.2 s simulated, the control period), one odom per tick.
TOPICS_SIMULATOR = {'real_time_factor': 20.0, 'idle_period': 0.01, 'publish_rate': 5.0}
JOIN_TIMEOUT = 300.0  # s for a --remote node to join: someone has to start it on another host
# The recorder writes into the run directory, so it runs here.
REMOTE_NODES = ('simulator', 'environment', 'agent')
# --compose: these two nodes in one process, the second's (sim_env), under the second's name.
COMPOSED = ('simulator', 'environment')
COMPOSED_TEXT = 'the simulator and the environment'
SIM_ENV = ('stealth_bringup', 'sim_env')

# --- command line -------------------------------------------------------------------------------


def _whole_number(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a whole number') from None


def _positive_int(text: str) -> int:
    value = _whole_number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text} is not a positive integer')
    return value


def _non_negative_int(text: str) -> int:
    value = _whole_number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'{text} is negative')
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number') from None
    if not value > 0 or not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'{text} is not a positive number')
    return value


def _common_options(parser: argparse.ArgumentParser, evaluating: bool = False) -> None:
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
        type=_non_negative_int,
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
        type=_positive_float,
        default=STARTUP_TIMEOUT,
        metavar='S',
        help='seconds for every node to come up (default: %(default)s)',
    )
    parser.add_argument(
        '--stall-timeout',
        type=_positive_float,
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
        type=_non_negative_int,
        default=0 if evaluating else DEFAULT_RESPAWN,
        metavar='N',
        help='restart a node that dies up to N times (each after a longer wait: 0.5, 1, 2, 4, '
        '8 s), in the same domain with the same parameters; the agent resumes from its '
        'checkpoint, the episode in progress counts as ABORTED (0 = a dead node ends the run; '
        'default: %(default)s)',
    )
    parser.add_argument(
        '--join-timeout',
        type=_positive_float,
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
        'episode budget or when the greedy policy reached the goal K evaluations in a row, '
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
        type=_positive_int,
        metavar='N',
        help='episode budget, greedy evaluations included (default: '
        f"{DEFAULT_EPISODES}); with --resume the new total, the run's earlier episodes "
        "included (default: the run's budget)",
    )
    parser.add_argument(
        '--eval-every',
        type=_non_negative_int,
        metavar='M',
        help='every M-th episode is a greedy evaluation, no exploration and no learning '
        f"(0 = never; default: {DEFAULT_EVAL_EVERY}, with --resume the run's)",
    )
    parser.add_argument(
        '--success-streak',
        type=_non_negative_int,
        metavar='K',
        help='stop once K greedy evaluations in a row reached the goal (0 = run the whole '
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
    _common_options(parser)
    return parser


def eval_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='stealth eval',
        description='Run a saved policy greedily, without learning (agent evaluate), on its '
        'scenario and record it: runs/<run>/eval-<time>/ for --run, else a new run directory.',
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument('--run', metavar='DIR', help='a training run directory (runs/<name>)')
    source.add_argument('--policy', metavar='FILE', help='a policy file (.npz)')
    parser.add_argument(
        '--scenario',
        metavar='NAME|PATH',
        help="scenario (default: the run's, or the one named in the policy file)",
    )
    parser.add_argument('--goal', help="goal (default: the run's or the policy file's)")
    parser.add_argument(
        '--episodes',
        type=_positive_int,
        default=DEFAULT_EVAL_EPISODES,
        metavar='N',
        help='episodes to run (default: %(default)s)',
    )
    _common_options(parser, evaluating=True)
    return parser


# --- input checks (nothing has started yet) ----------------------------------------------------


def _defaults_dir() -> Path:
    """share/stealth_bringup/config of the install space (or the source tree's config/)."""
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    with contextlib.suppress(PackageNotFoundError):
        installed = Path(get_package_share_directory('stealth_bringup')) / 'config'
        if installed.is_dir():
            return installed
    return Path(__file__).resolve().parent.parent / 'config'


def _load_scenario(name: str):
    from stealth_env.scenario import ScenarioError, load_scenario

    try:
        return load_scenario(name)
    except ScenarioError as error:
        raise RunConfigError(str(error)) from None
    except OSError as error:
        raise RunConfigError(f'scenario {name!r}: {error}') from None


def _check_goal(scenario, goal: str | None, default: str | None = None) -> str:
    goal = goal or default or scenario.default_goal
    if goal not in scenario.goals:
        raise RunConfigError(
            f'--goal {goal!r}: scenario {scenario.name!r} has no such goal '
            f'(it has: {", ".join(scenario.goals)})'
        )
    return goal


def _composed(commands: dict[str, list[str]], args) -> dict[str, list[str]]:
    """--compose: the environment's process is sim_env, which runs the simulator too (and there
    is no simulator process); RunConfigError where that cannot be."""
    from stealth_tools.executables import ExecutableNotFoundError, find_executable

    if args.watch:
        raise RunConfigError(
            '--compose with --watch: the simulator paced to real time would hold the '
            "environment's searchlights for each move; watch without --compose"
        )
    for node in COMPOSED:
        if node in args.remote:
            raise RunConfigError(f'--compose with --remote {node}: {COMPOSED_TEXT} are one '
                                 'process; drop one of the two')  # fmt: skip
        if any(item.partition('=')[0] == node for item in args.executable):
            raise RunConfigError(f'--compose with --executable {node}=...: {COMPOSED_TEXT} run '
                                 'as the installed nodes; drop one of the two')  # fmt: skip
    try:
        container = str(find_executable(*SIM_ENV))
    except ExecutableNotFoundError as error:
        raise RunConfigError(
            f'--compose: {error}; build the workspace (make setup) and source scripts/ros_env.sh'
        ) from None
    commands = dict(commands)
    del commands['simulator']
    commands['environment'] = [container]
    return commands


def _executables(
    nodes: list[str], replacements: list[str], remote: tuple[str, ...]
) -> dict[str, list[str]]:
    """{node: command prefix} of the nodes started here; RunConfigError for an executable that
    is not there."""
    from stealth_tools.executables import ExecutableNotFoundError, find_executable

    given = {}
    for item in replacements:
        node, sep, path = item.partition('=')
        if not sep or node not in NODES or not path:
            raise RunConfigError(
                f'--executable {item!r}: expected NODE=PATH with NODE one of {", ".join(NODES)}'
            )
        if node not in nodes:
            raise RunConfigError(f'--executable {item!r}: this run has no {node} node')
        if node in remote:
            raise RunConfigError(
                f'--executable {item!r}: {node} is --remote, started on the other host with '
                'the command printed there; drop one of the two'
            )
        given[node] = path
    commands = {}
    for name in nodes:
        if name in remote:
            continue
        spec = NODES[name]
        if name in given:
            path = Path(given[name])
            if not path.is_file():
                raise RunConfigError(f'{name}: executable {path} does not exist')
            if not os.access(path, os.X_OK):
                raise RunConfigError(f'{name}: {path} is not executable')
            commands[name] = [str(path)]
            continue
        try:
            commands[name] = [str(find_executable(spec.package, spec.executable))]
        except ExecutableNotFoundError as error:
            raise RunConfigError(
                f'{name}: {error}; build the workspace (make setup) and source scripts/ros_env.sh'
            ) from None
    return commands


@dataclasses.dataclass
class Continuation:
    """What the earlier part of a continued run left (stealth train --resume)."""

    records: list  # its episodes (EpisodeRecord), from its episodes.csv
    summary: dict  # its summary.json
    first_episode: int  # the number of the first episode of this part


@dataclasses.dataclass
class RunPlan:
    """Everything decided before anything starts."""

    mode: str  # 'train' or 'eval'
    command_line: str
    scenario: object
    goal: str
    directory: Path
    episodes: int
    eval_every: int
    streak: int
    parameters: dict[str, NodeParameters]
    commands: dict[str, list[str]]
    startup_timeout: float
    stall_timeout: float
    policy_path: Path
    record: bool
    watch_port: int | None = None  # the bridge's port under --watch
    discovery: str = 'localhost'  # a key of DISCOVERY_RANGES
    remote: tuple[str, ...] = ()  # nodes that join from another host (not in `commands`)
    join_timeout: float = JOIN_TIMEOUT
    respawn: int = 0  # restarts allowed per node
    continued: Continuation | None = None  # stealth train --resume: the run's earlier part
    notes: list[str] = dataclasses.field(default_factory=list)  # to say before the run starts
    hashes: dict[str, str] = dataclasses.field(default_factory=dict)  # scenario and map SHA-256
    composed: bool = False  # --compose: the simulator runs in the environment's process

    def process_of(self, node: str) -> str:
        """The name of the local process `node` runs in (its own, but for a composed
        simulator: the environment's)."""
        return COMPOSED[1] if self.composed and node == COMPOSED[0] else node

    def ros_args(self, process: str) -> list[str]:
        """--ros-args of a process: its node's params file (and --set values as -p, for a
        process list to show), or, for the composed one, both nodes' files (a -p would reach
        both nodes)."""
        if self.composed and process == COMPOSED[1]:
            files = [str(self.params_file(node).resolve()) for node in COMPOSED]
            return ['--ros-args', *(arg for path in files for arg in ('--params-file', path))]
        params_file = self.params_file(process).resolve()
        return self.parameters[process].ros_args(params_file)

    @property
    def nodes(self) -> list[str]:
        """Every node of the run, started here or remote, in start order."""
        return [n for n in NODE_ORDER if n in self.parameters]

    @property
    def title(self) -> str:
        return f'{self.scenario.name} ({self.goal})'

    def describe(self) -> str:
        """One line: what is run on what, and until when."""
        if self.mode != 'train':
            return f'{self.title}, policy {self.policy_path}, {self.episodes} greedy episodes'
        ending = f'up to {self.episodes} episodes'
        if self.continued is not None:
            done = len(self.continued.records)
            ending = f'continued from episode {self.continued.first_episode} ({done} done), ' + (
                ending + ' in all'
            )
        if self.eval_every:
            ending += f', a greedy evaluation every {self.eval_every}'
        if self.streak:
            ending += f', stopping after {self.streak} greedy successes in a row'
        learner = self.parameters['agent'].values.get('agent', 'qlearning')
        return f'{self.title}, learner {learner}; {ending}'

    def file(self, name: str) -> Path:
        return self.directory / name

    def params_file(self, node: str) -> Path:
        return self.directory / 'params' / f'{node}.yaml'

    def write_params_files(self) -> None:
        """Every node's effective parameters, with where they came from, for it to run with."""
        for node, parameters in self.parameters.items():
            header = (
                f'Parameters node {node!r} ran with in {relative_to_cwd(self.directory)}: '
                f'{parameters.source} + scenario/run values'
                + (f' + --set {", ".join(parameters.overrides)}' if parameters.overrides else '')
                + f'.\nCommand: {self.command_line}'
            )
            write_params_file(parameters, self.params_file(node), header)


def make_plan(args, mode: str, argv: Sequence[str]) -> RunPlan:
    """Check every input and lay out the run; RunConfigError before anything exists."""
    continued = None
    if mode == 'train' and args.resume is not None:
        continued, scenario, goal, params_dir = _continued_run(args)
    elif mode == 'train':
        scenario = _load_scenario(args.scenario or DEFAULT_SCENARIO)
        # The default scenario's quick goal, however it is named (by name or by its file).
        is_default = (
            Path(scenario.path).resolve() == Path(_load_scenario(DEFAULT_SCENARIO).path).resolve()
        )
        default_goal = DEFAULT_GOAL if is_default else None
        goal = _check_goal(scenario, args.goal, default_goal)
        params_dir = args.params_dir
    else:
        scenario, goal, source_policy, params_dir = _eval_source(args)
    if mode == 'train':
        episodes, eval_every, streak = _train_settings(args, continued)
    else:
        episodes, eval_every, streak = args.episodes, 0, 0
    left_out = {'recorder': args.no_record, 'bridge': not args.watch}
    nodes = [n for n in NODE_ORDER if not left_out.get(n)]
    sources = params_sources(_defaults_dir(), params_dir and Path(params_dir), nodes)
    overrides = parse_set(args.overrides, nodes)
    remote = tuple(n for n in REMOTE_NODES if n in args.remote)
    commands = _executables(nodes, args.executable, remote)
    if args.compose:
        commands = _composed(commands, args)
    hashes = _hashes(scenario)

    # The run's own values, on top of the parameter files.
    run_values = {n: {} for n in nodes}
    for node, values in scenario_parameters(scenario, goal).items():
        run_values[node].update(values)
    if args.seed is not None:
        for node in ('simulator', 'environment', 'agent'):
            run_values[node]['seed'] = args.seed
    if args.watch:  # real time, and the simulator's topics at a rate a viewer shows smoothly
        run_values['simulator'].update(real_time_factor=1.0, publish_rate=WATCH_PUBLISH_RATE)
        run_values['environment']['publish_plan'] = True  # the optimum, for the 3D view
    elif _robot_interface(sources, run_values, overrides) == 'topics':
        run_values['simulator'].update(TOPICS_SIMULATOR)
    # Read the files before creating anything, so a bad one stops us with nothing to undo.
    parameters = {
        node: effective_parameters(node, sources[node], run_values[node], overrides.get(node, {}))
        for node in nodes
    }

    if 'bridge' in parameters:
        _check_port_free(parameters['bridge'].values)

    stamp = utc_stamp()
    # Episode numbers start at 0, or go on after a continued run's last one (agent and
    # environment alike), whatever a parameter file from another run says.
    first = {'first_episode': continued.first_episode if continued is not None else 0}
    parameters['environment'].values.update(first)
    if mode == 'train' and continued is not None:
        directory = Path(args.resume)
        policy_path = directory / 'policy.npz'
        agent = {'policy_file': str(policy_path.resolve()), 'eval_every': eval_every, **first}
        agent.update(evaluate=False, load_policy=True)
    elif mode == 'train':
        directory = Path(args.runs_dir) / (args.name or f'{scenario.name}-{goal}-{stamp}')
        policy_path = directory / 'policy.npz'
        agent = {'policy_file': str(policy_path.resolve()), 'eval_every': eval_every, **first}
        agent.update(evaluate=False, load_policy=False)
    else:
        if args.run is not None:  # the evaluation goes into the run's directory
            runs_dir, default = Path(args.run), f'eval-{stamp}'
        else:
            runs_dir, default = Path(args.runs_dir), f'eval-{scenario.name}-{goal}-{stamp}'
        directory = run_directory(runs_dir, args.name, default)
        policy_path = source_policy
        agent = {
            'policy_file': str(source_policy.resolve()),
            'evaluate': True,
            'load_policy': False,
            'eval_every': 0,
            **first,
        }
    parameters['agent'].values.update(agent)
    if 'recorder' in parameters:
        recording = next_recording_file(directory).resolve()
        parameters['recorder'].values['output'] = str(recording)
    notes = _check_parameters(args, parameters, params_dir)
    if continued is not None and not policy_path.is_file():
        notes.append(f'{relative_to_cwd(policy_path)} is not there: the agent starts from a '
                     'fresh table (the run was killed before it saved one)')  # fmt: skip
    if mode == 'train' and continued is None:  # created last: a refused run leaves nothing
        directory = run_directory(Path(args.runs_dir), args.name, directory.name)
        policy_path = directory / 'policy.npz'
        parameters['agent'].values['policy_file'] = str(policy_path.resolve())
        if 'recorder' in parameters:
            recording = (directory / 'recording.mcap').resolve()
            parameters['recorder'].values['output'] = str(recording)
    return RunPlan(
        mode=mode,
        command_line=' '.join(['stealth', mode, *map(shlex.quote, argv)]),
        scenario=scenario,
        goal=goal,
        directory=directory,
        episodes=episodes,
        eval_every=eval_every,
        streak=streak if eval_every else 0,
        parameters=parameters,
        commands=commands,
        startup_timeout=args.startup_timeout,
        stall_timeout=args.stall_timeout,
        policy_path=policy_path,
        record='recorder' in parameters,
        watch_port=parameters['bridge'].values.get('port') if 'bridge' in parameters else None,
        discovery=args.discovery,
        remote=remote,
        join_timeout=args.join_timeout,
        respawn=args.respawn,
        continued=continued,
        notes=notes,
        hashes=hashes,
        composed=args.compose,
    )


def _train_settings(args, continued: Continuation | None) -> tuple[int, int, int]:
    """(episode budget, eval_every, success streak) of a training run: the options given, else
    a continued run's own, else the defaults; RunConfigError when a continued run would stop
    at once."""
    if continued is None:
        return (
            DEFAULT_EPISODES if args.episodes is None else args.episodes,
            DEFAULT_EVAL_EVERY if args.eval_every is None else args.eval_every,
            DEFAULT_STREAK if args.success_streak is None else args.success_streak,
        )
    saved = continued.summary
    episodes = _given(args.episodes, saved.get('episode_budget'), DEFAULT_EPISODES)
    eval_every = _given(args.eval_every, saved.get('eval_every'), DEFAULT_EVAL_EVERY)
    streak = _given(args.success_streak, saved.get('success_streak'), DEFAULT_STREAK)
    from stealth_bringup.episode_tracker import Tracker

    tracker = Tracker(episodes, (streak if eval_every else 0) or None)
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
            f'{where}: the run ended on {tracker.streak} greedy successes in a row (its '
            f'--success-streak {streak}); give a larger --success-streak, or 0 to spend the '
            'budget'
        )
    return episodes, eval_every, streak


def _given(value, saved, default):
    """An option's value: given on the command line, else the run's saved one, else default."""
    if value is not None:
        return value
    return saved if isinstance(saved, int) and not isinstance(saved, bool) else default


def _hashes(scenario) -> dict[str, str]:
    """SHA-256 of the scenario file and of its map, for a continued run to compare."""
    hashes = {}
    for key, path in (('sha256', scenario.path), ('map_sha256', scenario.map_path)):
        try:
            hashes[key] = file_sha256(Path(path))
        except OSError as error:
            raise RunConfigError(f'{path}: cannot read it ({error.strerror})') from None
    return hashes


def _continued_run(args):
    """(Continuation, scenario, goal, params dir) of `stealth train --resume RUN`;
    RunConfigError saying why RUN cannot be continued."""
    from stealth_bringup.run_outputs import read_episodes_csv

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
    summary = _read_run_summary(run)
    if not summary:
        raise RunConfigError(f'{where}: its summary.json is not a JSON object stealth train wrote')
    if summary.get('mode') != 'train':
        raise RunConfigError(
            f'{where}: a run of stealth {summary.get("mode") or "?"}, not a training run; only '
            'stealth train runs can be continued'
        )
    if not (run / 'params').is_dir():
        raise RunConfigError(f'{where}: it has no params/ directory (not a complete run)')
    saved = summary.get('scenario') or {}
    path = saved.get('path')
    if not isinstance(path, str) or not Path(path).is_file():
        raise RunConfigError(f'{where}: its scenario file {path} is not there any more')
    scenario = _load_scenario(path)
    for key, now in _hashes(scenario).items():
        then = saved.get(key)
        if then is not None and then != now:
            what = 'scenario file' if key == 'sha256' else 'map'
            changed = scenario.path if key == 'sha256' else scenario.map_path
            raise RunConfigError(
                f'{where}: its {what} {changed} changed since the run started (SHA-256 '
                f'{then[:12]}... then, {now[:12]}... now); the policy was learned on the old '
                'one: restore it, or start a new run'
            )
    goal = _check_goal(scenario, summary.get('goal'))
    csv_path = run / 'episodes.csv'
    records = read_episodes_csv(csv_path) if csv_path.is_file() else []
    first = max((r.episode for r in records), default=-1) + 1
    params_dir = args.params_dir or str(run / 'params')
    if not (run / 'params' / 'recorder.yaml').is_file():
        args.no_record = True  # the run was not recorded (--no-record): nor is its continuation
    return Continuation(records, summary, first), scenario, goal, params_dir


def _check_parameters(args, parameters, params_dir) -> list[str]:
    """Before anything starts: every parameter name one the node declares (its installed
    table; a node replaced with --executable is checked once it runs), and the values of a
    --params-dir file that the run sets itself honoured or refused. The notes to say."""
    replaced = {item.partition('=')[0] for item in args.executable}
    for node, values in parameters.items():
        if node not in replaced:
            check_parameter_names(values, declared_parameters(node))
    notes = []
    if args.params_dir is None:
        return notes
    for node, values in parameters.items():
        if Path(values.source).parent == Path(params_dir):
            file_values = read_params_file(values.source, node)
            notes += check_managed(values, file_values)
    return notes


def declared_parameters(node: str) -> frozenset[str]:
    """The parameters the installed node declares: its table, and those of every ROS node."""
    from stealth_agent import agent_parameters
    from stealth_env import env_parameters
    from stealth_sim import sim_parameters
    from stealth_tools import bridge_parameters, recorder_parameters

    tables = {
        'recorder': recorder_parameters,
        'bridge': bridge_parameters,
        'simulator': sim_parameters,
        'environment': env_parameters,
        'agent': agent_parameters,
    }
    return frozenset(tables[node].PARAMETERS) | ROS_OWN_PARAMETERS


def _check_port_free(bridge: dict) -> None:
    """The bridge's port must be free before anything starts (RunConfigError naming it)."""
    import socket

    from stealth_tools.bridge_core import DEFAULT_PORT, port_in_use_line

    port, address = bridge.get('port', DEFAULT_PORT), bridge.get('address', '127.0.0.1')
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server binds
        try:
            probe.bind((address, int(port)))
        except OSError as error:
            if error.errno == errno.EADDRINUSE:
                raise RunConfigError(
                    'bridge: ' + port_in_use_line(port, '--set bridge.port=N')
                ) from None
            raise RunConfigError(f'bridge: cannot listen on {address}:{port}: {error}') from None


def _robot_interface(sources, run_values, overrides) -> str:
    """The environment's effective robot_interface (issue 13: topics mode)."""
    environment = effective_parameters(
        'environment',
        sources['environment'],
        run_values['environment'],
        overrides.get('environment', {}),
    )
    return environment.values.get('robot_interface', 'service')


_TITLE = re.compile(r'^stealth-nav: (?P<scenario>.+) \((?P<goal>[^()]+)\)$')


def _eval_source(args):
    """(scenario, goal, policy path, params dir) of `stealth eval`."""
    from stealth_agent.policy_store import PolicyFileError, load_policy

    run_summary = {}
    params_dir = args.params_dir
    if args.run is not None:
        run = Path(args.run)
        if not run.is_dir():
            raise RunConfigError(f'--run {run}: no such run directory')
        policy = run / 'policy.npz'
        if not policy.is_file():
            raise RunConfigError(f'--run {run}: it has no policy.npz (did the run save one?)')
        run_summary = _read_run_summary(run)
        if params_dir is None and (run / 'params').is_dir():
            params_dir = str(run / 'params')
    else:
        policy = Path(args.policy)
        if not policy.is_file():
            raise RunConfigError(f'--policy {policy}: no such file')
        run_summary = _read_run_summary(policy.parent)
    try:
        saved = load_policy(policy)
    except PolicyFileError as error:
        raise RunConfigError(str(error)) from None
    title = str(saved.scenario.get('title', ''))
    named = _TITLE.match(title)
    scenario_name = (
        args.scenario
        or run_summary.get('scenario', {}).get('path')
        or (named.group('scenario') if named else None)
    )
    if scenario_name is None:
        raise RunConfigError(f'{policy}: it names no scenario; give --scenario')
    scenario = _load_scenario(scenario_name)
    default_goal = run_summary.get('goal') or (named.group('goal') if named else None)
    goal = _check_goal(scenario, args.goal, default_goal)
    from stealth_env.task import StealthTask

    expected = StealthTask(scenario, goal).title
    if title and title != expected:
        raise RunConfigError(
            f'{policy} was trained on {title!r}, not on {expected!r}; give the matching '
            '--scenario and --goal'
        )
    return scenario, goal, policy, params_dir


def _read_run_summary(directory: Path) -> dict:
    path = directory / 'summary.json'
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding='utf-8'))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}
