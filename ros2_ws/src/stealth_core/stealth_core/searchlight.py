"""Searchlights: what a light is, how it moves, and the checks that keep bad numbers out.

A light is a cone: a lamp at (x, y) shining along ``direction`` with a full opening angle
``fov`` out to ``range``; intensity falls off as ``1/(1 + beta*d^2)`` so that it is 1 at the
lamp and ``delta`` at the range (see ``stealth_core.lighting`` for the model itself).

Motion (off by default; ``Searchlight.at(t)`` gives the static pose at time t):

- ``SweepMotion``: the beam direction runs back and forth over ``[min_direction,
  max_direction]`` (radians, ``min <= max``, span at most 2*pi) at ``angular_speed`` (rad/s), a
  triangle wave. At t = 0 the beam points along the light's ``direction``, which must lie in
  the sweep (modulo 2*pi), and first turns towards ``max_direction`` (counter-clockwise), bounces
  back to ``min_direction``, and so on, with period ``2*(max - min)/angular_speed``.
- ``PatrolMotion``: the lamp travels at ``speed`` (m/s) along the closed route
  ``(x, y) -> waypoints[0] -> ... -> waypoints[-1] -> (x, y) -> ...``; so the light's own
  ``(x, y)`` is where it is at t = 0 and where every lap starts. Put ``(x, y)`` equal to the first
  waypoint for a plain loop over the waypoints. The beam keeps its ``direction`` (a fixed-heading
  lamp on a rail, not a guard turning its head).

Time may be any finite number of seconds; both motions are periodic, so negative t works too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
import math
import numbers

import numpy as np


class LightError(ValueError):
    """A searchlight parameter is out of range; the message names the light and the field."""


def _fail(name: str, field_name: str, expected: str, got: object) -> None:
    raise LightError(
        f'searchlight {name!r}: field {field_name!r}: expected {expected}, got {got!r}'
    )


def _number(
    name: str,
    field_name: str,
    value: object,
    expected: str = 'a finite number',
    valid: Callable[[float], bool] = lambda _: True,
) -> float:
    """Return value as a float, refusing bools, strings, NaN, infinities and invalid values."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        _fail(name, field_name, expected, value)
    number = float(value)
    if not math.isfinite(number) or not valid(number):
        _fail(name, field_name, expected, value)
    return number


def _non_negative(value: float) -> bool:
    return value >= 0.0


@dataclass(frozen=True)
class SweepMotion:
    """Beam direction sweeping between two angles (rad) at a constant angular speed (rad/s)."""

    min_direction: float
    max_direction: float
    angular_speed: float

    def validate(self, light_name: str) -> SweepMotion:
        low = _number(light_name, 'motion.min_direction', self.min_direction)
        high = _number(light_name, 'motion.max_direction', self.max_direction)
        if not low <= high <= low + 2 * math.pi:
            _fail(
                light_name,
                'motion.max_direction',
                f'a number in [min_direction, min_direction + 2*pi] = [{low}, {low + 2 * math.pi}]'
                ' (rad)',
                self.max_direction,
            )
        speed = _number(
            light_name,
            'motion.angular_speed',
            self.angular_speed,
            'a finite number >= 0 (rad/s)',
            _non_negative,
        )
        return SweepMotion(low, high, speed)

    def start_offset(self, light_name: str, direction: float) -> float:
        """Where along the sweep (rad from min_direction) the beam starts; it must be inside."""
        span = self.max_direction - self.min_direction
        offset = (direction - self.min_direction) % (2 * math.pi)
        tolerance = 1e-9
        if offset > span + tolerance:
            if 2 * math.pi - offset <= tolerance:  # just below min_direction by rounding
                return 0.0
            _fail(
                light_name,
                'direction',
                f'an angle inside the sweep [{self.min_direction}, {self.max_direction}]'
                ' (modulo 2*pi)',
                direction,
            )
        return min(offset, span)

    def direction_at(self, start_offset: float, t: float) -> float:
        """Triangle wave: the beam direction t seconds after starting at start_offset."""
        span = self.max_direction - self.min_direction
        if span == 0.0 or self.angular_speed == 0.0:
            return self.min_direction + start_offset
        travelled = (start_offset + self.angular_speed * t) % (2 * span)
        along = travelled if travelled <= span else 2 * span - travelled
        return self.min_direction + along


@dataclass(frozen=True)
class PatrolMotion:
    """Lamp moving along waypoints (m) at a constant speed (m/s), looping back to its start."""

    waypoints: tuple[tuple[float, float], ...]
    speed: float

    def validate(self, light_name: str) -> PatrolMotion:
        try:
            points = tuple(self.waypoints)
        except TypeError:
            _fail(light_name, 'motion.waypoints', 'a sequence of (x, y) pairs', self.waypoints)
        if not points:
            _fail(light_name, 'motion.waypoints', 'at least one (x, y) waypoint', self.waypoints)
        checked = []
        for index, point in enumerate(points):
            try:
                px, py = point
            except (TypeError, ValueError):
                _fail(light_name, f'motion.waypoints[{index}]', 'an (x, y) pair', point)
            checked.append(
                (
                    _number(light_name, f'motion.waypoints[{index}].x', px),
                    _number(light_name, f'motion.waypoints[{index}].y', py),
                )
            )
        speed = _number(
            light_name, 'motion.speed', self.speed, 'a finite number >= 0 (m/s)', _non_negative
        )
        return PatrolMotion(tuple(checked), speed)

    def position_at(self, start: tuple[float, float], t: float) -> tuple[float, float]:
        """Position t seconds in, on the closed route start -> waypoints... -> start."""
        route = (start, *self.waypoints, start)
        lengths = [math.dist(a, b) for a, b in zip(route, route[1:], strict=False)]
        lap = sum(lengths)
        if lap == 0.0 or self.speed == 0.0:
            return start
        remaining = (self.speed * t) % lap
        for (ax, ay), (bx, by), length in zip(route, route[1:], lengths, strict=False):
            if remaining <= length and length > 0.0:
                fraction = remaining / length
                return (ax + fraction * (bx - ax), ay + fraction * (by - ay))
            remaining -= length
        return start  # only reached through rounding at the very end of a lap


