"""The light model's evidence: a step walked again is one distinct step, and with a pose jitter a
hypothesis predicts a range that takes in a step read dark once and lit once near a beam edge
(through ROS the true pose stops a few cm off its node)."""

import math

import numpy as np
import pytest
from stealth_core.light_belief import BeliefSettings, LightBelief
from stealth_core.light_evidence import EvidenceSet
from stealth_core.light_world import LightWorld, StepEvidence
from stealth_core.scenario import load_scenario

JITTER = 0.15


@pytest.fixture(scope='module')
def world():
    return LightWorld(load_scenario('simple-maze'))


@pytest.fixture(scope='module')
def truth(world):
    """The scenario's lights as the world sees them (the world itself has none)."""
    return world.see(load_scenario('simple-maze').lights)


def test_a_step_walked_again_is_one_distinct_step_and_each_observation_keeps_its_own(world):
    evidence = EvidenceSet(world, 0.004, 0.02)
    assert evidence.observe(StepEvidence(3, 1, 0.2, 0.2))
    assert not evidence.observe(StepEvidence(3, 1, 0.25, 0.25))
    assert evidence.observe(StepEvidence(4, 0, 0.0, 0.0))
    assert len(evidence) == 3 and evidence.distinct.size == 2
    assert evidence.which.tolist() == [0, 0, 1]
    total = np.array([[0.2] * world.samples.width, [0.0] * world.samples.width])
    low, high = evidence.predict(total)
    assert low.tolist() == high.tolist() == [0.2, 0.2, 0.0]
    # the second observation missed by 0.05 in tolerances of its reading
    assert evidence.misses(low, high).tolist() == pytest.approx([0.0, 0.05 / 0.009, 0.0])


def test_many_observations_keep_their_order_and_their_steps_light_as_the_lattice_has_it():
    """Past the arrays' first capacity (they double), every observation is kept in order and a
    moving light's light at the distinct steps, shifted, is the lattice samples' own."""
    scenario = load_scenario('map1-moving')
    world = LightWorld(scenario)
    evidence = EvidenceSet(world, 0.004, 0.02, JITTER)
    rng = np.random.default_rng(3)
    places = rng.integers(0, world.samples.shape[0], 90)
    directions = rng.integers(0, world.samples.shape[1], 90)
    for k, (place, direction) in enumerate(zip(places.tolist(), directions.tolist(), strict=True)):
        evidence.observe(StepEvidence(place, direction, k / 100, k / 100))
    rows = world.samples.step_rows(places, directions)
    assert evidence.rows.tolist() == rows.tolist()
    assert evidence.low.tolist() == evidence.high.tolist() == [k / 100 for k in range(90)]
    assert evidence.distinct[evidence.which].tolist() == rows.tolist()
    see = world.see(scenario.lights, bounce=False)
    assert any(light.is_moving for light in see.lights)
    expected = world.samples.light_at(see, evidence.distinct, evidence.offsets)
    assert np.array_equal(evidence.light_at(see), expected)
    assert np.array_equal(evidence.light_at(see, np.array([2, 0])), expected[[2, 0]])


def test_a_steps_readings_clamp_a_prediction_as_applying_them_in_turn_would(world):
    threshold = world.threshold
    readings = {  # (low, high) in the order read
        (5, 0): [(0.1, 0.1), (threshold, math.inf)],  # read 0.1, then detected: the threshold
        (5, 1): [(threshold, math.inf), (0.1, 0.1)],  # detected, then read 0.1: 0.1
        (6, 2): [(0.0, 0.2)],  # reached the goal: at most 0.2
        (6, 3): [(0.0, 0.2), (threshold, math.inf), (0.0, 0.25)],  # up to the threshold, capped
    }
    evidence = EvidenceSet(world, 0.004, 0.02)
    for (place, direction), bounds in readings.items():
        for low, high in bounds:
            evidence.observe(StepEvidence(place, direction, low, high))
    places, directions, low, high = evidence.clamps()
    assert list(zip(places.tolist(), directions.tolist(), strict=True)) == list(readings)
    for predicted, expected in (
        (0.05, [threshold, 0.1, 0.05, 0.25]),
        (0.9, [threshold, 0.1, 0.2, 0.25]),
    ):
        assert np.clip(predicted, low, high).tolist() == pytest.approx(expected)


