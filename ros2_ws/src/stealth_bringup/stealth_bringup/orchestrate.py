"""`stealth train` and `stealth eval`: the whole system as separate OS processes, without launch.

    stealth train [--scenario NAME|PATH] [--goal G] [--episodes N] [--eval-every M]
                  [--success-streak K] [--seed S] [--set node.param=value ...] [--watch]
    stealth eval --run runs/<name> | --policy FILE [--episodes N]

A run starts the recorder, the simulator, the environment and the agent from the install space
(found through the ament index, as `ros2 run` finds them), each in its own process group with
its output in runs/<name>/logs/<node>.log, in a private ROS_DOMAIN_ID over localhost only, each
with `--ros-args --params-file runs/<name>/params/<node>.yaml` (the effective parameters: the
node's default file or --params-dir's, what the scenario and the run decide, --set). It waits
until every node is on the graph (and the simulator's services are there), then follows the
episodes as a small rclpy node of its own (rl_env/episode_summary, rl_agent/episode_info,
rl_env/step_info) with a progress bar, until the episode budget is spent or the greedy policy
has reached the goal in K evaluations in a row. It then stops the nodes in order (agent,
environment, simulator, and the recorder last, so the MCAP is finished), SIGKILL only after a
timeout, and writes the run's outputs.

Ctrl-C or SIGTERM: the same orderly stop, exit 130 or 143 (a second Ctrl-C kills at once). A
node that dies: everything else stopped, one line naming the node, how it ended and its last
log line, exit 1. Bad input (scenario, goal, parameter file, --set, a missing executable) is
one line and exit 1 before anything starts.
"""

from __future__ import annotations

from collections.abc import Sequence
import contextlib
import math
import os
from pathlib import Path
import signal
import sys
import time

from stealth_bringup.episode_tracker import (
    EpisodeRecord,
    Tracker,
    agent_fields,
    summary_fields,
)
from stealth_bringup.run_config import (
    NODE_ORDER,
    STOP_ORDER,
    RunConfigError,
    relative_to_cwd,
    write_params_file,
)
from stealth_bringup.run_plan import RunPlan, eval_parser, make_plan, train_parser

STOP_TIMEOUTS = {'agent': 15.0, 'environment': 10.0, 'simulator': 10.0, 'recorder': 30.0}
SPIN_PERIOD = 0.1  # s: how long a signal or a dead node can go unnoticed
EXIT_SIGNAL = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGHUP: 129}
GRAPH_TOPICS_IGNORED = {'/rosout', '/parameter_events'}
# The recorder works off what the others publish; at a lower priority it never delays the
# lockstep agent -> environment -> simulator chain, and catches up while that chain waits.
NICENESS = {'recorder': 10}
PARAMETER_TIMEOUT = 10.0  # s for a node's parameter services to answer
# The environment's start_delay until the recorder subscribes to every topic (then the file's).
HOLD_START_DELAY = 3600.0
DRAIN_TIME = 0.1  # s of taking in late reports before each node is stopped
ROS_OWN_PARAMETERS = {'use_sim_time', 'start_type_description_service'}  # every node has them


class RunError(RuntimeError):
    """The run failed after it started; the message is the one line to print."""


# --- signals ------------------------------------------------------------------------------------


class Signals:
    """SIGINT, SIGTERM and SIGHUP (the terminal went away) only noted: the run stops its nodes
    in order and still writes its outputs. Restored on exit."""

    def __init__(self):
        self.received: list[int] = []
        self._previous = {}

    def __enter__(self):
        for signum in EXIT_SIGNAL:
            self._previous[signum] = signal.signal(signum, self._note)
        return self

    def __exit__(self, *exc):
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)

    def _note(self, signum, _frame) -> None:
        self.received.append(signum)

    @property
    def first(self) -> int | None:
        return self.received[0] if self.received else None

    def hurry(self) -> bool:
        """A second signal: stop waiting for nodes to finish."""
        return len(self.received) >= 2


# --- the monitor node ----------------------------------------------------------------------------


