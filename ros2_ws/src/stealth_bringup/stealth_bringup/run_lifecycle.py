"""A run's processes from start to stop: the private domain, the nodes started in order and
waited for, their parameters checked, the episodes followed until an end criterion, a signal, a
dead node or a stall, then the nodes stopped in order. A node that dies may be started again
(respawn). A --remote node has no process here: its command for the other host is printed, the
run waits for it to join, and its leaving the ROS graph ends the run as a local node's exit
would (remote_nodes). What it finds out goes into RunFacts, from which run_report writes the
outputs; run_monitor watches (see orchestrate for the whole).
"""

from __future__ import annotations

import contextlib
import functools
from pathlib import Path
import signal
import sys
import time

from stealth_node_kit.full_disk import (
    EXIT_DISK_FULL,
    DiskFullError,
    checked_write,
    is_disk_full,
)

from stealth_bringup.episode_scores import EpisodeScorer
from stealth_bringup.episode_tracker import Tracker
from stealth_bringup.remote_nodes import RemoteNodes
from stealth_bringup.respawn import Respawner, RespawnPolicy
from stealth_bringup.run_arguments import prog_of
from stealth_bringup.run_config import (
    ROS_OWN_PARAMETERS,
    STOP_ORDER,
    RunError,
    relative_to_cwd,
    ros_arg_value,
)
from stealth_bringup.run_monitor import (
    ACTION_TOPIC,
    EXIT_SIGNAL,
    Monitor,
    Progress,
    Signals,
    private_ros_context,
)
from stealth_bringup.run_plan import RunPlan
from stealth_bringup.run_report import RunFacts, RunReport

STOP_TIMEOUTS = {'agent': 15.0, 'environment': 10.0, 'simulator': 10.0, 'recorder': 30.0}
# The recorder works off what the others publish; at a lower priority it never delays the
# lockstep agent -> environment -> simulator chain, and catches up while that chain waits.
NICENESS = {'recorder': 10}
PARAMETER_TIMEOUT = 10.0  # s for a node's parameter services to answer
# The environment's start_delay until the recorder subscribes to every topic (then the file's).
HOLD_START_DELAY = 3600.0
DRAIN_TIME = 0.1  # s of taking in late reports before each node is stopped
NAMING_TIME = 2.0  # s for the graph to name the node of a second action publisher


def start_line(local: list[str], remote: tuple[str, ...], composed: bool) -> str:
    """What the run says as it starts its nodes (none here when every one is --remote)."""
    if not local:
        return f'no local nodes to start; waiting for the remote ones: {", ".join(remote)} ...'
    composed_text = ' (the simulator in its process)' if composed else ''
    return f'starting {", ".join(local)}{composed_text} ...'


