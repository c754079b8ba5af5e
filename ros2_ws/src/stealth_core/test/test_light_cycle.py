"""Timing of moving lights: periods, the joint cycle, phase bins and the step's time."""

import math

import pytest
from stealth_core.light_cycle import (
    TimingError,
    check_timing,
    joint_cycle,
    lattice_move_seconds,
    lattice_step_seconds,
    light_period,
)
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion


def sweep(name='s', degrees_per_second=10.0, span=60.0):
    motion = SweepMotion(0.0, math.radians(span), math.radians(degrees_per_second))
    return Searchlight(name, 0.0, 0.0, 0.0, 1.0, 5.0, motion=motion)


def patrol(name='p', speed=1.0, to=(3.0, 4.0)):
    return Searchlight(name, 0.0, 0.0, 0.0, 1.0, 5.0, motion=PatrolMotion((to,), speed))


def test_periods_are_when_a_light_is_back_where_it_started():
    light = sweep(degrees_per_second=10.0, span=60.0)
    period = light_period(light)
    assert period == pytest.approx(12.0)
    for t in (0.0, 3.3, 7.9):
        assert light.at(t + period).direction == pytest.approx(light.at(t).direction)
    walker = patrol(speed=2.0)  # 5 m there, 5 m back
    assert light_period(walker) == pytest.approx(5.0)
    assert walker.at(1.2 + 5.0).x == pytest.approx(walker.at(1.2).x)
    assert light_period(Searchlight('still', 0.0, 0.0, 0.0, 1.0, 5.0)) is None
    assert light_period(sweep(span=0.0)) is None


def test_the_joint_cycle_is_the_least_common_multiple():
    assert joint_cycle([sweep(degrees_per_second=10.0), patrol(speed=2.0)]) == pytest.approx(60.0)
    assert joint_cycle([sweep(degrees_per_second=10.0), patrol(speed=10 / 3)]) == pytest.approx(
        12.0
    )  # 12 s and 3 s
    assert joint_cycle([Searchlight('still', 0.0, 0.0, 0.0, 1.0, 5.0)]) is None


def test_bins_and_steps():
    timing = check_timing([sweep()], 4, 6.0)  # 12 s in bins of 3 s, a step of two bins
    assert (timing.bin_seconds, timing.bins_per_step) == (3.0, 2)
    assert [timing.bin_of(t) for t in (0.0, 2.999, 3.0, 9.5, 12.0, 21.0 * 1.0)] == [
        0, 0, 1, 3, 0, 3,
    ]  # fmt: skip
    assert timing.bin_of(7 * 0.1 * 30) == 3  # 21.000000000000004 s stays in its bin
    assert check_timing([sweep()], 4, None).step_seconds == 3.0
    assert check_timing([Searchlight('still', 0.0, 0.0, 0.0, 1.0, 5.0)], 4, None) is None


@pytest.mark.parametrize(
    ('lights', 'bins', 'step', 'parts'),
    [
        ([sweep()], 0, None, ["field 'phase_bins'", 'an integer >= 1, got 0']),
        ([sweep()], 2.5, None, ["field 'phase_bins'"]),
        (
            [sweep('beam'), patrol('rail', speed=2.5)],  # 12 s and 4 s: 12 s in 5 bins
            5,
            None,
            ["searchlight 'rail'", "field 'motion.speed'", 'period 4 s is 1.66667 phase bins'],
        ),
        ([sweep()], 4, 4.0, ["field 'step_seconds'", 'whole number (>= 1) of phase bins of 3 s']),
        ([sweep()], 4, 1.5, ["field 'step_seconds'"]),
    ],
)
def test_what_does_not_fit_names_the_light_or_field(lights, bins, step, parts):
    with pytest.raises(TimingError) as raised:
        check_timing(lights, bins, step)
    for part in parts:
        assert part in str(raised.value)


def test_a_lattice_move_takes_the_trapezoid_time():
    # 0.5 m at 0.5 m/s and 1 m/s^2: 0.5 s up and 0.5 s down (0.125 m each), 0.25 m at 0.5 m/s.
    assert lattice_move_seconds(0.5, 0.5, 1.0) == pytest.approx(1.5)
    assert lattice_move_seconds(0.09, 0.5, 1.0) == pytest.approx(0.6)  # a triangle
    with pytest.raises(ValueError):
        lattice_move_seconds(0.5, 0.0)


def test_the_longest_lattice_step_is_a_half_turn_and_a_drive():
    # pi at 3 rad/s and 8 rad/s^2: 3/8 s up and down (9/8 rad in all), the rest at 3 rad/s;
    # 0.5 m at 0.5 m/s and 1.5 m/s^2: 1/3 s up and down (1/6 m in all), 1/3 m at 0.5 m/s.
    turn = 2.0 * 3.0 / 8.0 + (math.pi - 9.0 / 8.0) / 3.0
    assert lattice_step_seconds(0.5) == pytest.approx(turn + 2.0 / 3.0 + (0.5 - 1.0 / 6.0) / 0.5)
