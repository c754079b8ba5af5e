"""Watching a run from inside: the signals that stop it, the orchestrator's own rclpy node
(graph queries, the episode reports, parameter services) and the progress bar.

The orchestrator's participant talks UDP only, in the run's private domain, with rclpy's own
signal handling off: SIGINT, SIGTERM and SIGHUP are only noted (Signals), so that the run can
stop its nodes in order and still write its outputs.
"""

from __future__ import annotations

import contextlib
import os
import signal
import time

from stealth_node_kit import rl_contract

from stealth_bringup.episode_tracker import EpisodeRecord, Tracker, agent_fields, summary_fields

SPIN_PERIOD = 0.1  # s: how long a signal or a dead node can go unnoticed
PLAUSIBLE_DELAY = 600.0  # s a report may have waited in its queue (sent_at)
EXIT_SIGNAL = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGHUP: 129}
GRAPH_TOPICS_IGNORED = {'/rosout', '/parameter_events'}
# The system is up once they are there.
SIMULATOR_SERVICES = tuple(rl_contract.absolute(name) for name in rl_contract.SIMULATOR_SERVICES)
ACTION_TOPIC = rl_contract.absolute(rl_contract.ACTION)  # one publisher: the run's agent
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'  # rmw's name of a node whose endpoints came first
# The environment's, for a respawned node.
RESTART_SERVICE = rl_contract.absolute(rl_contract.RESTART_EPISODE)


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


