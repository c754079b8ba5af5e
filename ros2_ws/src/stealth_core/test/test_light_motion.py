"""The search's motion proposals keep a light where the evidence saw it: set moving, a light
stands at the chosen time as it stood still; stopped, it stands as it did then."""

import math

import numpy as np
import pytest
from stealth_core.light_cycle import Timing
from stealth_core.light_motion import (
    animated,
    fitted_patrol,
    motion_perturbed,
    periods,
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


@pytest.mark.parametrize('offset', [0.0, 2.5, 7.0, 11.0])
def test_a_patrol_is_fitted_to_where_and_when_its_beam_lit_steps(offset):
    """A lamp facing west patrols x = 38.8 m between y = 17 and 23 m every 24 s: the steps its
    beam lit 1-3 m ahead of it, at their times, give back its rail, period and phase (the
    searched light standing anywhere on it, facing its way), to the polish's few tenths."""
    truth = (38.8, 17.0, math.pi, 0.7, 0.3, 6.0, float(PATROL), 38.8, 23.0, 8, offset)
    lamp = hypothesis_light('truth', truth, TIMING)
    rng = np.random.default_rng(0)
    times = rng.uniform(0.0, 48.0, 60)
    ahead = rng.uniform(1.0, 3.0, 60)
    points = np.array(
        [[lamp.at(t).x - a, lamp.at(t).y] for t, a in zip(times, ahead, strict=True)]
    )
    points[:, 1] += rng.normal(0.0, 0.2, 60)  # the beam's width
    searched = (38.8, 20.0, math.pi, 0.7, 0.3, 6.0, *[float(STATIC)] + [0.0] * 4)
    fits = [fitted_patrol(rng, searched, points, times, TIMING, free) for _ in range(20)]
    across = [fit for fit in fits if fit is not None and abs(fit[7] - fit[0]) < 0.1]
    assert len(across) >= 10  # a rail along the beam is drawn a fifth of the time
    errors = []  # each fit's farthest from the lamp over a period, m
    for fit in across:
        assert int(fit[6]) == PATROL and fit[9] == 8 and fit[2] == math.pi
        found = hypothesis_light('found', fit, TIMING)
        assert all(found.at(t).x == pytest.approx(38.8) for t in range(24))
        errors.append(max(abs(found.at(t).y - lamp.at(t).y) for t in np.arange(0, 24, 0.5)))
    # drawn by their residuals: mostly the best, now and then one a little off
    assert np.median(errors) <= 0.4 and max(errors) <= 1.5, errors


def test_no_patrol_is_fitted_to_steps_lit_at_one_time():
    searched = (5.0, 5.0, 0.0, 0.7, 0.3, 6.0, float(STATIC), 0.0, 0.0, 0.0, 0.0)
    points = np.array([[6.0, 5.0], [7.0, 5.2], [6.5, 4.8]])
    rng = np.random.default_rng(0)
    assert fitted_patrol(rng, searched, points, np.full(3, 4.5), TIMING, free) is None
    assert fitted_patrol(rng, searched, points[:2], np.array([1.0, 2.0]), TIMING, free) is None
