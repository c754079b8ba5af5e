"""Respawn, as launch's `respawn` does: which dead node may be restarted, after how long, the
record of each restart for the run's summary (RespawnPolicy), and the restart itself, which
run_lifecycle asks for when a node of its run died (Respawner). No rclpy.

A node that dies during a run is started again in the same domain with the same parameters, at
most `limit` times per node, each time after a longer wait (RESPAWN_DELAYS), so a node that
keeps crashing costs seconds, not a busy loop. A node that exits with code 2 said it cannot
start with its parameters (stealth_node_kit's EXIT_CANNOT_START): the same parameters would
fail the same way, so it is not restarted; nor is one that exits with EXIT_DISK_FULL (4): its
file would not fit the next time either (run_lifecycle stops the run). What each restart is
given on top of its parameters, and what it is told afterwards, is node-specific: the agent
resumes from its checkpoint, the environment continues the episode numbering, the simulator's
episode is aborted and the recorder writes a new file of the recording.
"""

from __future__ import annotations

import dataclasses
import time

from stealth_node_kit.full_disk import EXIT_DISK_FULL
from stealth_tools.bag_files import next_recording_file

from stealth_bringup.episode_tracker import unfinished_fields
from stealth_bringup.run_config import RunError, relative_to_cwd
from stealth_bringup.run_plan import step_readers

EXIT_CANNOT_START = 2  # stealth_node_kit.running.EXIT_CANNOT_START (bad parameters or input)
RESPAWN_DELAYS = (0.5, 1.0, 2.0, 4.0, 8.0)  # s before the 1st, 2nd, ... restart of a node
LINGER_TIME = 30.0  # s a killed node's endpoints may stay on the graph (its DDS lease)
# A restarted node talks UDP only: the killed process's Fast DDS shared-memory port stays mapped
# by its peers (so it cannot be removed), and a new participant that takes over its port number
# was seen to receive nothing.
RESTARTED_ENVIRONMENT = {'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'}


@dataclasses.dataclass
class Restart:
    """One restart of a node: why, when, and what it cost."""

    node: str
    number: int  # 1 for the node's first restart
    cause: str  # how the process ended, when, and its last log line
    episode: int  # episodes completed when it died
    died_at: float  # s from the run's start, when the death was noticed
    delay: float  # s waited before starting it again
    back_after: float | None = None  # s from the death to the new process answering
    aborted_episode: int | None = None  # the episode the restart ended ABORTED, if any

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


class RespawnPolicy:
    """Bounded restarts with a growing delay, per node."""

    def __init__(self, limit: int, never: tuple[str, ...] = ()):
        self.limit = limit
        self.never = set(never)  # nodes that cannot be restarted here (remote ones)
        self.restarts: list[Restart] = []

    def count(self, node: str) -> int:
        return sum(r.node == node for r in self.restarts)

    def refusal(self, node: str, returncode: int | None) -> str:
        """Why `node`, which ended with `returncode`, is not restarted ('' = it is)."""
        if self.limit <= 0:
            return 'not restarted (--respawn 0)'
        if node in self.never:
            return 'not restarted: it does not run on this host'
        if returncode == EXIT_CANNOT_START:
            return 'not restarted: it cannot start with these parameters'
        if returncode == EXIT_DISK_FULL:
            return 'not restarted: the disk is full'
        done = self.count(node)
        if done >= self.limit:
            return f'not restarted again: it already was {done} times (--respawn {self.limit})'
        return ''

    def delay(self, node: str) -> float:
        """Seconds to wait before the next restart of `node`."""
        return RESPAWN_DELAYS[min(self.count(node), len(RESPAWN_DELAYS) - 1)]

    def begin(self, node: str, cause: str, episode: int, died_at: float) -> Restart:
        restart = Restart(node, self.count(node) + 1, cause, episode, died_at, self.delay(node))
        self.restarts.append(restart)
        return restart

    def died_recently(self, node: str, elapsed: float) -> int:
        """How many processes of `node` died less than LINGER_TIME before `elapsed` (s from the
        run's start): the graph keeps a killed process's endpoints until its DDS lease runs out."""
        return sum(r.node == node and elapsed - r.died_at < LINGER_TIME for r in self.restarts)