def private_ros_context(domain_id: int, discovery: str = 'localhost'):
    """An initialised rclpy context of this process in the run's domain and discovery range,
    without rclpy's signal handlers (Signals has them)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from stealth_bringup.ros_domain import DISCOVERY_RANGES

    os.environ['ROS_DOMAIN_ID'] = str(domain_id)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = DISCOVERY_RANGES[discovery]
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


def sent_at(info: dict, now: float) -> float:
    """When a message taken at monotonic `now` was published, in monotonic s, from its DDS
    source timestamp (system clock ns; rclpy's message info); `now` where there is none or it
    is not plausible (another host's clock ahead, or far behind)."""
    source = info.get('source_timestamp') if isinstance(info, dict) else None
    if not source:
        return now
    delay = (time.time_ns() - source) / 1e9
    return now - delay if 0.0 <= delay <= PLAUSIBLE_DELAY else now


# --- the monitor node ----------------------------------------------------------------------------


class Monitor:
    """The orchestrator's rclpy side: graph queries and the episode reports."""

    def __init__(self, context, tracker: Tracker, started: float, on_record):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
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
        # (reward, visibility, distance to goal, x, y) of each step, by episode: what is known
        # of an episode whose environment died before its summary.
        self.steps: dict[int, list[tuple]] = {}
        self.frozen = False  # set when the run ends: later reports are not counted
        # When each counted episode's summary was sent (monotonic s): a report may wait in its
        # queue while the orchestrator checks the nodes' parameters, and episodes run meanwhile.
        self.ended: dict[int, float] = {}
        self.late: list[dict] = []  # summaries that arrived after that
        self._restart_client = None  # rl_env/restart_episode, once a node was respawned
        # Transient local: the reports' writers keep their latest messages, and after a node
        # restarts DDS may match its writer with this reader only after its first reports.
        qos = rl_contract.REPORT_READER_QOS
        self.node.create_subscription(
            EpisodeSummary, rl_contract.EPISODE_SUMMARY, self._on_summary, qos
        )
        self.node.create_subscription(
            AgentEpisodeInfo, rl_contract.AGENT_EPISODE_INFO, self._on_agent_info, qos
        )
        self.node.create_subscription(StepInfo, rl_contract.STEP_INFO, self._on_step, qos)

    def close(self) -> None:
        self.executor.remove_node(self.node)
        self.executor.shutdown()
        self.node.destroy_node()

    def spin(self, timeout: float = SPIN_PERIOD) -> None:
        self.executor.spin_once(timeout_sec=timeout)

    def _elapsed(self) -> float:
        return time.monotonic() - self.started

    def _ended(self) -> bool:
        """The run has ended, or its end criterion holds and the run loop has yet to see it:
        one spin can take in the reports of several fast episodes, and those after the
        budget or the streak are not the run's."""
        return self.frozen or self.tracker.stop_reason() is not None

    def _on_summary(self, msg, info) -> None:
        self.last_activity = time.monotonic()
        if self._ended():  # an episode after the end, or cut short by it
            self.late.append(summary_fields(msg))
            return
        self.ended.setdefault(int(msg.episode), sent_at(info, self.last_activity))
        for record in self.tracker.add_summary(summary_fields(msg), self._elapsed()):
            self.on_record(record)

    def _on_agent_info(self, msg) -> None:
        self.last_activity = time.monotonic()
        if self._ended():
            return
        fields = agent_fields(msg)
        for record in self.tracker.add_agent_info(int(msg.episode), fields, self._elapsed()):
            self.on_record(record)

    def _on_step(self, msg) -> None:
        self.last_activity = time.monotonic()
        self.paths.setdefault(msg.episode, []).append((msg.true_pose.x, msg.true_pose.y))
        self.steps.setdefault(msg.episode, []).append(
            (msg.reward, msg.visibility, msg.distance_to_goal, msg.true_pose.x, msg.true_pose.y)
        )
        if self._ended():
            return
        estimate = msg.estimated_pose  # with the action: the episode's scores
        steps = self.tracker.add_step(
            msg.episode, msg.action, estimate.x, estimate.y, self._elapsed()
        )
        for record in steps:
            self.on_record(record)

    # --- the graph --------------------------------------------------------------------------

    def node_names(self) -> set[str]:
        return {name for name, namespace in self.node.get_node_names_and_namespaces()
                if namespace == '/'}  # fmt: skip

    def publishers_of(self, topic: str) -> list[str | None]:
        """The nodes publishing `topic`, one entry per publisher (two agents both named 'agent'
        are two entries); None for one whose node is not known yet (its endpoint is discovered
        before its node's name)."""
        names = [
            None
            if info.node_name == UNKNOWN_NODE
            else f'{info.node_namespace.rstrip("/")}/{info.node_name}'
            for info in self.node.get_publishers_info_by_topic(topic)
        ]
        return sorted(names, key=lambda name: name or '~')

    def services_of(self, node_name: str) -> set[str]:
        with contextlib.suppress(Exception):  # the node may not be there yet
            return {
                name for name, _ in self.node.get_service_names_and_types_by_node(node_name, '/')
            }
        return set()

    def _parameter_service(self, node_name: str, call, timeout: float, alive=lambda: True):
        """The response to call(client) of a node's parameter services, None if it does not
        come within `timeout` s; alive() false stops waiting."""
        from rclpy.parameter_client import AsyncParameterClient

        client = AsyncParameterClient(self.node, node_name)
        deadline = time.monotonic() + timeout
        while not client.services_are_ready():
            if time.monotonic() >= deadline or not alive():
                return None
            self.spin()
        future = call(client)
        while not future.done():
            if time.monotonic() >= deadline or not alive():
                return None
            self.spin()
        return future.result()

    def parameter_names(self, node_name: str, alive, timeout: float) -> set[str] | None:
        """The parameters `node_name` declares (its list_parameters service), None if the
        service does not answer within `timeout` s; alive() false stops waiting."""
        response = self._parameter_service(
            node_name, lambda client: client.list_parameters(), timeout, alive
        )
        return None if response is None else set(response.result.names)

    def answers(self, node_name: str, alive, timeout: float, resend: float = 1.0) -> bool:
        """Whether `node_name` answers its list_parameters service within `timeout` s (alive()
        false stops waiting). The request goes again every `resend` s: after a restart the
        graph still lists the dead process's service, and a request sent before the new one
        is matched reaches only the dead one."""
        from rcl_interfaces.srv import ListParameters

        client = self.node.create_client(ListParameters, f'/{node_name}/list_parameters')
        try:
            deadline = time.monotonic() + timeout
            future, sent = None, 0.0
            while time.monotonic() < deadline and alive():
                if future is not None and future.done() and future.result() is not None:
                    return True
                if client.service_is_ready() and time.monotonic() - sent >= resend:
                    if future is not None:
                        client.remove_pending_request(future)
                    future, sent = client.call_async(ListParameters.Request()), time.monotonic()
                self.spin(0.05)
            return False
        finally:
            self.node.destroy_client(client)

    def set_parameter(self, node_name: str, name: str, value, timeout: float) -> bool:
        """Set one parameter of a node; True when it took it."""
        from rclpy.parameter import Parameter

        parameters = [Parameter(name, value=value)]
        response = self._parameter_service(
            node_name, lambda client: client.set_parameters(parameters), timeout
        )
        return bool(response is not None and all(r.successful for r in response.results))

    def restart_episode(self, restarted: str, reason: str, timeout: float):
        """Ask the environment to end the episode a restarted node (`restarted`: 'simulator'
        or 'agent') left behind; its RestartEpisode response, None without one in `timeout`."""
        from stealth_interfaces.srv import RestartEpisode

        if self._restart_client is None:
            self._restart_client = self.node.create_client(RestartEpisode, RESTART_SERVICE)
        client = self._restart_client
        request = RestartEpisode.Request(
            restarted=getattr(RestartEpisode.Request, restarted.upper()), reason=reason
        )
        deadline = time.monotonic() + timeout
        while not client.service_is_ready():
            if time.monotonic() >= deadline:
                return None
            self.spin()
        future = client.call_async(request)
        while not future.done():
            if time.monotonic() >= deadline:
                client.remove_pending_request(future)
                return None
            self.spin()
        return future.result()

    def open_episode(self) -> int | None:
        """The latest episode with steps but no completed record: the one a dead environment
        left unfinished; None when there is none."""
        done = {record.episode for record in self.tracker.records}
        return max((episode for episode in self.steps if episode not in done), default=None)

    def next_episode(self) -> int:
        """The number the next episode of the run takes: after every episode completed or
        stepped in so far."""
        numbers = [record.episode for record in self.tracker.records] + list(self.paths)
        return max(numbers, default=-1) + 1

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

    def not_up(self, names) -> str:
        """What of the system is not on the graph yet ('' once every node in `names` is, with
        the simulator's services when it is one of them)."""
        seen = self.node_names()
        missing = [n for n in names if n not in seen]
        if missing:
            return 'node ' + ', '.join(missing)
        if 'simulator' not in names:
            return ''
        wanted = set(SIMULATOR_SERVICES) - self.services_of('simulator')
        if wanted:
            return 'simulator services ' + ', '.join(sorted(wanted))
        return ''

    def not_recorded(self, names) -> str:
        """What the recorder does not subscribe to yet ('' once it listens to every topic)."""
        for name in names:
            unrecorded = self.unrecorded_topics(name)
            if unrecorded:
                return f'the recorder to subscribe to {", ".join(unrecorded)} ({name})'
        return ''


# --- the progress bar ----------------------------------------------------------------------------


class Progress:
    """The episode bar on stderr, with the run's messages above it; without a terminal, plain
    lines instead (every greedy evaluation and every tenth episode)."""

    def __init__(self, tracker: Tracker, err):
        self.tracker = tracker
        self.err = err
        self.bar = None

    def say(self, text: str) -> None:
        """A line on stderr (above the progress bar); a terminal that went away is no error."""
        with contextlib.suppress(OSError, ValueError):
            if self.bar is not None and not self.bar.disable:
                self.bar.write(text, file=self.err)
            else:
                print(text, file=self.err, flush=True)

    def start(self, total: int, done: int = 0) -> None:
        """The bar of `total` episodes, `done` of them before (a continued run)."""
        from tqdm import tqdm

        self.bar = tqdm(
            total=total,
            initial=done,
            unit='ep',
            desc='episodes',
            dynamic_ncols=True,
            file=self.err,
            disable=None,  # no bar when stderr is not a terminal: plain lines instead
            smoothing=0.1,
            # No time left: the budget is an upper bound, most runs end on the streak.
            bar_format='{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, {rate_fmt}{postfix}]',
        )

    def on_record(self, record: EpisodeRecord) -> None:
        tracker = self.tracker
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix_str(tracker.postfix(), refresh=False)
            if self.bar.disable and (record.greedy or tracker.episodes % 10 == 0):
                what = 'greedy evaluation' if record.greedy else 'training'
                verdict = ''
                if record.greedy and tracker.scorer is not None:
                    met = 'meets' if record.meets_criterion else 'misses'
                    verdict = f', {met} the criterion'
                print(
                    f'episode {record.episode} ({what}): {record.outcome.lower()} in '
                    f'{record.steps} steps, return {record.total_reward:.1f}{verdict}; '
                    f'{tracker.postfix()}',
                    file=self.err,
                    flush=True,
                )

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
