"""Node processes of a run: started from the install space, each in its own process group with
its output in a log file, watched, and stopped in order. No rclpy.

Each node runs in a session of its own, so a Ctrl-C in the terminal reaches only the
orchestrator, which then stops the nodes in its order; the kernel sends a node SIGTERM if the
orchestrator itself dies (PR_SET_PDEATHSIG), so nothing outlives a run. Stopping is SIGINT to
the node's process group, a wait, then SIGKILL; whoever had to be killed is remembered so the
caller can clean up the shared memory it left.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import contextlib
import dataclasses
import os
from pathlib import Path
import re
import signal
import subprocess
import time

from stealth_node_kit.orphan_watch import die_with_parent

CLEAN_EXITS = (0, -signal.SIGINT, -signal.SIGTERM, 130, 143)
_LOG_PREFIX = re.compile(r'^\[(\w+)\] \[[0-9.]+\] \[([^\]]+)\]: ')
_RESTART_MARK = re.compile(r'^--- \w+ started again: ')  # Supervisor.start's, in a log
_MARKERS = re.compile(r'^\s*[\^~]+[\s\^~]*$')  # a traceback's column markers (3.11+)
_TRACEBACK = re.compile(r'^Traceback \(most recent call last\):')
_FRAME = re.compile(r'^\s+File "')


def _preexec(niceness: int = 0) -> Callable[[], None]:
    """A preexec function that lowers the priority by `niceness` and asks for SIGTERM when the
    parent dies (``orphan_watch.die_with_parent``)."""
    return die_with_parent((lambda: os.nice(niceness)) if niceness else None)


def last_line(path: Path, limit: int = 64 * 1024) -> str:
    """The last message of a log file, without rcutils' '[LEVEL] [time]' prefix: from the
    latest process only (after the last RESTART_MARK), never a traceback's ^^^ marker line; a
    log that ends inside a traceback (cut short: its exception line never made it, as on a
    full disk) says so with the last frame."""
    try:
        with open(path, 'rb') as stream:
            stream.seek(0, os.SEEK_END)
            size = stream.tell()
            stream.seek(max(0, size - limit))
            text = stream.read().decode(errors='replace')
    except OSError:
        return ''
    lines = [line.rstrip() for line in text.splitlines()]
    marks = [k for k, line in enumerate(lines) if _RESTART_MARK.match(line)]
    if marks:  # what the processes before the latest one wrote is not about this one
        lines = lines[marks[-1] + 1 :]
    lines = [line for line in lines if line.strip() and not _MARKERS.match(line)]
    if not lines:
        return ''
    line = lines[-1]
    if line[0].isspace() and any(_TRACEBACK.match(text) for text in lines):
        frame = next((text.strip() for text in reversed(lines) if _FRAME.match(text)), '')
        return 'its log ends inside a Python traceback (cut short)' + (
            f' at {frame}' if frame else ''
        )
    line = line.strip()
    match = _LOG_PREFIX.match(line)
    return f'[{match.group(1)}] {line[match.end() :]}' if match else line


def exit_description(returncode: int) -> str:
    """'exited with code 2', 'was killed by SIGSEGV'."""
    if returncode < 0:
        try:
            return f'was killed by {signal.Signals(-returncode).name}'
        except ValueError:
            return f'was killed by signal {-returncode}'
    return f'exited with code {returncode}'


@dataclasses.dataclass
class NodeProcess:
    """One running node."""

    name: str
    command: list[str]
    log_path: Path
    process: subprocess.Popen
    started: float  # time.monotonic()
    killed: bool = False  # SIGKILLed by us (it cannot have cleaned up its shared memory)
    stopping: bool = False  # we asked it to stop
    ended: float | None = None  # time.monotonic() when it was first seen ended

    @property
    def pid(self) -> int:
        return self.process.pid

    def poll(self) -> int | None:
        returncode = self.process.poll()
        if returncode is not None and self.ended is None:
            self.ended = time.monotonic()
        return returncode

    @property
    def alive(self) -> bool:
        return self.poll() is None

    def exit_text(self) -> str:
        """'exited with code 0', 'was killed by SIGKILL', 'is running'."""
        returncode = self.process.returncode
        return exit_description(returncode) if returncode is not None else 'is running'

    def why(self, during: str = '') -> str:
        """One line: how it ended, when, after how long, and the last line of its log."""
        seconds = (self.ended or time.monotonic()) - self.started
        line = last_line(self.log_path)
        when = f' {during}' if during else ''
        return f'{self.name} {self.exit_text()}{when} after {seconds:.1f} s' + (
            f': {line}' if line else ''
        )

    def cpu_seconds(self) -> float | None:
        """User + system CPU time the process has used so far (None once it is gone)."""
        try:
            fields = Path(f'/proc/{self.process.pid}/stat').read_text().rsplit(')', 1)[1].split()
        except (OSError, IndexError):
            return None
        ticks = os.sysconf('SC_CLK_TCK')
        return (int(fields[11]) + int(fields[12])) / ticks  # utime, stime (fields 14, 15)

    def signal_group(self, signum: int) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.process.pid, signum)


class Supervisor:
    """Starts node processes and guarantees they are all gone at the end."""

    def __init__(self, env: dict[str, str], log_dir: Path):
        self.env = env
        self.log_dir = Path(log_dir)
        self.nodes: dict[str, NodeProcess] = {}  # the latest process of each node
        self.retired: list[NodeProcess] = []  # processes of nodes that were started again

    def start(
        self, name: str, command: list[str], niceness: int = 0, env: dict | None = None
    ) -> NodeProcess:
        """Start one node (`niceness` lower in priority, `env` on top of the run's environment);
        OSError (e.g. not executable) is the caller's to report. A node started again appends
        to its log."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log_path = self.log_dir / f'{name}.log'
        previous = self.nodes.get(name)
        if previous is not None:  # a restart: the dead one's log stays, the new one follows it
            self.retired.append(previous)
        with open(log_path, 'ab') as log:
            if log.tell():
                log.write(f'--- {name} started again: {" ".join(command)}\n'.encode())
                log.flush()
            process = subprocess.Popen(
                command,
                env={**self.env, **(env or {})},
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                preexec_fn=_preexec(niceness),
            )
        node = NodeProcess(name, command, log_path, process, time.monotonic())
        self.nodes[name] = node
        return node

    def dead(self) -> list[NodeProcess]:
        """Nodes that exited without being asked to."""
        return [n for n in self.nodes.values() if not n.stopping and n.poll() is not None]

    @property
    def any_killed(self) -> bool:
        """Whether some node ended by a signal (ours or anyone's): it may have left shared
        memory behind."""
        return any(
            n.killed or (n.process.returncode is not None and n.process.returncode < 0)
            for n in (*self.nodes.values(), *self.retired)
        )

    def stop(
        self,
        order: Iterable[str],
        timeout: float | Callable[[str], float] = 10.0,
        hurry: Callable[[], bool] = lambda: False,
        on_stop: Callable[[str], None] = lambda name: None,
    ) -> None:
        """Stop the nodes one after the other in `order` (then any others): SIGINT to the
        group, wait up to `timeout` s, then SIGKILL. When hurry() turns true (a second Ctrl-C),
        whatever is still running is killed at once."""
        names = [n for n in order if n in self.nodes]
        names += [n for n in self.nodes if n not in names]
        for name in names:
            node = self.nodes[name]
            node.stopping = True
            if node.alive and not hurry():
                on_stop(name)
                node.signal_group(signal.SIGINT)
                limit = timeout(name) if callable(timeout) else timeout
                deadline = time.monotonic() + limit
                while node.alive and time.monotonic() < deadline and not hurry():
                    time.sleep(0.02)
            if node.alive:
                node.signal_group(signal.SIGKILL)
                node.killed = True
                with contextlib.suppress(subprocess.TimeoutExpired):
                    node.process.wait(5.0)
            # A clean exit of the leader is not enough: anything else in its group goes too.
            node.signal_group(signal.SIGKILL)

    def kill_all(self) -> None:
        """SIGKILL every node at once (the last resort)."""
        for node in self.nodes.values():
            node.stopping = True
            if node.alive:
                node.signal_group(signal.SIGKILL)
                node.killed = True
        for node in self.nodes.values():
            with contextlib.suppress(subprocess.TimeoutExpired):
                node.process.wait(5.0)

    def unclean(self) -> list[NodeProcess]:
        """Nodes that did not end cleanly when stopped (killed, or an error exit)."""
        return [
            n
            for n in self.nodes.values()
            if n.killed
            or (n.process.returncode is not None and n.process.returncode not in CLEAN_EXITS)
        ]