class Respawner:
    """Restarts a dead node of a run: waits its delay, starts it again with what it needs to
    carry on the run, waits until it answers, and has the environment end the episode in
    progress where the restarted node cannot carry it on. `run` is run_lifecycle's Run, whose
    plan, policy (respawns), monitor, tracker, supervisor and signals it works with;
    `answer_timeout` is the seconds the environment has to answer rl_env/restart_episode."""

    def __init__(self, run, answer_timeout: float):
        self.run = run
        self.answer_timeout = answer_timeout

    def restart(self, node, during: str) -> None:
        """Start a dead node again (respawn), with what it needs to carry on the run, and tell
        the environment when the episode in progress cannot go on."""
        run = self.run
        name, facts = node.name, run.facts
        cause = node.why(during)
        restart = run.respawns.begin(
            name, cause, run.tracker.episodes, time.monotonic() - facts.started
        )
        run.say(
            f'{run.prog}: {cause}; restarting it in {restart.delay:g} s (restart '
            f'{restart.number} of at most {run.respawns.limit})'
        )
        noticed = time.monotonic()
        until = noticed + restart.delay
        while time.monotonic() < until and run.signals.first is None:
            run.monitor.spin(0.05)  # reports still on their way come in meanwhile
        if run.signals.first is not None:
            return
        run.start(name, self._restart_values(name, restart), RESTARTED_ENVIRONMENT)
        new = run.supervisor.nodes[name]

        def alive() -> bool:
            return new.alive and run.signals.first is None

        if not run.monitor.answers(name, alive, run.plan.startup_timeout):
            if alive():
                raise RunError(
                    f'{name} did not come back within {run.plan.startup_timeout:g} s of its '
                    f'restart (log: {relative_to_cwd(new.log_path)})'
                )
            return  # it died again or a signal came: the next check says which
        if name in ('simulator', 'agent'):
            self._restart_episode(name, restart, node.exit_text())
        restart.back_after = round(time.monotonic() - noticed, 3)
        run.monitor.last_activity = time.monotonic()
        aborted = restart.aborted_episode
        run.say(
            f'{run.prog}: {name} is back after {restart.back_after:.1f} s'
            + (f'; episode {aborted} counted as ABORTED' if aborted is not None else '')
        )

    def _restart_values(self, name: str, restart: Restart) -> dict:
        """What a restarted node gets on top of its parameters file."""
        run = self.run
        monitor = run.monitor
        if name == 'environment':
            # The episode it left has no summary: counted ABORTED from its steps.
            episode = monitor.open_episode()
            if episode is not None:
                fields = unfinished_fields(
                    episode, monitor.steps[episode], run.plan.scenario.start[:2]
                )
                wall_time = time.monotonic() - run.facts.started
                for record in run.tracker.add_summary(fields, wall_time):
                    run.on_record(record)
                restart.aborted_episode = episode
            # Its first steps must reach the monitor and the recorder, as at the start.
            readers = step_readers(run.plan.record)
            return {'first_episode': monitor.next_episode(), 'step_readers': readers}
        if name == 'agent' and run.plan.mode == 'train':
            # Its checkpoint (saved every episode) holds the table, the model, the schedules'
            # position and the random stream.
            return {'load_policy': True, 'first_episode': monitor.next_episode()}
        if name == 'recorder':  # a new file: the dead recorder's is recovered at the end
            run.recording_files.append(next_recording_file(run.plan.directory))
            return {'output': str(run.recording_files[-1].resolve())}
        return {}

    def _restart_episode(self, name: str, restart: Restart, reason: str) -> None:
        """The restarted simulator or agent cannot carry on the episode in progress: the
        environment ends it ABORTED and starts the next."""
        response = self.run.monitor.restart_episode(name, reason, self.answer_timeout)
        if response is None:
            if self.run.signals.first is None:
                raise RunError(
                    f'the environment did not answer rl_env/restart_episode after the {name} '
                    'was restarted; see its log'
                )
            return
        if response.aborted:
            restart.aborted_episode = int(response.episode)
