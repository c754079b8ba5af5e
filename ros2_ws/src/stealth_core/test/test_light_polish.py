"""The polish's moves: a cone edge moved alone, and placed where the misses ask for it, which
takes a light whose edge the parameter steps leave short to the truth's."""

import dataclasses
import math

import numpy as np
import pytest
from stealth_core import light_belief
from stealth_core.lattice_model import LatticeModel
from stealth_core.light_belief import LightBelief
from stealth_core.light_polish import (
    EDGE_CLEARANCE,
    LOWER,
    MIN_FOV,
    UPPER,
    edge_moved,
    edge_steps,
)
from stealth_core.light_world import LightWorld, StepEvidence
from stealth_core.scenario import load_scenario
from stealth_core.searchlight import PatrolMotion, Searchlight
from stealth_core.task import StealthTask

FOV = math.radians(40.0)
LIGHT = (0.0, 0.0, 0.0, FOV, 0.25, 6.0)  # x, y, direction, fov, beta, range


def edges(params):
    return params[2] + params[3] / 2.0, params[2] - params[3] / 2.0


def at_bearings(*rows, distance=3.0):
    """Sample points (x, y, no time), one row of samples per step, at the given bearings
    (degrees) from the origin."""
    angles = np.radians(np.array(rows, dtype=np.float64))
    return distance * np.cos(angles), distance * np.sin(angles), None


def test_an_edge_moved_keeps_the_other_edge_where_it_was():
    upper, lower = edges(LIGHT)
    opened = edge_moved(LIGHT, UPPER, 0.1)
    assert edges(opened) == pytest.approx((upper + 0.1, lower))
    closed = edge_moved(LIGHT, LOWER, -0.1)
    assert edges(closed) == pytest.approx((upper, lower + 0.1))
    assert edge_moved(LIGHT, UPPER, MIN_FOV - FOV - 0.01) is None  # narrower than a cone may be


def test_an_edge_opens_just_past_a_sample_left_dark_and_closes_short_of_one_left_bright():
    light = Searchlight('lamp', 0.0, 0.0, 0.0, FOV, 6.0)
    nothing = at_bearings(*np.zeros((0, 1)))
    # Too dark: one sample 3 degrees past the upper edge (the other beyond the edge's reach).
    moves = edge_steps(light, LIGHT, at_bearings([23.0, 50.0]), nothing)
    assert moves == [(UPPER, pytest.approx(math.radians(3.0) + EDGE_CLEARANCE, abs=1e-4))]
    # Out of the light's range: no move.
    assert edge_steps(light, LIGHT, at_bearings([23.0], distance=7.0), nothing) == []
    # Too bright: each sample in the cone within the edge's reach, the nearest first; the
    # sample across the axis is the lower edge's.
    moves = edge_steps(light, LIGHT, nothing, at_bearings([15.0, 18.0], [18.0, -19.0]))
    assert moves == [
        (UPPER, pytest.approx(math.radians(-2.0) - EDGE_CLEARANCE, abs=1e-4)),
        (UPPER, pytest.approx(math.radians(-5.0) - EDGE_CLEARANCE, abs=1e-4)),
        (LOWER, pytest.approx(math.radians(-1.0) - EDGE_CLEARANCE, abs=1e-4)),
    ]


def test_a_moving_lamp_is_judged_where_it_was_when_the_step_was_taken():
    light = Searchlight('rail', 0.0, 0.0, 0.0, FOV, 6.0, motion=PatrolMotion(((0.0, 4.0),), 1.0))
    x, y, _ = at_bearings([23.0])
    y = y + 4.0  # 23 degrees off the axis from the rail's far end, reached at t = 4 s
    then = edge_steps(light, LIGHT, (x, y, np.array([[4.0]])), (x[:0], y[:0], None))
    assert then == [(UPPER, pytest.approx(math.radians(3.0) + EDGE_CLEARANCE, abs=1e-4))]
    assert edge_steps(light, LIGHT, (x, y, np.array([[0.0]])), (x[:0], y[:0], None)) == []


@pytest.fixture(scope='module')
def map1_lamp():
    """map1's first light alone, and a belief that read every step within its range."""
    scenario = load_scenario('map1')
    lamp = scenario.lights[0]
    scenario = dataclasses.replace(scenario, lights=(lamp,))
    truth = LatticeModel.build(StealthTask(scenario)).step_visibility
    world = LightWorld(scenario)
    belief = LightBelief(world, np.random.default_rng(0))
    for place in np.flatnonzero(np.hypot(*(world.model.points - (lamp.x, lamp.y)).T) <= 6.0):
        for direction in range(truth.shape[1]):
            value = float(truth[place, direction])
            belief.observe(StepEvidence(int(place), direction, value, value))
    beta = (1.0 - lamp.delta) / (lamp.delta * lamp.range**2)
    return belief, (lamp.x, lamp.y, lamp.direction, lamp.fov, beta, lamp.range)


def test_the_polish_places_an_edge_the_parameter_steps_leave_short(map1_lamp, monkeypatch):
    """The truth with its upper edge 3 degrees short (measured: the parameter steps alone
    leave it at energy 306 where the truth has 4; each steps both edges or neither)."""
    belief, truth = map1_lamp
    particle = belief.particles[0]
    truth_energy = belief._energy([belief._make(truth)])

    def polished(edge_rounds):
        monkeypatch.setattr(light_belief, 'EDGE_ROUNDS', edge_rounds)
        particle.lights = [belief._make(edge_moved(truth, UPPER, math.radians(-3.0)))]
        particle.energy = belief._energy(particle.lights)
        belief.polish(particle)
        return particle

    assert polished(0).energy > truth_energy + 100.0
    found = polished(3)
    assert found.energy <= truth_energy + 0.5
    assert edges(found.lights[0].params) == pytest.approx(edges(truth), abs=math.radians(0.25))
