"""Schedules for the exploration rate epsilon and the learning rate alpha.

A schedule is a pure function of the episode number t (count of finished episodes, from 0):

- ``constant``:    value(t) = start
- ``linear``:      value(t) = start + (final - start) * min(1, t / decay); reaches `final` after
                   `decay` episodes and stays there
- ``exponential``: value(t) = final + (start - final) * exp(-t / decay); `decay` is the time
                   constant in episodes (63 % of the way from start to final after `decay`
                   episodes), works with final = 0

No rclpy here: the ROS node and the in-process trainers share these.
"""

from dataclasses import asdict, dataclass
import math

SCHEDULE_KINDS = ('constant', 'linear', 'exponential')


def constant(start: float, t: float) -> float:
    """The same value at every episode."""
    del t
    return float(start)


def linear(start: float, final: float, decay: float, t: float) -> float:
    """From start to final in `decay` episodes along a straight line, then final."""
    fraction = min(1.0, max(0.0, t) / decay)
    return float(start + (final - start) * fraction)


def exponential(start: float, final: float, decay: float, t: float) -> float:
    """From start towards final with time constant `decay` episodes."""
    return float(final + (start - final) * math.exp(-max(0.0, t) / decay))


@dataclass(frozen=True)
class Schedule:
    """A value that may change with the episode number; see the module docstring."""

    kind: str = 'constant'
    start: float = 0.1
    final: float = 0.1
    decay: float = 1000.0  # episodes: linear, to reach `final`; exponential, time constant

    def __post_init__(self):
        problem = schedule_problem(self.kind, self.start, self.final, self.decay)
        if problem:
            raise ValueError(problem)

    def __call__(self, t: float) -> float:
        return schedule_value(self, t)

    @classmethod
    def fixed(cls, value: float) -> 'Schedule':
        """A constant schedule."""
        return cls('constant', float(value), float(value), 1.0)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> 'Schedule':
        return cls(
            str(data['kind']), float(data['start']), float(data['final']), float(data['decay'])
        )


def schedule_problem(kind: str, start: float, final: float, decay: float) -> str | None:
    """What is wrong with these schedule settings, or None when they are usable."""
    if kind not in SCHEDULE_KINDS:
        return f'unknown schedule kind {kind!r} (expected one of {", ".join(SCHEDULE_KINDS)})'
    for name, value in (('start', start), ('final', final), ('decay', decay)):
        if not isinstance(value, int | float) or not math.isfinite(value):
            return f'schedule {name} must be a finite number, got {value!r}'
    if decay <= 0:
        return f'schedule decay must be > 0 episodes, got {decay}'
    return None


def schedule_value(schedule: Schedule, t: float) -> float:
    """The schedule's value at episode t."""
    if schedule.kind == 'constant':
        return constant(schedule.start, t)
    if schedule.kind == 'linear':
        return linear(schedule.start, schedule.final, schedule.decay, t)
    return exponential(schedule.start, schedule.final, schedule.decay, t)