class Run:
    """One orchestrated run: the nodes' processes from start to stop. What it finds out goes
    into `facts`, from which run_report writes the outputs; run_monitor watches."""

    def __init__(self, plan: RunPlan, started: float | None = None, out=None, err=None):
        self.plan = plan
        self.out = out or sys.stdout
        self.prog = prog_of(plan.mode)
        scorer = EpisodeScorer(plan.scenario, plan.goal, plan.criterion)
        self.tracker = Tracker(plan.episodes, plan.streak or None, scorer)
        self.facts = RunFacts(time.monotonic() if started is None else started)  # command start
        self.progress = Progress(self.tracker, err or sys.stderr)
        self.say = self.progress.say
        self.report = RunReport(plan, self.tracker, self.facts, self.say)
        if plan.continued is not None:  # the earlier part's episodes, streak and clock
            self.tracker.load(plan.continued.records)
        self.supervisor = None
        self.monitor: Monitor | None = None
        self.crashed: set[str] = set()  # nodes that died on their own (reported already)
        self.remote = RemoteNodes(self.say, self.prog)  # --remote nodes, once their command is out
        self.crowded_since: float | None = None  # when a second action publisher showed up
        self.respawns = RespawnPolicy(plan.respawn, never=plan.remote)
        self.respawner = Respawner(self, PARAMETER_TIMEOUT)
        self.signals: Signals | None = None
        # One file per recorder process: this command's first, then one per restart.
        recorder = plan.parameters.get('recorder')
        self.recording_files = [Path(recorder.values['output'])] if recorder else []

    def _fail(self, message: str) -> None:
        if self.facts.disk_full:  # the run stopped for that: what followed is its consequence
            return
        self.facts.status, self.facts.message, self.facts.exit_code = 'failed', message, 1

    def disk_full(self, error: DiskFullError) -> None:
        """A file of the run could not be written for want of space: the one line, and the run
        stops (the nodes in order, every output that still fits written; exit EXIT_DISK_FULL)."""
        if self.facts.disk_full:
            return
        self.facts.disk_full = str(error)
        self.facts.status, self.facts.message = 'failed', str(error)
        self.facts.exit_code = EXIT_DISK_FULL
        self.say(f'{self.prog}: {error}; stopping')

    def execute(self) -> int:
        """The whole run; its exit status."""
        from stealth_bringup.ros_domain import shm_segments

        try:
            params = self.plan.directory / 'params'
            with checked_write(params, relative_to_cwd(params)):
                self.plan.write_params_files()
        except DiskFullError as error:
            self.disk_full(error)
            self.report.print_closing({}, self.out)
            return self.facts.exit_code
        for note in self.plan.notes:
            self.say(f'{self.prog}: {note}')
        self._remove_dead_shm()
        shm_before = shm_segments()
        facts = self.facts
        with Signals() as signals:
            self._write_progress()  # a run directory from the start, whatever happens next
            self._run(signals, shm_before)
            if facts.status == 'failed' and not facts.disk_full:  # that line was said already
                self.say(f'{self.prog}: {facts.message}')
            if self.monitor is not None:
                facts.paths, facts.late = self.monitor.paths, self.monitor.late
                facts.episode_ends = self.monitor.ended
            facts.remote = {name: node.summary() for name, node in self.remote.items()}
            facts.nodes = dict(self.supervisor.nodes) if self.supervisor else {}
            facts.restarts = [restart.as_dict() for restart in self.respawns.restarts]
            # A signal now changes nothing: the files get written.
            self.report.print_closing(self.report.write(), self.out)
        return facts.exit_code

    def _remove_dead_shm(self) -> None:
        """Fast DDS files in /dev/shm that an earlier run's killed processes left: named, gone."""
        from stealth_bringup.ros_domain import remove_dead_shm

        removed = remove_dead_shm()
        if removed:
            self.say(
                f'{self.prog}: removed {len(removed)} Fast DDS files of dead processes from '
                f'/dev/shm: {", ".join(removed)}'
            )

    def _write_progress(self) -> None:
        """summary.json as the run stands; a full disk stops the run."""
        if self.plan.mode != 'train':
            return
        self.facts.restarts = [restart.as_dict() for restart in self.respawns.restarts]
        try:
            self.report.write_progress()
        except DiskFullError as error:
            self.disk_full(error)
        except OSError as error:
            self.say(f'{self.prog}: could not write summary.json: {error}')

    def on_record(self, record) -> None:
        """An episode is complete: the progress bar, its row of episodes.csv at once, and after
        a greedy evaluation summary.json, so a killed orchestrator leaves them."""
        from stealth_bringup.run_outputs import append_episode

        self.progress.on_record(record)
        if self.facts.disk_full:  # the run is stopping: the final report writes what fits
            return
        try:
            append_episode(record, self.plan.file('episodes.csv'))
        except DiskFullError as error:
            self.disk_full(error)
            return
        except OSError as error:
            self.say(f'{self.prog}: could not append to episodes.csv: {error}')
        if record.greedy:
            self._write_progress()

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
        self.signals = signals
        with contextlib.ExitStack() as stack:
            try:
                domain_id = stack.enter_context(reserved_domain_id())
            except DomainError as error:
                self._fail(str(error))
                return
            self.facts.domain_id = domain_id
            env = private_environment(domain_id, discovery=plan.discovery)
            self.supervisor = Supervisor(env, plan.directory / 'logs')
            self._announce()
            context = None
            try:
                context = private_ros_context(domain_id, plan.discovery)
                # A continued run's episode times go on from where its earlier part stopped.
                offset = max((r.wall_time for r in self.tracker.records), default=0.0)
                self.monitor = Monitor(
                    context, self.tracker, self.facts.started - offset, self.on_record
                )
                self._start_nodes(signals)
                self._follow(signals)
            except RunError as error:
                self._fail(str(error))
            finally:
                self.progress.close()
                self.facts.stopped_at = time.monotonic()
                self._stop_nodes(signals)
                self.remote.remind(plan.mode, plan.policy_path)
                if self.monitor is not None:
                    self.monitor.close()
                if context is not None:
                    context.try_shutdown()
            if self.supervisor.any_killed:
                removed = remove_orphaned_shm(shm_before)
                if removed:
                    self.say(f'{self.prog}: removed {len(removed)} shared-memory segments of '
                             'killed nodes from /dev/shm')  # fmt: skip

    def _announce(self) -> None:
        self.say(f'{self.prog}: {self.plan.describe()}')
        directory = relative_to_cwd(self.plan.directory)
        discovery = '' if self.plan.discovery == 'localhost' else ', discovery subnet'
        self.say(f'run directory: {directory} (ROS_DOMAIN_ID {self.facts.domain_id}{discovery})')

    def _held_values(self, name: str) -> dict:
        """Parameters a node starts with on top of its file, for the run to change later."""
        if name == 'environment' and self.plan.record:  # on hold until the recorder listens
            return {'start_delay': HOLD_START_DELAY}
        return {}

    def start(self, name: str, values: dict | None = None, env: dict | None = None) -> None:
        """Start a node with its parameters file and `values` on top (default: the values it
        is held with at the run's start), `env` on top of the run's environment."""
        plan = self.plan
        command = plan.commands[name] + plan.ros_args(name)
        values = self._held_values(name) if values is None else values
        for key, value in values.items():
            command += ['-p', f'{key}:={ros_arg_value(value)}']
        try:
            self.supervisor.start(name, command, niceness=NICENESS.get(name, 0), env=env)
        except OSError as error:
            if is_disk_full(error):  # its log file
                log = self.plan.directory / 'logs' / f'{name}.log'
                self.disk_full(DiskFullError(log, relative_to_cwd(log)))
            raise RunError(f'{name}: cannot start {command[0]}: {error.strerror}') from None

    def _check_processes(self, during: str) -> None:
        """A local node that exited, a remote one that left the graph, a second agent: the run
        cannot go on (RunError)."""
        if self.facts.disk_full:
            raise RunError(self.facts.disk_full)
        dead = self.supervisor.dead()
        if dead:
            node = dead[0]
            if node.process.returncode == EXIT_DISK_FULL:
                self.crashed.add(node.name)
                self.disk_full(self._full_disk_of(node.name))
                raise RunError(self.facts.disk_full)
            refusal = self.respawns.refusal(node.name, node.process.returncode)
            if not refusal:
                self.respawner.restart(node, during)
                return
            self.crashed.update(n.name for n in dead)
            log = relative_to_cwd(node.log_path)
            restarted = f'; {refusal}' if self.respawns.count(node.name) else ''
            raise RunError(f'{node.why(during)} (log: {log}){restarted}')
        if self.remote:
            self.remote.check(self.monitor.node_names(), during)
        self._check_one_agent()

    def _full_disk_of(self, name: str) -> DiskFullError:
        """The file a node that stopped on a full disk could not write: the agent's policy,
        the recorder's recording, else the node's log."""
        path = self.plan.directory / 'logs' / f'{name}.log'
        if name == 'agent' and self.plan.mode == 'train':
            path = self.plan.policy_path
        elif name == 'recorder' and self.recording_files:
            path = self.recording_files[-1]
        return DiskFullError(path, relative_to_cwd(path))

    def _check_one_agent(self) -> None:
        """Two publishers of the actions: two agents answer every state (RunError), once the
        graph names both (or after NAMING_TIME)."""
        agents = self.monitor.publishers_of(ACTION_TOPIC)
        now = time.monotonic()
        if len(agents) <= 1 or self._killed_agent_lingers(agents, now):
            self.crowded_since = None
            return
        self.crowded_since = self.crowded_since or now
        if None in agents and now - self.crowded_since < NAMING_TIME:
            return
        names = ', '.join(name or '(a node not named on the graph)' for name in agents)
        raise RunError(
            f'a second agent joined the run: {ACTION_TOPIC} has {len(agents)} publishers '
            f'(nodes {names}); a run takes one agent, stop the one that does not belong and '
            'start the run again'
        )

    def _killed_agent_lingers(self, agents: list, now: float) -> bool:
        """Whether the extra publishers can be agents that died recently (respawn)."""
        recent = self.respawns.died_recently('agent', now - self.facts.started)
        return len(agents) <= 1 + recent and set(agents) <= {'/agent', None}

    def _wait(
        self, signals: Signals, what: str, ready, deadline: float, during: str, too_late=None
    ) -> None:
        """Spin until ready() or the deadline; a signal or a dead node ends it at once.
        too_late(missing) is the message at the deadline (default: `what` not up in time)."""
        while True:
            self._check_processes(during)
            if signals.first is not None:
                return
            missing = ready()
            if not missing:
                return
            if time.monotonic() >= deadline:
                raise RunError(
                    too_late(missing)
                    if too_late is not None
                    else f'{what} not up within {self.plan.startup_timeout:g} s: still waiting '
                    f'for {missing} (logs: {relative_to_cwd(self.plan.directory / "logs")})'
                )
            self.monitor.spin()

    def _start_nodes(self, signals: Signals) -> None:
        """Start every node, wait until all are on the graph with the simulator's services, check
        their parameter names, and (when recording) release the first episode only once the
        recorder listens to every topic, so the recording misses nothing."""
        plan, monitor = self.plan, self.monitor
        deadline = time.monotonic() + plan.startup_timeout
        names = [n for n in plan.nodes if n in plan.commands]
        self.say(start_line(names, plan.remote, plan.composed))
        for name in names:
            self.start(name)
        for name in plan.remote:
            values = {**plan.parameters[name].values, **self._held_values(name)}
            domain_id = self.facts.domain_id
            self.remote.announce(name, values, domain_id, plan.discovery, plan.join_timeout)

        local = [n for n in plan.nodes if n not in plan.remote]
        up = functools.partial(monitor.not_up, local)
        self._wait(signals, 'the system', up, deadline, 'during startup')
        if self.remote and signals.first is None:
            join_deadline = max(node.since for node in self.remote.values()) + plan.join_timeout
            too_late = functools.partial(
                self.remote.join_timeout, domain_id=self.facts.domain_id, timeout=plan.join_timeout
            )
            self._wait(
                signals, 'the remote nodes', self.remote.not_joined, join_deadline,
                f'while waiting for {", ".join(self.remote)} to join', too_late,
            )  # fmt: skip
            deadline = time.monotonic() + plan.startup_timeout  # for what the joined ones bring
            up = functools.partial(monitor.not_up, plan.nodes)
            self._wait(signals, 'the system', up, deadline, 'during startup')
        if signals.first is not None:
            return
        if not plan.record:  # the environment is not held: its episodes begin now
            self.facts.released = time.monotonic()
        self._check_parameter_names(signals)
        if plan.record and signals.first is None:
            recorded = functools.partial(
                monitor.not_recorded, ('simulator', 'environment', 'agent')
            )
            self._wait(signals, 'the recording', recorded, deadline, 'during startup')
            if signals.first is None:
                self._release_first_episode()
                self.facts.released = time.monotonic()
        self.facts.startup_seconds = time.monotonic() - self.facts.started
        self.say(f'all nodes up after {self.facts.startup_seconds:.1f} s')
        if self.plan.watch_port is not None:
            self.say(
                f'watch live: in Foxglove, Open connection > Foxglove WebSocket > '
                f'ws://localhost:{self.plan.watch_port} (layout: docs/foxglove/stealth-nav.json)'
            )

    def _release_first_episode(self) -> None:
        """Give the environment its configured start_delay back (it started on hold)."""
        value = float(self.plan.parameters['environment'].values.get('start_delay', 0.0))
        if not self.monitor.set_parameter('environment', 'start_delay', value, PARAMETER_TIMEOUT):
            self.say(f'{self.prog}: could not set environment start_delay to {value:g}')

    def _check_parameter_names(self, signals: Signals) -> None:
        """A parameter a node does not declare would be ignored without a word (a typo in
        --set, a file for another version): every one given must exist."""
        plan = self.plan
        for name in plan.nodes:
            if signals.first is not None:
                continue
            if name in self.remote:

                def alive(name=name) -> bool:
                    return name in self.monitor.node_names() and signals.first is None
            else:
                process = self.supervisor.nodes[plan.process_of(name)]

                def alive(node=process) -> bool:
                    return node.alive and signals.first is None

            declared = self.monitor.parameter_names(name, alive, PARAMETER_TIMEOUT)
            self._check_processes('during startup')
            if declared is None:
                if signals.first is None:
                    self.say(f'{self.prog}: {name} does not list its parameters; not checked')
                continue
            unknown = sorted(set(plan.parameters[name].values) - declared)
            if unknown:
                source = relative_to_cwd(plan.params_file(name))
                raise RunError(
                    f'{name} has no parameter {", ".join(map(repr, unknown))} (in {source}); '
                    f'its parameters: {", ".join(sorted(declared - ROS_OWN_PARAMETERS))}'
                )

    def _follow(self, signals: Signals) -> None:
        """Spin until an end criterion, a signal, a dead node or a stall."""
        plan, monitor = self.plan, self.monitor
        if signals.first is not None:
            self._interrupted(signals.first)
            return
        self.facts.training_started = time.monotonic()
        monitor.last_activity = self.facts.training_started
        self.progress.start(plan.episodes, self.tracker.episodes)
        while True:
            if signals.first is not None:
                self._interrupted(signals.first)
                return
            self._check_processes(f'during the run (episode {self.tracker.episodes})')
            reason = self.tracker.stop_reason()
            if reason is not None:
                message = self.tracker.end_message(reason, evaluating=plan.mode == 'eval')
                self._end('success' if reason == 'streak' else 'budget', message, 0, 'stopping')
                return
            idle = time.monotonic() - monitor.last_activity
            if idle > plan.stall_timeout:
                raise RunError(
                    f'no step for {idle:.0f} s (episode {self.tracker.episodes}): the system is '
                    f'stuck; see the logs in {relative_to_cwd(plan.directory / "logs")}'
                )
            monitor.spin()

    def _end(self, status: str, message: str, exit_code: int, then: str) -> None:
        """The run is over (the nodes still run): the bar goes, the reason is said."""
        self.progress.close()
        self.facts.status, self.facts.message, self.facts.exit_code = status, message, exit_code
        self.say(f'{self.prog}: {message}; {then}')

    def _interrupted(self, signum: int) -> None:
        name = signal.Signals(signum).name
        message = f'interrupted by {name} after {self.tracker.episodes} episodes'
        then = 'stopping every node (again to kill them)'
        self._end('interrupted', message, EXIT_SIGNAL.get(signum, 1), then)

    def _stop_nodes(self, signals: Signals) -> None:
        supervisor = self.supervisor
        if self.monitor is not None:
            self.monitor.frozen = True
        if supervisor is None or not supervisor.nodes:
            return
        for name, node in supervisor.nodes.items():
            self.facts.node_cpu[name] = node.cpu_seconds()
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
            self.facts.node_exits[name] = node.exit_text()
            if node.process.returncode == EXIT_DISK_FULL and name not in self.crashed:
                self.crashed.add(name)  # e.g. the agent's last save, as it was stopped
                self.disk_full(self._full_disk_of(name))
        problems = [n for n in supervisor.unclean() if n.name not in self.crashed]
        if problems:
            for node in problems:
                detail = 'had to be killed' if node.killed else 'did not stop cleanly'
                self.say(f'{self.prog}: {node.name} {detail}: {node.why()}')
            if self.facts.status in ('success', 'budget'):
                self._fail(f'{problems[0].name} did not stop cleanly (see its log)')
        self._recover_recordings()

    def _recover_recordings(self) -> None:
        """A recording file whose recorder was killed has no index: rewrite it complete and
        indexed (everything readable in it), so every file of the recording opens."""
        from stealth_tools.bag_format import BagError
        from stealth_tools.bag_recover import recover

        from stealth_bringup.supervisor import CLEAN_EXITS

        recorders = [n for n in self.supervisor.retired if n.name == 'recorder']
        if 'recorder' in self.supervisor.nodes:
            recorders.append(self.supervisor.nodes['recorder'])
        for node, path in zip(recorders, self.recording_files, strict=False):
            if not path.exists() or (not node.killed and node.process.returncode in CLEAN_EXITS):
                continue
            shown = relative_to_cwd(path)
            if node.process.returncode == EXIT_DISK_FULL:  # its recovery would not fit either
                self.facts.incomplete[path] = (
                    'cut short: the disk is full; '
                    f'`stealth bag recover {shown}` reads what it holds'
                )
                continue
            temporary = path.with_name(f'.{path.name}.recovering')
            temporary.unlink(missing_ok=True)
            try:
                _, report = recover(path, temporary)
            except (BagError, OSError) as error:
                temporary.unlink(missing_ok=True)
                why = 'the disk is full' if is_disk_full(error) else str(error)
                self.facts.incomplete[path] = (
                    f'not closed ({why}): `stealth bag recover {shown}` reads what it holds'
                )
                self.say(
                    f'{self.prog}: the recording {shown} was not closed and could not be '
                    f'recovered ({why}); `stealth bag recover {shown}` tries again'
                )
                continue
            temporary.replace(path)
            self.say(f'{self.prog}: {shown} was not closed (its recorder was killed): '
                     f'recovered {report.messages} messages into an indexed file')  # fmt: skip