class Monitor:
    """The orchestrator's rclpy side: graph queries and the episode reports."""

    def __init__(self, context, tracker: Tracker, started: float, on_record):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from stealth_interfaces.msg import AgentEpisodeInfo, EpisodeSummary, StepInfo

        self.node = rclpy.create_node(
            'orchestrator', context=context, start_parameter_services=False
        )
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.tracker = tracker
        self.started = started
        self.on_record = on_record
        self.last_activity = time.monotonic()  # of the latest report (the stall watchdog)
        self.paths: dict[int, list[tuple[float, float]]] = {}  # true (x, y) by episode
        self.frozen = False  # set when the run ends: later reports are not counted
        self.late: list[dict] = []  # summaries that arrived after that
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_ALL,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.VOLATILE,
        )
        self.node.create_subscription(
            EpisodeSummary, 'rl_env/episode_summary', self._on_summary, qos
        )
        self.node.create_subscription(
            AgentEpisodeInfo, 'rl_agent/episode_info', self._on_agent_info, qos
        )
        self.node.create_subscription(StepInfo, 'rl_env/step_info', self._on_step, qos)

    def close(self) -> None:
        self.executor.remove_node(self.node)
        self.executor.shutdown()
        self.node.destroy_node()

    def spin(self, timeout: float = SPIN_PERIOD) -> None:
        self.executor.spin_once(timeout_sec=timeout)

    def _elapsed(self) -> float:
        return time.monotonic() - self.started

    def _on_summary(self, msg) -> None:
        self.last_activity = time.monotonic()
        if self.frozen:  # the run has ended: an episode after the end or cut short by it
            self.late.append(summary_fields(msg))
            return
        for record in self.tracker.add_summary(summary_fields(msg), self._elapsed()):
            self.on_record(record)

    def _on_agent_info(self, msg) -> None:
        self.last_activity = time.monotonic()
        if self.frozen:
            return
        fields = agent_fields(msg)
        for record in self.tracker.add_agent_info(int(msg.episode), fields, self._elapsed()):
            self.on_record(record)

    def _on_step(self, msg) -> None:
        self.last_activity = time.monotonic()
        self.paths.setdefault(msg.episode, []).append((msg.true_pose.x, msg.true_pose.y))

    # --- the graph --------------------------------------------------------------------------

    def node_names(self) -> set[str]:
        return {name for name, namespace in self.node.get_node_names_and_namespaces()
                if namespace == '/'}  # fmt: skip

    def services_of(self, node_name: str) -> set[str]:
        with contextlib.suppress(Exception):  # the node may not be there yet
            return {
                name for name, _ in self.node.get_service_names_and_types_by_node(node_name, '/')
            }
        return set()

    def parameter_names(self, node_name: str, alive, timeout: float) -> set[str] | None:
        """The parameters `node_name` declares (its list_parameters service), None if the
        service does not answer within `timeout` s; alive() false stops waiting."""
        from rclpy.parameter_client import AsyncParameterClient

        client = AsyncParameterClient(self.node, node_name)
        deadline = time.monotonic() + timeout
        while not client.services_are_ready():
            if time.monotonic() >= deadline or not alive():
                return None
            self.spin()
        future = client.list_parameters()
        while not future.done():
            if time.monotonic() >= deadline or not alive():
                return None
            self.spin()
        response = future.result()
        return None if response is None else set(response.result.names)

    def set_parameter(self, node_name: str, name: str, value, timeout: float) -> bool:
        """Set one parameter of a node; True when it took it."""
        from rclpy.parameter import Parameter
        from rclpy.parameter_client import AsyncParameterClient

        client = AsyncParameterClient(self.node, node_name)
        deadline = time.monotonic() + timeout
        while not client.services_are_ready():
            if time.monotonic() >= deadline:
                return False
            self.spin()
        future = client.set_parameters([Parameter(name, value=value)])
        while not future.done():
            if time.monotonic() >= deadline:
                return False
            self.spin()
        response = future.result()
        return bool(response is not None and all(r.successful for r in response.results))

    def unrecorded_topics(self, node_name: str) -> list[str]:
        """Topics `node_name` publishes that the recorder does not subscribe to yet."""
        try:
            topics = self.node.get_publisher_names_and_types_by_node(node_name, '/')
        except Exception:  # noqa: BLE001 - not on the graph yet
            return ['(node not discovered)']
        topics = [(t, types) for t, types in topics if t not in GRAPH_TOPICS_IGNORED]
        if not topics:  # the node is known before its endpoints are
            return ['(its publishers, not discovered yet)']
        missing = []
        for topic, _ in topics:
            readers = self.node.get_subscriptions_info_by_topic(topic)
            if not any(info.node_name == 'recorder' for info in readers):
                missing.append(topic)
        return missing


# --- the run ------------------------------------------------------------------------------------


