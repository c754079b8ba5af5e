"""The search's motion proposals keep a light where the evidence saw it: set moving, a light
stands at the chosen time as it stood still; stopped, it stands as it did then."""

import math

import numpy as np
import pytest
from stealth_core.light_cycle import Timing
from stealth_core.light_motion import animated, motion_perturbed, periods, stilled
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