@dataclass(frozen=True)
class Searchlight:
    """One searchlight; validated on construction, immutable, hashable (usable as a cache key).

    Units: x, y and range in metres (map frame), direction and fov in radians (direction
    counter-clockwise from +x, fov the full opening angle), delta and soft_edge unitless.
    """

    name: str
    x: float
    y: float
    direction: float
    fov: float
    range: float
    delta: float = 0.1
    soft_edge: float = 0.0
    motion: SweepMotion | PatrolMotion | None = field(default=None)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise LightError(f'searchlight name: expected a non-empty string, got {self.name!r}')
        name = self.name
        checked = {
            'x': _number(name, 'x', self.x),
            'y': _number(name, 'y', self.y),
            'direction': _number(name, 'direction', self.direction),
            'fov': _number(
                name,
                'fov',
                self.fov,
                'a number in (0, 2*pi] (rad)',
                lambda v: 0 < v <= 2 * math.pi,
            ),
            'range': _number(
                name, 'range', self.range, 'a finite number > 0 (m)', lambda v: v > 0
            ),
            'delta': _number(name, 'delta', self.delta, 'a number in (0, 1)', lambda v: 0 < v < 1),
            'soft_edge': _number(
                name, 'soft_edge', self.soft_edge, 'a number in [0, 1]', lambda v: 0 <= v <= 1
            ),
        }
        if self.motion is not None:
            if not isinstance(self.motion, SweepMotion | PatrolMotion):
                _fail(name, 'motion', 'None, a SweepMotion or a PatrolMotion', self.motion)
            checked['motion'] = self.motion.validate(name)
            if isinstance(self.motion, SweepMotion):
                checked['motion'].start_offset(name, checked['direction'])
        for key, value in checked.items():
            object.__setattr__(self, key, value)

    @property
    def beta(self) -> float:
        """Fall-off constant of I(d) = 1/(1 + beta*d^2), chosen so that I(range) = delta."""
        return (1.0 - self.delta) / (self.delta * self.range**2)

    @property
    def is_moving(self) -> bool:
        return self.motion is not None

    def at(self, t: float) -> Searchlight:
        """The static light (motion None) this light is at time t (s)."""
        t = _number(self.name, 'time t', t, 'a finite time in seconds')
        if isinstance(self.motion, SweepMotion):
            start = self.motion.start_offset(self.name, self.direction)
            return replace(self, direction=self.motion.direction_at(start, t), motion=None)
        if isinstance(self.motion, PatrolMotion):
            x, y = self.motion.position_at((self.x, self.y), t)
            return replace(self, x=x, y=y, motion=None)
        return self


def poses_at(light: Searchlight, ts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, direction) arrays of the light at the times ts (an array, s): ``light.at(t)``
    for every t at once (equal to rounding), so a moving light over thousands of sample times
    is a few array operations, not a Searchlight each."""
    ts = np.asarray(ts, dtype=np.float64)
    x, y = np.full(ts.shape, light.x), np.full(ts.shape, light.y)
    direction = np.full(ts.shape, light.direction)
    motion = light.motion
    if isinstance(motion, SweepMotion):
        span = motion.max_direction - motion.min_direction
        if span != 0.0 and motion.angular_speed != 0.0:
            start = motion.start_offset(light.name, light.direction)
            travelled = np.mod(start + motion.angular_speed * ts, 2 * span)
            along = np.where(travelled <= span, travelled, 2 * span - travelled)
            direction = motion.min_direction + along
        else:
            direction = np.full(
                ts.shape, motion.min_direction + motion.start_offset(light.name, light.direction)
            )
    elif isinstance(motion, PatrolMotion):
        route = np.array(((light.x, light.y), *motion.waypoints, (light.x, light.y)))
        lengths = np.hypot(*np.diff(route, axis=0).T)
        lap = float(lengths.sum())
        if lap > 0.0 and motion.speed != 0.0:
            remaining = np.mod(motion.speed * ts, lap)
            ends = np.cumsum(lengths)
            leg = np.minimum(np.searchsorted(ends, remaining, side='left'), len(lengths) - 1)
            before = ends[leg] - lengths[leg]
            fraction = np.where(
                lengths[leg] > 0, (remaining - before) / np.maximum(lengths[leg], 1e-300), 0.0
            )
            start, end = route[leg], route[leg + 1]
            x = start[..., 0] + fraction * (end[..., 0] - start[..., 0])
            y = start[..., 1] + fraction * (end[..., 1] - start[..., 1])
    return x, y, direction