class Run:
    """One orchestrated run: processes, progress, end, outputs."""

    def __init__(self, plan: RunPlan, started: float | None = None, out=None, err=None):
        self.plan = plan
        self.out, self.err = out or sys.stdout, err or sys.stderr
        self.prog = f'stealth {plan.mode}'
        self.tracker = Tracker(plan.episodes, plan.streak or None)
        self.started = time.monotonic() if started is None else started  # the command's start
        self.status = 'failed'
        self.message = ''
        self.exit_code = 1
        self.startup_seconds = math.nan
        self.training_started: float | None = None
        self.stopped_at: float | None = None
        self.domain_id: int | None = None
        self.supervisor = None
        self.monitor: Monitor | None = None
        self.bar = None
        self.node_exits: dict[str, str] = {}
        self.crashed: set[str] = set()  # nodes that died on their own (reported already)
        self.node_cpu: dict[str, float | None] = {}  # CPU s each node used, taken at the end
        self.files: dict[str, Path] = {}

    # --- printing ---------------------------------------------------------------------------

    def say(self, text: str) -> None:
        """A line on stderr (above the progress bar); a terminal that went away is no error."""
        with contextlib.suppress(OSError, ValueError):
            if self.bar is not None and not self.bar.disable:
                self.bar.write(text, file=self.err)
            else:
                print(text, file=self.err, flush=True)

    def _fail(self, message: str) -> None:
        self.status, self.message, self.exit_code = 'failed', message, 1

    # --- running ----------------------------------------------------------------------------

    def execute(self) -> int:
        """The whole run; its exit status."""
        from stealth_bringup.ros_domain import shm_segments

        self._write_params()
        shm_before = shm_segments()
        with Signals() as signals:
            self._run(signals, shm_before)
            if self.status == 'failed':
                self.say(f'{self.prog}: {self.message}')
            self._write_outputs()  # a signal now changes nothing: the files get written
            self._closing_summary()
        return self.exit_code

    def _run(self, signals: Signals, shm_before: set[str]) -> None:
        """Start, follow and stop the nodes in the private domain."""
        from stealth_bringup.ros_domain import (
            DomainError,
            private_environment,
            remove_orphaned_shm,
            reserved_domain_id,
        )
        from stealth_bringup.supervisor import Supervisor

        plan = self.plan
        with contextlib.ExitStack() as stack:
            try:
                domain_id = stack.enter_context(reserved_domain_id())
            except DomainError as error:
                self._fail(str(error))
                return
            self.domain_id = domain_id
            env = private_environment(domain_id)
            self.supervisor = Supervisor(env, plan.directory / 'logs')
            self._announce()
            context = None
            try:
                context = self._init_ros(domain_id)
                self.monitor = Monitor(context, self.tracker, self.started, self._on_record)
                self._start_nodes(signals)
                self._follow(signals)
            except RunError as error:
                self._fail(str(error))
            finally:
                self._close_bar()
                self.stopped_at = time.monotonic()
                self._stop_nodes(signals)
                if self.monitor is not None:
                    self.monitor.close()
                if context is not None:
                    context.try_shutdown()
            if self.supervisor.any_killed:
                removed = remove_orphaned_shm(shm_before)
                if removed:
                    self.say(f'{self.prog}: removed {len(removed)} shared-memory segments of '
                             'killed nodes from /dev/shm')  # fmt: skip

    def _init_ros(self, domain_id: int):
        import rclpy
        from rclpy.signals import SignalHandlerOptions

        os.environ['ROS_DOMAIN_ID'] = str(domain_id)
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        os.environ.pop('ROS_LOCALHOST_ONLY', None)
        # The orchestrator's own participant talks UDP only (the nodes' environment was taken
        # before this): it then holds no Fast DDS shared memory, so even a SIGKILL of this
        # process leaves /dev/shm clean (the nodes get SIGTERM and close theirs normally).
        os.environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
        context = rclpy.Context()
        rclpy.init(
            context=context,
            domain_id=domain_id,
            signal_handler_options=SignalHandlerOptions.NO,
        )
        return context

    def _write_params(self) -> None:
        plan = self.plan
        for node, parameters in plan.parameters.items():
            header = (
                f'Parameters node {node!r} ran with in {relative_to_cwd(plan.directory)}: '
                f'{parameters.source} + scenario/run values'
                + (f' + --set {", ".join(parameters.overrides)}' if parameters.overrides else '')
                + f'.\nCommand: {plan.command_line}'
            )
            write_params_file(parameters, plan.directory / 'params' / f'{node}.yaml', header)

    def _announce(self) -> None:
        plan = self.plan
        agent = plan.parameters['agent'].values
        if plan.mode == 'train':
            ending = f'up to {plan.episodes} episodes'
            if plan.eval_every:
                ending += f', a greedy evaluation every {plan.eval_every}'
            if plan.streak:
                ending += f', stopping after {plan.streak} greedy successes in a row'
            learner = f'{agent.get("agent", "qlearning")}'
            self.say(f'{self.prog}: {plan.title}, learner {learner}; {ending}')
        else:
            self.say(
                f'{self.prog}: {plan.title}, policy {plan.policy_path}, {plan.episodes} greedy '
                'episodes'
            )
        self.say(
            f'run directory: {relative_to_cwd(plan.directory)} (ROS_DOMAIN_ID {self.domain_id})'
        )

    def _start(self, name: str) -> None:
        plan = self.plan
        params_file = (plan.directory / 'params' / f'{name}.yaml').resolve()
        command = plan.commands[name] + plan.parameters[name].ros_args(params_file)
        if name == 'environment' and plan.record:  # on hold until the recorder listens
            command += ['-p', f'start_delay:={HOLD_START_DELAY}']
        try:
            self.supervisor.start(name, command, niceness=NICENESS.get(name, 0))
        except OSError as error:
            raise RunError(f'{name}: cannot start {command[0]}: {error.strerror}') from None

    def _check_processes(self, during: str) -> None:
        dead = self.supervisor.dead()
        if dead:
            node = dead[0]
            self.crashed.update(n.name for n in dead)
            log = relative_to_cwd(node.log_path)
            raise RunError(f'{node.why(during)} (log: {log})')

    def _wait(self, signals: Signals, what: str, ready, deadline: float, during: str) -> None:
        """Spin until ready() or the deadline; a signal or a dead node ends it at once."""
        while True:
            self._check_processes(during)
            if signals.first is not None:
                return
            missing = ready()
            if not missing:
                return
            if time.monotonic() >= deadline:
                raise RunError(
                    f'{what} not up within {self.plan.startup_timeout:g} s: still waiting for '
                    f'{missing} (logs: {relative_to_cwd(self.plan.directory / "logs")})'
                )
            self.monitor.spin()

    def _start_nodes(self, signals: Signals) -> None:
        """Start every node, wait until all are on the graph with the simulator's services, check
        their parameter names, and (when recording) release the first episode only once the
        recorder listens to every topic, so the recording misses nothing."""
        plan, monitor = self.plan, self.monitor
        deadline = time.monotonic() + plan.startup_timeout
        names = [n for n in NODE_ORDER if n in plan.commands]
        self.say(f'starting {", ".join(names)} ...')
        for name in names:
            self._start(name)

        def up() -> str:
            seen = monitor.node_names()
            missing = [n for n in names if n not in seen]
            if missing:
                return 'node ' + ', '.join(missing)
            services = monitor.services_of('simulator')
            wanted = {'/sim/execute_move', '/sim/reset'} - services
            if wanted:
                return 'simulator services ' + ', '.join(sorted(wanted))
            return ''

        self._wait(signals, 'the system', up, deadline, 'during startup')
        if signals.first is not None:
            return
        self._check_parameter_names(signals)
        if plan.record and signals.first is None:

            def recorded() -> str:
                for name in ('simulator', 'environment', 'agent'):
                    unrecorded = monitor.unrecorded_topics(name)
                    if unrecorded:
                        return f'the recorder to subscribe to {", ".join(unrecorded)} ({name})'
                return ''

            self._wait(signals, 'the recording', recorded, deadline, 'during startup')
            if signals.first is None:
                self._release_first_episode()
        self.startup_seconds = time.monotonic() - self.started
        self.say(f'all nodes up after {self.startup_seconds:.1f} s')

    def _release_first_episode(self) -> None:
        """Give the environment its configured start_delay back (it started on hold)."""
        value = float(self.plan.parameters['environment'].values.get('start_delay', 0.0))
        if not self.monitor.set_parameter('environment', 'start_delay', value, PARAMETER_TIMEOUT):
            self.say(f'{self.prog}: could not set environment start_delay to {value:g}')

    def _check_parameter_names(self, signals: Signals) -> None:
        """A parameter a node does not declare would be ignored without a word (a typo in
        --set, a file for another version): every one given must exist."""
        plan = self.plan
        for name in NODE_ORDER:
            if name not in plan.commands or signals.first is not None:
                continue
            node = self.supervisor.nodes[name]
            declared = self.monitor.parameter_names(
                name, lambda node=node: node.alive and signals.first is None, PARAMETER_TIMEOUT
            )
            self._check_processes('during startup')
            if declared is None:
                if signals.first is None:
                    self.say(f'{self.prog}: {name} does not list its parameters; not checked')
                continue
            unknown = sorted(set(plan.parameters[name].values) - declared)
            if unknown:
                source = relative_to_cwd(plan.directory / 'params' / f'{name}.yaml')
                raise RunError(
                    f'{name} has no parameter {", ".join(map(repr, unknown))} (in {source}); '
                    f'its parameters: {", ".join(sorted(declared - ROS_OWN_PARAMETERS))}'
                )

    def _follow(self, signals: Signals) -> None:
        """Spin until an end criterion, a signal, a dead node or a stall."""
        from tqdm import tqdm

        plan, monitor = self.plan, self.monitor
        if signals.first is not None:
            self._interrupted(signals.first)
            return
        self.training_started = time.monotonic()
        monitor.last_activity = self.training_started
        unit = 'ep'
        self.bar = tqdm(
            total=plan.episodes,
            unit=unit,
            desc='episodes',
            dynamic_ncols=True,
            file=self.err,
            disable=None,  # no bar when stderr is not a terminal: plain lines instead
            smoothing=0.1,
            # No time left: the budget is an upper bound, most runs end on the streak.
            bar_format='{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, {rate_fmt}{postfix}]',
        )
        while True:
            if signals.first is not None:
                self._interrupted(signals.first)
                return
            self._check_processes(f'during the run (episode {self.tracker.episodes})')
            reason = self.tracker.stop_reason()
            if reason is not None:
                self._finished(reason)
                return
            idle = time.monotonic() - monitor.last_activity
            if idle > plan.stall_timeout:
                raise RunError(
                    f'no step for {idle:.0f} s (episode {self.tracker.episodes}): the system is '
                    f'stuck; see the logs in {relative_to_cwd(plan.directory / "logs")}'
                )
            monitor.spin()

    def _on_record(self, record: EpisodeRecord) -> None:
        tracker = self.tracker
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix_str(tracker.postfix(), refresh=False)
            if self.bar.disable and (record.greedy or tracker.episodes % 10 == 0):
                what = 'greedy evaluation' if record.greedy else 'training'
                print(
                    f'episode {record.episode} ({what}): {record.outcome.lower()} in '
                    f'{record.steps} steps, return {record.total_reward:.1f}; '
                    f'{tracker.postfix()}',
                    file=self.err,
                    flush=True,
                )

    def _close_bar(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def _finished(self, reason: str) -> None:
        tracker, plan = self.tracker, self.plan
        self._close_bar()
        if reason == 'streak':
            episodes = [r.episode for r in tracker.records if r.greedy][-plan.streak :]
            self.status = 'success'
            self.message = (
                f'the greedy policy reached the goal undetected in {plan.streak} evaluations in '
                f'a row (episodes {", ".join(map(str, episodes))})'
            )
        else:
            self.status = 'budget'
            if plan.mode == 'eval':
                counts = tracker.outcome_counts()
                self.message = (
                    f'{plan.episodes} greedy episodes: {counts["SUCCESS"]} reached the goal'
                )
            else:
                self.message = f'episode budget of {plan.episodes} spent'
                if plan.streak:
                    self.message += (
                        f' before {plan.streak} greedy successes in a row (best streak at the '
                        f'end: {tracker.streak})'
                    )
        self.exit_code = 0
        self.say(f'{self.prog}: {self.message}; stopping')

    def _interrupted(self, signum: int) -> None:
        self._close_bar()
        name = signal.Signals(signum).name
        self.status = 'interrupted'
        self.message = f'interrupted by {name} after {self.tracker.episodes} episodes'
        self.exit_code = EXIT_SIGNAL.get(signum, 1)
        self.say(f'{self.prog}: {self.message}; stopping every node (again to kill them)')

    def _stop_nodes(self, signals: Signals) -> None:
        supervisor = self.supervisor
        if self.monitor is not None:
            self.monitor.frozen = True
        if supervisor is None or not supervisor.nodes:
            return
        for name, node in supervisor.nodes.items():
            self.node_cpu[name] = node.cpu_seconds()
        running = [n for n in STOP_ORDER if n in supervisor.nodes and supervisor.nodes[n].alive]
        if running:
            self.say(f'stopping {", ".join(running)} ...')

        def spin_while_waiting(name: str) -> None:
            # Once the agent is gone (it goes first, at once, so the policy it saves is the one
            # last evaluated), reports still on their way are taken in for summary.json.
            if self.monitor is not None and name != STOP_ORDER[0]:
                with contextlib.suppress(Exception):
                    until = time.monotonic() + DRAIN_TIME
                    while time.monotonic() < until:
                        self.monitor.spin(0.01)

        supervisor.stop(
            STOP_ORDER,
            timeout=lambda name: STOP_TIMEOUTS.get(name, 10.0),
            hurry=signals.hurry,
            on_stop=spin_while_waiting,
        )
        for name, node in supervisor.nodes.items():
            self.node_exits[name] = node.exit_text()
        problems = [n for n in supervisor.unclean() if n.name not in self.crashed]
        if problems:
            for node in problems:
                detail = 'had to be killed' if node.killed else 'did not stop cleanly'
                self.say(f'{self.prog}: {node.name} {detail}: {node.why()}')
            if self.status in ('success', 'budget'):
                self._fail(f'{problems[0].name} did not stop cleanly (see its log)')
        if 'recorder' in supervisor.nodes and supervisor.nodes['recorder'].killed:
            self.say(
                f'{self.prog}: the recording was not closed; `stealth bag recover '
                f'{relative_to_cwd(self.plan.file("recording.mcap"))}` writes an indexed copy'
            )

    # --- outputs ----------------------------------------------------------------------------

    def _policy_check(self) -> dict:
        plan = self.plan
        info = {'path': relative_to_cwd(plan.policy_path)}
        if plan.mode != 'train':
            return info
        from stealth_agent.policy_store import PolicyFileError, load_policy

        if not plan.policy_path.is_file():
            info['saved'] = False
            return info
        try:
            saved = load_policy(plan.policy_path)
        except PolicyFileError as error:
            info.update(saved=False, error=str(error))
            return info
        info.update(
            saved=True,
            learner=saved.learner.name,
            episodes=saved.learner.episodes,
            updates=saved.learner.updates,
            states=len(saved.index),
        )
        last = self.tracker.last_greedy()
        if last is not None and last.learner_updates >= 0:
            info['as_last_evaluated'] = saved.learner.updates == last.learner_updates
            info['updates_since_last_evaluation'] = saved.learner.updates - last.learner_updates
        return info

    def _write_outputs(self) -> None:
        from stealth_bringup.run_outputs import (
            optimal_path,
            plot_learning_curve,
            plot_path,
            write_episodes_csv,
            write_json,
        )

        plan, tracker = self.plan, self.tracker
        files = {}
        records = sorted(tracker.records, key=lambda r: r.episode)
        try:
            optimum_points, optimum = optimal_path(plan.scenario, plan.goal)
        except Exception as error:  # noqa: BLE001 - a baseline must not cost the run its outputs
            self.say(f'{self.prog}: no value-iteration baseline: {error}')
            optimum_points, optimum = None, None
        if records:
            files['episodes'] = write_episodes_csv(records, plan.file('episodes.csv'))
        if records and plan.mode == 'train':
            agent = plan.parameters['agent'].values
            title = f'{plan.title}: {agent.get("agent", "qlearning")}, {len(records)} episodes'
            curve = plot_learning_curve(
                records,
                plan.file('learning_curve.png'),
                title,
                streak_start=tracker.streak_start if self.status == 'success' else None,
                optimal_return=None if optimum is None else optimum.total_reward,
            )
            if curve is not None:
                files['learning_curve'] = curve
        shown = tracker.last_greedy() or (records[-1] if records else None)
        learned = None
        if shown is not None and shown.episode in self.monitor_paths():
            start = plan.scenario.start[:2]
            learned = [tuple(start), *self.monitor_paths()[shown.episode]]
        if shown is not None:
            kind = 'greedy' if shown.greedy else 'last'
            label = (
                f'learned: {kind} episode {shown.episode}, true pose '
                f'({shown.outcome.lower()}, {shown.steps} steps, return {shown.total_reward:.1f})'
            )
            optimum_label = (
                'value-iteration optimum on the lattice'
                if optimum is None
                else f'optimum on the lattice ({optimum.steps} steps, return '
                f'{optimum.total_reward:.1f})'
            )
            try:
                picture = plot_path(
                    plan.scenario,
                    plan.goal,
                    plan.file('path.png'),
                    learned,
                    label,
                    optimum_points,
                    optimum_label,
                    f'{plan.title}: the learned path (true pose) and the optimum',
                )
            except Exception as error:  # noqa: BLE001
                self.say(f'{self.prog}: could not draw path.png: {error}')
                picture = None
            if picture is not None:
                files['path'] = picture
        for key, name in (('recording', 'recording.mcap'), ('policy', 'policy.npz')):
            if plan.file(name).exists():
                files[key] = plan.file(name)
        files['params'] = plan.file('params')
        files['logs'] = plan.file('logs')
        summary = self._summary(records, optimum, files)
        write_json(summary, plan.file('summary.json'))
        self.files = {k: Path(v) for k, v in files.items()}
        self.files['summary'] = plan.file('summary.json')

    def monitor_paths(self) -> dict:
        return self.monitor.paths if self.monitor is not None else {}

    def _summary(self, records, optimum, files) -> dict:
        plan, tracker = self.plan, self.tracker
        agent = plan.parameters['agent'].values
        training = [r for r in records if not r.greedy]
        greedy = [r for r in records if r.greedy]
        steps = sum(r.steps for r in records)
        end = self.stopped_at or time.monotonic()
        run_seconds = end - self.training_started if self.training_started else 0.0
        last = tracker.last_greedy()
        seeds = {
            node: plan.parameters[node].values.get('seed')
            for node in ('simulator', 'environment', 'agent')
        }
        learner_keys = (
            'agent', 'gamma', 'alpha', 'epsilon', 'n', 'initialvalue', 'epsilon_schedule',
            'epsilon_final', 'epsilon_decay_episodes', 'alpha_schedule', 'alpha_final',
            'alpha_decay_episodes',
        )  # fmt: skip
        summary = {
            'status': self.status,
            'message': self.message,
            'mode': plan.mode,
            'command': plan.command_line,
            'scenario': {
                'name': plan.scenario.name,
                'path': str(Path(plan.scenario.path).resolve()),
                'map': str(Path(plan.scenario.map_path).resolve()),
            },
            'goal': plan.goal,
            'seeds': seeds,
            'learner': {k: agent[k] for k in learner_keys if k in agent},
            'simulator': {
                k: plan.parameters['simulator'].values.get(k)
                for k in ('real_time_factor', 'particles', 'physics_dt')
            },
            'episode_budget': plan.episodes,
            'eval_every': plan.eval_every,
            'success_streak': plan.streak,
            'episodes': len(records),
            'training_episodes': len(training),
            'greedy_episodes': len(greedy),
            'steps': steps,
            'outcomes': tracker.outcome_counts(records),
            'success_rate': _rate(records),
            'training_success_rate': _rate(training),
            'greedy_success_rate': _rate(greedy),
            'streak': {
                'length': tracker.streak,
                'began_at_episode': tracker.streak_start,
                'first_success_episode': next((r.episode for r in records if r.success), None),
            },
            'final_greedy': None if last is None else _episode_brief(last),
            # Episodes that ended after the end criterion, before the nodes were stopped (or
            # that the stop cut short: ABORTED): in the recording, not counted here.
            'not_counted': [
                {'episode': f['episode'], 'outcome': f['outcome'], 'steps': f['steps']}
                for f in (self.monitor.late if self.monitor is not None else [])
            ],
            'optimum_on_lattice': None
            if optimum is None
            else {
                'outcome': optimum.outcome.name if optimum.outcome is not None else None,
                'return': optimum.total_reward,
                'steps': optimum.steps,
                'path_length': optimum.path_length,
                'peak_visibility': optimum.peak_visibility,
            },
            # From the command's start to now (nodes stopped, pictures drawn).
            'wall_time_s': round(time.monotonic() - self.started, 2),
            'startup_s': round(self.startup_seconds, 2)
            if math.isfinite(self.startup_seconds)
            else None,
            'run_s': round(run_seconds, 2),
            'steps_per_s': round(steps / run_seconds, 2) if run_seconds > 0 else None,
            'ros_domain_id': self.domain_id,
            'policy': self._policy_check(),
            'nodes': {
                name: {
                    'command': node.command,
                    'exit': self.node_exits.get(name, ''),
                    'cpu_s': self.node_cpu.get(name),
                    'log': relative_to_cwd(node.log_path),
                }
                for name, node in (self.supervisor.nodes.items() if self.supervisor else [])
            },
            'files': {key: relative_to_cwd(value) for key, value in files.items()},
        }
        summary['files']['summary'] = relative_to_cwd(plan.file('summary.json'))
        return summary

    def _closing_summary(self) -> None:
        plan, tracker = self.plan, self.tracker
        records = tracker.records
        lines = []
        elapsed = time.monotonic() - self.started
        verdict = {
            'success': 'done',
            'budget': 'done',
            'interrupted': 'stopped',
            'failed': 'failed',
        }[self.status]
        if self.status != 'failed':  # a failure's one line is on stderr already
            lines.append(f'{self.prog}: {verdict} after {_duration(elapsed)}: {self.message}')
        if records:
            counts = tracker.outcome_counts()
            mix = ', '.join(f'{k.lower()} {v}' for k, v in counts.items() if v)
            steps = sum(r.steps for r in records)
            rate = ''
            if self.training_started and self.stopped_at:
                rate = f' at {steps / max(1e-9, self.stopped_at - self.training_started):.0f}/s'
            greedy = sum(r.greedy for r in records)
            lines.append(
                f'  {len(records)} episodes ({len(records) - greedy} training, {greedy} greedy): '
                f'{mix}; {steps} steps{rate}'
            )
            last = tracker.last_greedy()
            if last is not None:
                lines.append(
                    f'  last greedy episode {last.episode}: {last.outcome.lower()} in '
                    f'{last.steps} steps, return {last.total_reward:.1f}, path '
                    f'{last.path_length:.1f} m, peak visibility {last.peak_visibility:.3f}'
                )
        directory = relative_to_cwd(plan.directory)
        lines.append(f'Files in {directory}/:')
        described = (
            ('recording', 'recording.mcap', 'every topic of the run (MCAP, rosbag2 layout)'),
            ('policy', 'policy.npz', 'the learned Q-table with its settings (resumable)'),
            ('summary', 'summary.json', 'settings, outcomes, timings, file list'),
            ('episodes', 'episodes.csv', 'one row per episode'),
            ('learning_curve', 'learning_curve.png', 'return per episode, outcomes, epsilon'),
            ('path', 'path.png', 'the learned path over the scenario, with the optimum'),
            ('params', 'params/', 'the parameter file each node ran with'),
            ('logs', 'logs/', "each node's log"),
        )
        files = self.files
        for key, name, what in described:
            if key in files and files[key].exists():
                lines.append(f'  {name:<20}{what}')
        if 'recording' in files and files['recording'].exists():
            bag = relative_to_cwd(files['recording'])
            lines.append(f'Replay:    stealth bag play {bag}   (details: stealth bag info {bag})')
        if plan.mode == 'train' and 'policy' in files and records and self.status != 'failed':
            lines.append(f'Evaluate:  stealth eval --run {directory}')
        with contextlib.suppress(OSError, ValueError):
            print('\n'.join(lines), file=self.out, flush=True)


def _rate(records) -> float | None:
    return sum(r.success for r in records) / len(records) if records else None


def _episode_brief(record: EpisodeRecord) -> dict:
    return {
        'episode': record.episode,
        'outcome': record.outcome,
        'return': record.total_reward,
        'steps': record.steps,
        'path_length': record.path_length,
        'peak_visibility': record.peak_visibility,
        'accumulated_visibility': record.accumulated_visibility,
        'final_distance_to_goal': record.final_distance_to_goal,
    }


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f'{seconds:.1f} s'
    minutes, rest = divmod(int(round(seconds)), 60)
    return f'{minutes} min {rest:02d} s'


# --- entry points -------------------------------------------------------------------------------


def _main(mode: str, argv: Sequence[str] | None) -> int:
    started = time.monotonic()
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = train_parser() if mode == 'train' else eval_parser()
    args = parser.parse_args(argv)
    prog = f'stealth {mode}'
    try:
        plan = make_plan(args, mode, argv)
    except RunConfigError as error:
        print(f'{prog}: {error}', file=sys.stderr)
        return 1
    try:
        return Run(plan, started).execute()
    except KeyboardInterrupt:  # outside the run's own signal handling (e.g. while plotting)
        print(f'{prog}: interrupted', file=sys.stderr)
        return 130


def train_main(argv: Sequence[str] | None = None) -> int:
    """`stealth train`: see the module docstring and --help."""
    return _main('train', argv)


def eval_main(argv: Sequence[str] | None = None) -> int:
    """`stealth eval`: see the module docstring and --help."""
    return _main('eval', argv)


if __name__ == '__main__':
    sys.exit(train_main())
