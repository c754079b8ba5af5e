"""What `stealth train` and `stealth rollout` are asked to do, checked before anything starts: the
parameter files and --set, the executables (--compose, --executable, --remote), and the run
directory laid out with every node's effective parameters (RunPlan). The command line is
run_arguments', a continued run's earlier part run_resume's, the policy a rollout runs
rollout_source's. Every problem is a RunConfigError with one line to print. No rclpy.
"""

from __future__ import annotations

from collections.abc import Sequence
import contextlib
import dataclasses
import errno
import os
from pathlib import Path
import shlex
import shutil

from stealth_core.path_scores import DEFAULT_CRITERION, OPTIMUM_GAMMA, Criterion
from stealth_core.world_file import WORLD_FILE, write_world_file
from stealth_tools.bag_files import next_recording_file

from stealth_bringup.episode_budget import STATE_ACTIONS_PER_EPISODE, default_episode_budget
from stealth_bringup.parameter_checks import check_parameters
from stealth_bringup.prior_policy import write_prior_policy
from stealth_bringup.rollout_source import check_plugin_grid, rollout_source
from stealth_bringup.run_arguments import (
    COMMAND_OF_MODE,
    DEFAULT_EPISODES,
    DEFAULT_GOAL,
    DEFAULT_SCENARIO,
    JOIN_TIMEOUT,
    REMOTE_NODES,
)
from stealth_bringup.run_config import (
    NODE_ORDER,
    NODES,
    NodeParameters,
    RunConfigError,
    check_goal,
    check_managed,
    choose_run_directory,
    create_run_directory,
    effective_parameters,
    load_run_scenario,
    params_sources,
    parse_set,
    read_params_file,
    relative_to_cwd,
    scenario_hashes,
    scenario_parameters,
    utc_stamp,
    write_params_file,
)
from stealth_bringup.run_learner import (
    agent_value,
    asked_learner,
    check_modelled_scenario,
    exploration_notes,
    run_prior,
    table_learner,
)
from stealth_bringup.run_resume import (
    Continuation,
    continued_run,
    criterion_setting,
    train_settings,
)

WATCH_PUBLISH_RATE = 10.0  # Hz of odom, ground_truth, scan, clock under --watch
# environment.robot_interface topics (issue 13): the environment drives the simulator over
# cmd_vel/odom, one control step per odom message (a control period of 0.2 s simulated), and
# the simulator runs in lockstep with it (real_time_factor 0: the next period as soon as the
# command for the latest odom has come). Every node of such a run is on its simulated time
# (use_sim_time, issue 28), so its clock is the robot's wherever it runs.
TOPICS_SIMULATOR = {'real_time_factor': 0.0, 'publish_rate': 5.0}
TOPICS_ENVIRONMENT = {'command_latency': 0.0}  # a command acts from the odometry it answers
SIM_TIME = {'use_sim_time': True}
# --compose: these two nodes in one process, the second's (sim_env), under the second's name.
COMPOSED = ('simulator', 'environment')
COMPOSED_TEXT = 'the simulator and the environment'
SIM_ENV = ('stealth_bringup', 'sim_env')


def _defaults_dir() -> Path:
    """share/stealth_bringup/config of the install space (or the source tree's config/)."""
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    with contextlib.suppress(PackageNotFoundError):
        installed = Path(get_package_share_directory('stealth_bringup')) / 'config'
        if installed.is_dir():
            return installed
    return Path(__file__).resolve().parent.parent / 'config'


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
class RunPlan:
    """Everything decided before anything starts."""

    mode: str  # 'train' or 'eval' (`stealth rollout`)
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
    criterion: Criterion = DEFAULT_CRITERION  # what a greedy episode must meet (the streak's)

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
            grid = self.parameters['environment'].values.get('observation_layout') == 'grid'
            policy = f'{self.parameters["agent"].values["agent"]} ' if grid else ''
            episodes = f'{self.episodes} greedy episodes'
            return f'{self.title}, policy {policy}{self.policy_path}, {episodes}'
        ending = f'up to {self.episodes} episodes'
        if self.continued is not None:
            done = len(self.continued.records)
            ending = f'continued from episode {self.continued.first_episode} ({done} done), ' + (
                ending + ' in all'
            )
        if self.eval_every:
            ending += f', a greedy evaluation every {self.eval_every}'
        if self.streak:
            ending += (
                f', stopping after {self.streak} greedy evaluations in a row meet the success '
                f'criterion ({self.criterion.short()})'
            )
        return f'{self.title}, learner {agent_value(self.parameters, "agent")}; {ending}'

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


def step_readers(record: bool) -> int:
    """The readers of rl_env/step_info a run brings (its monitor, and its recorder when
    recording): the environment starts episodes only once that many are matched. Its StepInfo
    is built only while someone reads it, and a monitor matched late (the orchestrator busy
    checking parameters while the first episodes ran) left those steps unscored: a run without
    a recording then missed the criterion for its first 16 episodes."""
    return 1 + bool(record)


