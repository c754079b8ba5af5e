"""Respawn, as launch's `respawn` does: which dead node may be restarted, after how long, and the
record of each restart for the run's summary. No rclpy: run_lifecycle does the restarting.

A node that dies during a run is started again in the same domain with the same parameters, at
most `limit` times per node, each time after a longer wait (RESPAWN_DELAYS), so a node that
keeps crashing costs seconds, not a busy loop. A node that exits with code 2 said it cannot
start with its parameters (stealth_node_kit's EXIT_CANNOT_START): the same parameters would
fail the same way, so it is not restarted. What each restart is given on top of its parameters,
and what it is told afterwards, is node-specific (run_lifecycle): the agent resumes from its
checkpoint, the environment continues the episode numbering, the simulator's episode is
aborted and the recorder writes a new file of the recording.
"""

from __future__ import annotations

import dataclasses

EXIT_CANNOT_START = 2  # stealth_node_kit.running.EXIT_CANNOT_START (bad parameters or input)
RESPAWN_DELAYS = (0.5, 1.0, 2.0, 4.0, 8.0)  # s before the 1st, 2nd, ... restart of a node


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
