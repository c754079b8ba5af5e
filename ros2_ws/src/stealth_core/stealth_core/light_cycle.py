"""Time for moving searchlights: the lights' joint cycle, its bins and each move's duration.

A moving light is periodic (``searchlight``): a sweep repeats every ``2*(max - min)/speed``
seconds, a patrol every lap length / speed. The lights together repeat every *joint cycle*, the
least common multiple of their periods. A scenario with moving lights splits the cycle into
``phase_bins`` equal bins; the bin the current time falls in is the *phase*, an extra state
feature, which makes the task a Markov decision process again: where the lights are is a function
of the phase.

Decisions:

- **Exact, not approximate**: every moving light's period must be a whole number of bins, and a
  step (a move or a wait) must take a whole number of bins (``step_seconds``). Then time is
  always a multiple of the bin width in the in-process model, the bin advances by the same
  number of bins every step, and the time-expanded lattice (node x bin, ``planners``) is the
  exact task. A period that does not divide into the bins, or a step that does not, is an error
  naming the light (or the field) and what would fit.
- **Common multiples of real numbers**: periods are turned into fractions with denominators up
  to 1000 (ms resolution for periods of seconds), whose lcm is exact; a period that is no such
  fraction to 1e-9 relative is refused.
- **Bin of a time**: ``floor(t / bin + 1e-9) mod phase_bins``: the tolerance keeps a time that is
  a multiple of the bin up to rounding (t = 7 * 3.0 s) in its own bin.
- **Move duration**: ``lattice_move_seconds`` is how long the simulator's robot takes to drive
  (or turn) a given amount from rest to rest at its speed and acceleration limits (a
  trapezoid); ``lattice_step_seconds``, the longest lattice move (a half turn, then a lattice
  step), is what the shipped moving scenarios' ``step_seconds`` (3 s) must hold: 2.76 s for
  0.5 m, and 2.8-3.0 s measured with the controller's settling (stealth_bringup's
  simulator.yaml says more). A move longer than its step ends in a later phase than the model
  assumes. In ROS the environment uses the simulator's reported time.
"""

from __future__ import annotations

from collections.abc import Iterable
import dataclasses
from fractions import Fraction
import math

from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion

_DENOMINATOR = 1000
_TOLERANCE = 1e-9
DEFAULT_MAX_SPEED = 0.5  # m/s: stealth_bringup/config/simulator.yaml's max_linear_speed
DEFAULT_MAX_ACCEL = 1.5  # m/s^2: its max_linear_accel
DEFAULT_MAX_TURN_RATE = 3.0  # rad/s: its max_angular_speed
DEFAULT_MAX_TURN_ACCEL = 8.0  # rad/s^2: its max_angular_accel


class TimingError(ValueError):
    """Light periods, bins and step time that do not fit; the message names the light or field."""


def light_period(light: Searchlight) -> float | None:
    """Seconds after which the light is where it started; None for a light that never moves
    (no motion, a zero sweep span or a patrol of no length)."""
    motion = light.motion
    if isinstance(motion, SweepMotion):
        span = motion.max_direction - motion.min_direction
        if span == 0.0 or motion.angular_speed == 0.0:
            return None
        return 2.0 * span / motion.angular_speed
    if isinstance(motion, PatrolMotion):
        route = ((light.x, light.y), *motion.waypoints, (light.x, light.y))
        lap = sum(math.dist(a, b) for a, b in zip(route, route[1:], strict=False))
        if lap == 0.0 or motion.speed == 0.0:
            return None
        return lap / motion.speed
    return None


def speed_field(light: Searchlight) -> str:
    """The field that sets the light's period (what to change when it does not fit)."""
    return 'motion.angular_speed' if isinstance(light.motion, SweepMotion) else 'motion.speed'


def _fraction(light: Searchlight, period: float) -> Fraction:
    fraction = Fraction(period).limit_denominator(_DENOMINATOR)
    if abs(float(fraction) - period) > _TOLERANCE * period:
        raise TimingError(
            f'searchlight {light.name!r}: field {speed_field(light)!r}: expected a period that '
            f'is a whole number of milliseconds, got {period!r} s'
        )
    return fraction


def joint_cycle(lights: Iterable[Searchlight]) -> float | None:
    """The least common multiple of the moving lights' periods (s); None when none moves."""
    cycle: Fraction | None = None
    for light in lights:
        period = light_period(light)
        if period is None:
            continue
        fraction = _fraction(light, period)
        if cycle is None:
            cycle = fraction
        else:
            numerator = math.lcm(cycle.numerator, fraction.numerator)
            cycle = Fraction(numerator, math.gcd(cycle.denominator, fraction.denominator))
    return None if cycle is None else float(cycle)