def make_plan(args, mode: str, argv: Sequence[str]) -> RunPlan:
    """Check every input and lay out the run; RunConfigError before anything exists."""
    continued = None
    if mode == 'train' and args.resume is not None:
        continued, scenario, goal, params_dir = continued_run(args)
    elif mode == 'train':
        scenario = load_run_scenario(args.scenario or DEFAULT_SCENARIO)
        # The default scenario's quick goal, however it is named (by name or by its file).
        is_default = (
            Path(scenario.path).resolve()
            == Path(load_run_scenario(DEFAULT_SCENARIO).path).resolve()
        )
        default_goal = DEFAULT_GOAL if is_default else None
        goal = check_goal(scenario, args.goal, default_goal)
        params_dir = args.params_dir
    else:
        scenario, goal, source_policy, params_dir, source_notes = rollout_source(args)
    budget_note = None
    if mode == 'train':
        default_episodes = DEFAULT_EPISODES
        if args.episodes is None and continued is None:
            default_episodes, pairs = default_episode_budget(scenario, goal)
        if default_episodes > DEFAULT_EPISODES:  # said where the scenario raised it
            budget_note = (
                f'episode budget {default_episodes}: one per {STATE_ACTIONS_PER_EPISODE} of the '
                f"table's {pairs:,} state-actions (--episodes N to change it)"
            )
        episodes, eval_every, streak = train_settings(args, continued, default_episodes)
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
    hashes = scenario_hashes(scenario)

    # The run's own values, on top of the parameter files.
    run_values = {n: {} for n in nodes}
    for node, values in scenario_parameters(scenario, goal).items():
        run_values[node].update(values)
    if mode == 'train' and args.learner is not None:
        run_values['agent']['agent'] = asked_learner(args.learner, overrides)
    if args.seed is not None:
        for node in ('simulator', 'environment', 'agent'):
            run_values[node]['seed'] = args.seed
    if args.watch:  # real time, and the simulator's topics at a rate a viewer shows smoothly
        run_values['simulator'].update(real_time_factor=1.0, publish_rate=WATCH_PUBLISH_RATE)
        run_values['environment']['publish_plan'] = True  # the optimum, for the 3D view
    elif _environment_value(sources, run_values, overrides, 'robot_interface') == 'topics':
        run_values['simulator'].update(TOPICS_SIMULATOR)
        run_values['environment'].update(TOPICS_ENVIRONMENT)
    if _environment_value(sources, run_values, overrides, 'robot_interface') == 'topics':
        for values in run_values.values():
            values.update(SIM_TIME)
    if _environment_value(sources, run_values, overrides, 'track') == 'sensed':
        run_values['agent']['state_features'] = sensed_state_features(scenario, goal)
    # Read the files before creating anything, so a bad one stops us with nothing to undo.
    parameters = {
        node: effective_parameters(node, sources[node], run_values[node], overrides.get(node, {}))
        for node in nodes
    }

    if 'bridge' in parameters:
        _check_port_free(parameters['bridge'])

    stamp = utc_stamp()
    # Episode numbers start at 0, or go on after a continued run's last one (agent and
    # environment alike), whatever a parameter file from another run says.
    first = {'first_episode': continued.first_episode if continued is not None else 0}
    parameters['environment'].values.update(
        first, step_readers=step_readers(record='recorder' in parameters)
    )
    if mode == 'train' and continued is not None:
        directory = Path(args.resume)
        policy_path = directory / 'policy.npz'
        agent = {'policy_file': str(policy_path.resolve()), 'eval_every': eval_every, **first}
        agent.update(evaluate=False, load_policy=True)
    elif mode == 'train':
        default = f'{scenario.name}-{goal}-{stamp}'
        directory = choose_run_directory(Path(args.runs_dir), args.name, default)
        policy_path = directory / 'policy.npz'
        agent = {'policy_file': str(policy_path.resolve()), 'eval_every': eval_every, **first}
        agent.update(evaluate=False, load_policy=False)
    else:
        if args.run is not None:  # the evaluation goes into the run's directory
            runs_dir, default = Path(args.run), f'eval-{stamp}'
        else:
            runs_dir, default = Path(args.runs_dir), f'eval-{scenario.name}-{goal}-{stamp}'
        directory = choose_run_directory(runs_dir, args.name, default)
        policy_path = source_policy
        learner = getattr(args, 'learner', None)
        if learner is not None:  # a policy plugin: the environment sends it the grid
            check_plugin_grid(scenario, goal, learner, parameters['environment'].values['track'])
            parameters['agent'].values['agent'] = learner
            parameters['environment'].values['observation_layout'] = 'grid'
        agent = {
            'policy_file': str(source_policy.resolve()),
            'evaluate': True,
            'load_policy': False,
            'eval_every': 0,
            **first,
        }
    world_path = None
    if mode == 'train' and table_learner(parameters) == 'light-model':
        check_modelled_scenario(scenario)  # before anything exists
        world_path = directory / WORLD_FILE
        agent['world_file'] = str(world_path.resolve())
    parameters['agent'].values.update(agent)
    if 'recorder' in parameters:
        recording = next_recording_file(directory).resolve()
        parameters['recorder'].values['output'] = str(recording)
    notes = _check_parameters(args, parameters, params_dir)
    if budget_note is not None:
        notes.append(budget_note)
    gamma = parameters['agent'].values.get('gamma', OPTIMUM_GAMMA)
    if mode == 'train' and gamma != OPTIMUM_GAMMA and scenario.has_moving_lights:
        notes.append(
            f'agent gamma {gamma:g}: the success criterion judges against the undiscounted '
            'optimum, which a discounting learner may not converge to where lights move'
        )
    if mode == 'train':
        notes += exploration_notes(parameters)
    if mode != 'train':
        notes += source_notes
    if continued is not None and not policy_path.is_file():
        notes.append(f'{relative_to_cwd(policy_path)} is not there: the agent starts from a '
                     'fresh table (the run was killed before it saved one)')  # fmt: skip
    prior = run_prior(args.prior, continued, parameters) if mode == 'train' else 'none'
    if continued is None:  # created last: a refused run leaves nothing
        create_run_directory(directory)
    if world_path is not None:  # what the light model may know: the scenario without lights
        with _removed_on_failure(directory, 'the world file', keep=continued is not None):
            write_world_file(scenario, goal, world_path)
        notes.append(
            f'the agent knows {relative_to_cwd(world_path)}: the scenario without its lights'
        )
    if prior == 'floor_plan':  # a new run's (run_prior refuses it with --resume)
        with _removed_on_failure(directory, 'the prior'):
            states = write_prior_policy(policy_path, scenario, goal, parameters['agent'].values)
        parameters['agent'].values['load_policy'] = True
        notes.append(f"the agent's table starts from the floor plan ({states:,} states)")
    return RunPlan(
        mode=mode,
        command_line=' '.join(['stealth', COMMAND_OF_MODE[mode], *map(shlex.quote, argv)]),
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
        criterion=criterion_setting(args, continued),
    )


