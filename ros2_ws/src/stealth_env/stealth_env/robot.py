"""What the environment node asks of its robot, however it is reached (``robot_interface``): the
simulator's services (:mod:`stealth_env.service_robot`) or any ROS robot's standard topics
(:mod:`stealth_env.topic_robot`). The node holds one :class:`Robot` and never asks which.

Everything is asynchronous: a move's end and a reset's result come back through callbacks (from
an answer, an odometry message or the node's housekeeping ``tick``), so no callback ever blocks
the executor. A robot that is cancelled reports nothing more of what it was doing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, Protocol

from stealth_core.moves import MoveOutcome

from stealth_env.topic_moves import MoveGoal, Pose


class MoveEnd(NamedTuple):
    """What a finished move hands back: outcome (None: it could not be run, or failed: the
    message says why), poses, time."""

    outcome: MoveOutcome | None
    message: str
    estimate: Pose | None
    truth: Pose | None  # None when no ground truth is published
    t: float  # the robot's clock at the end (s)
    moved: bool  # the robot moved during it (the simulator's moves: always said to)


OnMoveEnd = Callable[[MoveEnd], None]
# A reset's result: why it failed ('' when the robot is at the start), and the robot's clock
# when it got there (s; -inf when the robot does not say).
OnReset = Callable[[str, float], None]


def failed(message: str) -> MoveEnd:
    """The end of a move that could not be run or got no usable answer."""
    return MoveEnd(None, message, None, None, 0.0, False)


class Robot(Protocol):
    def ready(self) -> bool:
        """Whether moves and resets can be sent."""

    def describe(self) -> str:
        """What the robot is reached over (for the log)."""

    def run(self, move: MoveGoal, on_end: OnMoveEnd) -> None:
        """Run one move of an episode; ``on_end`` gets its end."""

    def reset(self, pose: Pose, on_done: OnReset) -> None:
        """Put the robot at `pose` (the episode's start)."""

    def not_responding(self) -> str:
        """Why the robot cannot be used any more ('' while it can)."""

    def cancel(self) -> None:
        """Drop whatever the robot was asked to do (its answer would be stale)."""

    def tick(self) -> None:
        """Housekeeping every TICK_PERIOD of wall time: deadlines and watchdogs."""