@dataclasses.dataclass(frozen=True)
class Timing:
    """The bins of the lights' joint cycle: ``cycle_bins`` bins of ``bin_seconds`` each (the
    scenario's ``phase_bins``); a step takes ``step_seconds`` = ``bins_per_step`` bins."""

    cycle: float  # s
    cycle_bins: int
    step_seconds: float  # s per step (move or wait)

    @property
    def bin_seconds(self) -> float:
        return self.cycle / self.cycle_bins

    @property
    def bins_per_step(self) -> int:
        return round(self.step_seconds / self.bin_seconds)

    def bin_of(self, t: float) -> int:
        """The bin of the cycle time t (s) falls in (the state's ``phase`` feature)."""
        return math.floor(float(t) / self.bin_seconds + _TOLERANCE) % self.cycle_bins

    def bin_start(self, cycle_bin: int) -> float:
        """The start of bin ``cycle_bin`` in the first cycle (s)."""
        return cycle_bin * self.bin_seconds


def check_timing(
    lights: Iterable[Searchlight], cycle_bins: int, step_seconds: float | None
) -> Timing | None:
    """The Timing of these lights split into cycle_bins bins, each step taking step_seconds
    (None: one bin); None when no light moves. TimingError naming the light or the field when
    a period or the step is not a whole number of bins."""
    lights = tuple(lights)
    if isinstance(cycle_bins, bool) or not isinstance(cycle_bins, int) or cycle_bins < 1:
        raise TimingError(f"field 'phase_bins': expected an integer >= 1, got {cycle_bins!r}")
    cycle = joint_cycle(lights)
    if cycle is None:
        return None
    bin_seconds = cycle / cycle_bins
    for light in lights:
        period = light_period(light)
        if period is None:
            continue
        bins = period / bin_seconds
        if abs(bins - round(bins)) > 1e-6 * max(bins, 1.0):
            raise TimingError(
                f'searchlight {light.name!r}: field {speed_field(light)!r}: its period '
                f'{period:g} s is {bins:g} phase bins of {bin_seconds:g} s (joint cycle '
                f'{cycle:g} s / phase_bins {cycle_bins}); expected a whole number: change the '
                'speed, or choose phase_bins so that each bin divides every period'
            )
    return timing_of(cycle, cycle_bins, step_seconds)


def timing_of(cycle: float, cycle_bins: int, step_seconds: float | None) -> Timing:
    """The Timing of a joint cycle (s) split into cycle_bins bins, each step taking
    step_seconds (None: one bin); TimingError naming the field when the bins are not a whole
    number >= 1 or a step is not a whole number of bins (a world that knows the cycle but not
    the lights, ``world_file``, is checked here too)."""
    if isinstance(cycle_bins, bool) or not isinstance(cycle_bins, int) or cycle_bins < 1:
        raise TimingError(f"field 'phase_bins': expected an integer >= 1, got {cycle_bins!r}")
    bin_seconds = cycle / cycle_bins
    if step_seconds is None:
        step_seconds = bin_seconds
    numeric = isinstance(step_seconds, int | float) and not isinstance(step_seconds, bool)
    steps = step_seconds / bin_seconds if numeric else math.nan
    if not (numeric and math.isfinite(step_seconds) and step_seconds > 0) or (
        abs(steps - round(steps)) > 1e-6 * max(steps, 1.0) or round(steps) < 1
    ):
        raise TimingError(
            f"field 'step_seconds': expected a whole number (>= 1) of phase bins of "
            f'{bin_seconds:g} s (joint cycle {cycle:g} s / phase_bins {cycle_bins}), got '
            f'{step_seconds!r}'
        )
    return Timing(cycle, cycle_bins, float(step_seconds))


def lattice_move_seconds(
    distance: float, max_speed: float = DEFAULT_MAX_SPEED, max_accel: float = DEFAULT_MAX_ACCEL
) -> float:
    """Seconds to drive ``distance`` m from rest to rest at these limits (a trapezoidal speed
    profile, a triangle when the distance is too short to reach max_speed)."""
    if not (distance >= 0 and max_speed > 0 and max_accel > 0):
        raise ValueError(
            f'distance >= 0, max_speed > 0 and max_accel > 0 expected, got {distance!r}, '
            f'{max_speed!r}, {max_accel!r}'
        )
    ramp = max_speed * max_speed / max_accel  # accelerating and braking together, m
    if distance <= ramp:
        return 2.0 * math.sqrt(distance / max_accel)
    return 2.0 * max_speed / max_accel + (distance - ramp) / max_speed


def lattice_step_seconds(step_distance: float) -> float:
    """Seconds of the longest lattice move as the training robot makes it at simulator.yaml's
    limits: a half turn in place, then the drive of one step."""
    turn = lattice_move_seconds(math.pi, DEFAULT_MAX_TURN_RATE, DEFAULT_MAX_TURN_ACCEL)
    return turn + lattice_move_seconds(step_distance)