def test_a_step_read_detected_and_dark_is_mixed_with_its_share_and_dark_light(world):
    evidence = EvidenceSet(world, 0.004, 0.02, JITTER)
    for low, high in ((0.1, 0.1), (world.threshold, math.inf), (0.2, 0.2)):
        evidence.observe(StepEvidence(7, 2, low, high))
    evidence.observe(StepEvidence(8, 1, world.threshold, math.inf))  # detected every time
    evidence.observe(StepEvidence(9, 0, 0.05, 0.05))  # dark every time
    places, directions, share, dark = evidence.mixed_steps()
    assert places.tolist() == [7] and directions.tolist() == [2]
    assert share.tolist() == pytest.approx([1 / 3]) and dark.tolist() == pytest.approx([0.15])


def test_without_jitter_a_step_is_predicted_at_its_nodes_as_the_lattice_judges_it(world, truth):
    evidence = EvidenceSet(world, 0.004, 0.02)
    rows = np.arange(0, world.samples.x.shape[0], 7)
    shape = world.samples.shape
    for row in rows.tolist():
        evidence.observe(StepEvidence(row // shape[1], row % shape[1], 0.0, 0.0))
    low, high = evidence.predict(evidence.light_at(truth))
    peaks = world.samples.step_peaks(world.samples.light_at(truth, rows))
    assert np.array_equal(low, peaks) and np.array_equal(high, peaks)


def test_the_shifted_samples_are_the_step_walked_that_far_off_its_nodes(world, truth):
    evidence = EvidenceSet(world, 0.004, 0.02, JITTER)
    assert evidence.offsets.tolist() == [
        [0.0, 0.0], [JITTER, 0.0], [0.0, JITTER], [-JITTER, 0.0], [0.0, -JITTER]
    ]  # fmt: skip
    evidence.observe(StepEvidence(5, 2, 0.0, 0.0))
    light = evidence.light_at(truth)
    samples, width = world.samples, world.samples.width
    row = evidence.distinct[0]
    for k, (dx, dy) in enumerate(evidence.offsets):
        direct = truth.many(samples.x[row] + dx, samples.y[row] + dy)
        assert np.array_equal(light[0, k * width : (k + 1) * width], direct)


def edge_step(world, truth):
    """A step of simple-maze's lights dark at its nodes and lit above the threshold with its
    way shifted by JITTER: a beam edge beside the node."""
    evidence = EvidenceSet(world, 0.004, 0.02, JITTER)
    places, directions = world.samples.shape
    for row in range(places * directions):
        evidence.observe(StepEvidence(row // directions, row % directions, 0.0, 0.0))
    light = evidence.light_at(truth)
    peaks = light.reshape(light.shape[0], len(evidence.offsets), -1).max(axis=2)
    edges = np.flatnonzero((peaks[:, 0] == 0.0) & (peaks.max(axis=1) >= world.threshold))
    assert edges.size, 'no beam edge within the jitter of a node'
    row = int(evidence.distinct[edges[0]])
    return row // directions, row % directions


def test_with_jitter_a_step_read_dark_once_and_detected_once_contradicts_no_true_light(world):
    """The true lights, as a hypothesis, miss the detection at the node (the reading the
    environment gave a pose 10 cm off it) by 30 tolerances; with the jitter each reading costs
    only the log of the share of the poses that explain it (the node's 0.6, 0.1 a shift)."""
    scenario = load_scenario('simple-maze')
    truth = world.see(scenario.lights)
    place, direction = edge_step(world, truth)
    energies = {}
    for jitter in (0.0, JITTER):
        belief = LightBelief(world, np.random.default_rng(0), BeliefSettings(pose_jitter=jitter))
        belief.observe(StepEvidence(place, direction, 0.0, 0.0))
        belief.observe(StepEvidence(place, direction, world.threshold, math.inf))
        lights = [belief._make(parameters_of(light)) for light in scenario.lights]
        energies[jitter] = belief._energy(lights) - belief.settings.light_cost * len(lights)
    peaks = belief.observed.light_at(truth).reshape(1, 5, -1).max(axis=2)[0]
    lit = peaks >= world.threshold
    assert not lit[0] and lit.any()  # dark at the node, lit walked off it
    shares = belief.observed.shares
    assert shares.tolist() == [0.6, 0.1, 0.1, 0.1, 0.1]
    dark_and_lit = -math.log(shares[~lit].sum()) - math.log(shares[lit].sum())
    assert energies[JITTER] == pytest.approx(dark_and_lit, abs=1e-6)
    assert energies[0.0] > 20.0  # the detection missed by the threshold: 30 tolerances


def parameters_of(light):
    """A Searchlight as the six parameters a hypothesis has (``light_from_parameters``)."""
    beta = (1.0 - light.delta) / (light.delta * light.range**2)
    return (light.x, light.y, light.direction, light.fov, beta, light.range)


def test_pose_jitter_is_checked():
    with pytest.raises(ValueError, match='pose_jitter'):
        BeliefSettings(pose_jitter=-0.1)


def test_with_jitter_a_reading_explained_only_off_the_node_costs_more_and_repeats_count(world):
    """The likelihood where the pose jitters: a reading a field explains at its node costs
    -log(0.6 + ...), one it explains only at one shift -log(0.1); the same reading twice costs
    twice (readings are kept once with their count)."""
    evidence = EvidenceSet(world, 0.004, 0.02, JITTER)
    evidence.observe(StepEvidence(3, 1, 0.5, 0.5))
    width = world.samples.width
    at_node = np.zeros((1, 5 * width))
    at_node[0, :width] = 0.5
    at_shift = np.zeros((1, 5 * width))
    at_shift[0, width : 2 * width] = 0.5
    assert evidence.energy(at_node) == pytest.approx(-math.log(0.6), abs=1e-9)
    assert evidence.energy(at_shift) == pytest.approx(-math.log(0.1), abs=1e-9)
    evidence.observe(StepEvidence(3, 1, 0.5, 0.5))
    assert evidence.energy(at_shift) == pytest.approx(-2 * math.log(0.1), abs=1e-9)
    assert evidence.energy(None) > 30.0  # no light: missed by 0.5 at every pose


def test_the_steps_a_prediction_leaves_too_dark_or_too_bright_are_named_with_their_samples():
    """What the polish's edge moves read: distinct steps a predicted range misses by more than a
    tolerance each way (a detection predicted dark, a dark reading predicted lit), and their
    samples where the lattice has them."""
    scenario = load_scenario('map1-moving')
    world = LightWorld(scenario)
    evidence = EvidenceSet(world, 0.004, 0.02)
    readings = [(3, 1, 0.5, math.inf), (4, 0, 0.0, 0.0), (5, 2, 0.2, 0.2), (3, 1, 0.5, math.inf)]
    for place, direction, low, high in readings:
        evidence.observe(StepEvidence(place, direction, low, high))
    predicted = np.array([0.1, 0.3, 0.2, 0.1])  # per observation: dark, lit, right, dark
    too_dark, too_bright = evidence.wanting(predicted, predicted)
    assert too_dark.tolist() == [0] and too_bright.tolist() == [1]
    x, y, t = evidence.sample_points(np.array([1, 2]))
    rows = world.samples.step_rows(np.array([4, 5]), np.array([0, 2]))
    assert np.array_equal(x, world.samples.x[rows]) and np.array_equal(y, world.samples.y[rows])
    assert np.array_equal(t, world.samples.t[rows])
