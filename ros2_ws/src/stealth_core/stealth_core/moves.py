"""One move of the robot, as stealth_interfaces/ExecuteMove has it: its kinds, outcomes,
request and result, the controller's tolerances, and why a request cannot be executed.

The vocabulary that the simulator (``stealth_sim.move_executor``, the service) and the
environment (its robots over services or topics) share, so neither imports the other's package.
"""

import dataclasses
import enum
import math

from stealth_core.kinematics import Pose


class MoveKind(enum.IntEnum):
    """The kinds of stealth_interfaces/ExecuteMove (same numbers)."""

    UP = 0
    DOWN = 1
    LEFT = 2
    RIGHT = 3
    TURN_TO_HEADING = 4
    DRIVE_DISTANCE = 5
    GO_TO = 6
    HOLD = 7


class MoveOutcome(enum.IntEnum):
    """The outcomes of stealth_interfaces/ExecuteMove (same numbers)."""

    DONE = 0
    BUMPED = 1
    REJECTED = 2
    TIMED_OUT = 3


GRID_HEADINGS = {
    MoveKind.UP: math.pi / 2,
    MoveKind.DOWN: -math.pi / 2,
    MoveKind.LEFT: math.pi,
    MoveKind.RIGHT: 0.0,
}


@dataclasses.dataclass(frozen=True)
class MoveRequest:
    """A move as stealth_interfaces/ExecuteMove's request has it: ``distance`` (m) for the
    drives, ``heading`` (rad, map) for the turn, ``x``, ``y`` (m, map) for GO_TO, ``seconds``
    (simulated) for HOLD."""

    kind: int
    distance: float = 0.0
    heading: float = 0.0
    x: float = 0.0
    y: float = 0.0
    seconds: float = 0.0


@dataclasses.dataclass(frozen=True)
class MoveResult:
    outcome: MoveOutcome
    message: str = ''
    duration: float = 0.0  # simulated s
    steps: int = 0


@dataclasses.dataclass(frozen=True)
class ControllerConfig:
    """Tolerances (rad, m), braking and the time limit of the move controller."""

    heading_tolerance: float = 0.02
    position_tolerance: float = 0.01
    # Deceleration planned with this share of the acceleration limit, so braking never lags.
    braking_share: float = 0.8
    # Aim at the target point until this close, then hold the drive's heading.
    aim_distance: float = 0.1
    stopped_speed: float = 1e-3  # m/s and rad/s
    # The time limit: this many times the nominal duration, plus the margin (s).
    time_limit_factor: float = 4.0
    time_limit_margin: float = 5.0


MAX_HOLD_SECONDS = 600.0  # a HOLD longer than this is a mistake in the caller, not a wait


def move_problem(move: MoveRequest, max_distance: float, start: Pose | None = None) -> str | None:
    """Why a move request cannot be executed, or None when it can (GO_TO: from `start`)."""
    try:
        kind = MoveKind(move.kind)
    except ValueError:
        kinds = ', '.join(f'{k.value} ({k.name})' for k in MoveKind)
        return f'kind: expected one of {kinds}, got {move.kind!r}'
    if kind == MoveKind.HOLD:
        if not (math.isfinite(move.seconds) and 0.0 < move.seconds <= MAX_HOLD_SECONDS):
            return (
                f'seconds: expected a number of seconds > 0 and at most {MAX_HOLD_SECONDS:g}, '
                f'got {move.seconds!r}'
            )
        return None
    if kind == MoveKind.TURN_TO_HEADING:
        if not math.isfinite(move.heading):
            return f'heading: expected a finite angle (rad), got {move.heading!r}'
        return None
    if kind == MoveKind.GO_TO:
        if not (math.isfinite(move.x) and math.isfinite(move.y)):
            return f'x, y: expected a finite point (m), got ({move.x!r}, {move.y!r})'
        distance = math.hypot(move.x - start.x, move.y - start.y)
        if distance > max_distance:
            return (
                f'x, y: ({move.x:g}, {move.y:g}) is {distance:.2f} m away, more than the map '
                f'diagonal ({max_distance:.2f} m); no single move can be that long'
            )
        return None
    distance = move.distance
    if not math.isfinite(distance) or distance <= 0:
        return f'distance: expected a finite number > 0 (m), got {distance!r}'
    if distance > max_distance:
        return (
            f'distance: {distance:g} m is longer than the map diagonal ({max_distance:.2f} m); '
            'no single move can be that long'
        )
    return None
