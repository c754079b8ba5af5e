"""The search's motion proposals keep a light where the evidence saw it: set moving, a light
stands at the chosen time as it stood still; stopped, it stands as it did then."""

import math

import numpy as np
import pytest
from stealth_core.light_cycle import Timing
from stealth_core.light_motion import (
    RAIL_STRETCH,
    RAIL_X,
    RAIL_Y,
    animated,
    motion_perturbed,
    periods,
    rail_stepped,
    stilled,
)
from stealth_core.light_world import PATROL, STATIC, SWEEP, hypothesis_light

TIMING = Timing(cycle=24.0, cycle_bins=8, step_seconds=3.0)


def free(start, end):
    return True


def pose(light, t):
    at = light.at(t)
    return at.x, at.y, math.cos(at.direction), math.sin(at.direction)


def test_periods_divide_the_cycle():
    assert periods(TIMING) == [2, 4, 8]
    assert periods(Timing(cycle=3.0, cycle_bins=1, step_seconds=3.0)) == [1]


@pytest.mark.parametrize('seed', range(40))
def test_a_light_set_moving_stands_then_as_it_stood_still(seed):
    rng = np.random.default_rng(seed)
    still = (5.0, 6.0, float(rng.uniform(-3, 3)), 0.7, 0.3, 6.0, float(STATIC), 0, 0, 0, 0)
    when = float(rng.uniform(0.0, 30.0))
    moving = animated(rng, still, when, TIMING, free)
    if moving is None:  # a sweep that would start turning down: refused, never wrong
        return
    assert int(moving[6]) in (SWEEP, PATROL) and int(moving[9]) in periods(TIMING)
    then = hypothesis_light('m', moving, TIMING)
    assert pose(then, when) == pytest.approx(pose(hypothesis_light('s', still, TIMING), 0.0))
    stopped = stilled(moving, when, TIMING)
    assert int(stopped[6]) == STATIC
    assert pose(hypothesis_light('s', stopped, TIMING), 0.0) == pytest.approx(pose(then, when))
    changed = motion_perturbed(rng, moving, TIMING, free)
    assert changed is None or changed[:7] == moving[:7]


def test_a_rail_into_a_wall_is_not_proposed():
    rng = np.random.default_rng(0)
    still = (5.0, 6.0, 0.0, 0.7, 0.3, 6.0, float(STATIC), 0, 0, 0, 0)
    kinds = [animated(rng, still, 1.0, TIMING, lambda a, b: False) for _ in range(50)]
    assert all(k is None or int(k[6]) == SWEEP for k in kinds)
    assert any(k is not None for k in kinds)


def test_a_rail_moved_whole_keeps_the_lamps_timing():
    """Shifted, the lamp stands shifted at every time; stretched about the rail's middle, it
    stands as far along the rail, in the same phase, at every time (a lamp found a little short
    of both ends of its rail is polished out to them without losing its timing)."""
    patrol = (38.6, 17.25, math.pi, 0.7, 0.25, 6.0, float(PATROL), 38.6, 22.55, 8, 10.4)
    light = hypothesis_light('p', patrol, TIMING)
    shifted_x = hypothesis_light('x', rail_stepped(patrol, RAIL_X, 0.3), TIMING)
    shifted_y = hypothesis_light('y', rail_stepped(patrol, RAIL_Y, -0.25), TIMING)
    stretched = hypothesis_light('s', rail_stepped(patrol, RAIL_STRETCH, 0.25), TIMING)
    scale = (5.3 + 0.5) / 5.3
    for t in np.linspace(0.0, 24.0, 17):
        x, y, _, _ = pose(light, t)
        assert pose(shifted_x, t)[:2] == pytest.approx((x + 0.3, y))
        assert pose(shifted_y, t)[:2] == pytest.approx((x, y - 0.25))
        assert pose(stretched, t)[:2] == pytest.approx((38.6, 19.9 + (y - 19.9) * scale))
    assert rail_stepped(patrol, RAIL_STRETCH, -2.5) is None  # 0.3 m: too short a rail