def _check_parameters(args, parameters, params_dir) -> list[str]:
    """Before anything exists: every node's parameters against its table (parameter_checks),
    and the values of a --params-dir file that the run sets itself honoured or refused. The
    notes to say."""
    check_parameters(parameters, {item.partition('=')[0] for item in args.executable})
    notes = []
    if args.params_dir is None:
        return notes
    for node, values in parameters.items():
        if Path(values.source).parent == Path(params_dir):
            file_values = read_params_file(values.source, node)
            notes += check_managed(values, file_values)
    return notes


@contextlib.contextmanager
def _removed_on_failure(directory: Path, what: str, keep: bool = False):
    """A new run directory goes again when what fills it before the run fails (the prior's
    table, the world file): the name stays free (``keep``: a resumed run's stays).
    RunConfigError for a file that cannot be written."""
    try:
        yield
    except BaseException as error:
        if not keep:
            shutil.rmtree(directory, ignore_errors=True)
        if isinstance(error, OSError):
            raise RunConfigError(f'{directory}: cannot write {what}: {error}') from None
        raise


def _check_port_free(bridge: NodeParameters) -> None:
    """The bridge's port must be a TCP port, and free, before anything starts (RunConfigError
    naming where the value came from)."""
    import socket

    from stealth_tools.bridge_core import DEFAULT_PORT, port_in_use_line
    from stealth_tools.bridge_parameters import PARAMETERS

    port = bridge.values.get('port', DEFAULT_PORT)
    address = bridge.values.get('address', '127.0.0.1')
    low, high = PARAMETERS['port'].bounds
    if isinstance(port, bool) or not isinstance(port, int) or not low <= port <= high:
        given = '--set' if 'port' in bridge.overrides else f'{bridge.source}:'
        raise RunConfigError(
            f'{given} bridge.port: expected a TCP port, a whole number from {low} to {high}, '
            f'got {port!r}'
        )
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server binds
        try:
            probe.bind((address, port))
        except OSError as error:
            if error.errno == errno.EADDRINUSE:
                raise RunConfigError(
                    'bridge: ' + port_in_use_line(port, '--set bridge.port=N')
                ) from None
            raise RunConfigError(f'bridge: cannot listen on {address}:{port}: {error}') from None


def _environment_value(sources, run_values, overrides, name: str):
    """The environment's effective value of parameter `name` (robot_interface: issue 13's
    topics mode; track), its table's default when nothing sets it."""
    from stealth_env.env_parameters import PARAMETERS

    environment = effective_parameters(
        'environment',
        sources['environment'],
        run_values['environment'],
        overrides.get('environment', {}),
    )
    return environment.values.get(name, PARAMETERS[name].default)


def sensed_state_features(scenario, goal: str) -> int:
    """The full track's state length (x, y, any phase and heading): what the tabular agent keys
    on when the environment sends the sensed track's states (agent parameter state_features)."""
    from stealth_core.task import StealthTask

    return len(StealthTask(scenario, goal).state_features)
