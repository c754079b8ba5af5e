"""The light belief: a search under the law's own form finds the lights that explain the steps,
a moving light with its period and phase where the world has phase bins."""

import dataclasses

import numpy as np
from stealth_core.lattice_model import LatticeModel
from stealth_core.light_belief import BeliefSettings, LightBelief
from stealth_core.light_world import SWEEP, LightWorld, StepEvidence
from stealth_core.scenario import load_scenario
from stealth_core.task import StealthTask


def steps_near(model, centre, radius, rng, count):
    """Random lattice steps (place, direction) starting within radius m of centre, every bin."""
    near = np.flatnonzero(np.hypot(*(model.points - centre).T) <= radius)
    places = rng.choice(near, count)
    return places, rng.integers(0, 4, count)


def test_a_sweeping_light_is_found_with_its_period_from_the_light_its_steps_met():
    """simple-maze-moving's sweeping guard alone: 500 steps around it at every phase, read
    exactly, are explained by one sweeping light of the cycle's period, which then calls lit or
    dark 300 steps it never saw as the truth does."""
    scenario = load_scenario('simple-maze-moving')
    (guard,) = [light for light in scenario.lights if light.is_moving]
    scenario = dataclasses.replace(scenario, lights=(guard,))
    truth = LatticeModel.build(StealthTask(scenario)).step_visibility
    world = LightWorld(scenario)
    belief = LightBelief(world, np.random.default_rng(0), BeliefSettings())
    rng = np.random.default_rng(1)
    places, directions = steps_near(world.model, (guard.x, guard.y), 6.0, rng, 500)
    for place, direction in zip(places.tolist(), directions.tolist(), strict=True):
        value = float(truth[place, direction])
        belief.observe(StepEvidence(place, direction, value, value))
    for _ in range(3):
        belief.fit()
    best = belief.particles[belief.best()]
    sweeps = [light.params for light in best.lights if int(light.params[6]) == SWEEP]
    assert sweeps, [light.params for light in best.lights]
    assert any(int(params[9]) == world.timing.cycle_bins for params in sweeps)
    places, directions = steps_near(world.model, (guard.x, guard.y), 6.0, rng, 300)
    predicted = belief.step_visibility(belief.best())[places, directions]
    lit = truth[places, directions] >= world.threshold
    agree = np.mean((predicted >= world.threshold) == lit)
    assert agree >= 0.9 and lit.any(), (agree, int(lit.sum()))


def test_where_lights_move_a_hypothesis_without_a_moving_light_costs_one_light_more():
    world = LightWorld(load_scenario('simple-maze-moving'))
    belief = LightBelief(world, np.random.default_rng(0))
    belief.observe(StepEvidence(world.model.start, 0, 0.0, 0.0))
    settings = belief.settings
    assert belief._energy([]) == settings.still_cost
    still = LightWorld(load_scenario('simple-maze'))
    assert LightBelief(still, np.random.default_rng(0))._energy([]) == 0.0


def test_with_a_pose_jitter_a_plan_sees_every_step_at_its_nodes_and_at_each_shift():
    """The shifted visibility a plan weighs: at the nodes exactly the particle's step
    visibility, and at each shift the light of its lights at the shifted samples, on every
    step, not only on those the belief finds a light could reach (map1-moving: a static
    light, a patrol and a sweep)."""
    world = LightWorld(load_scenario('map1-moving'))
    belief = LightBelief(world, np.random.default_rng(0), BeliefSettings(pose_jitter=0.15))
    (x0, y0), (x1, y1), (x2, y2) = world.model.points[[5, 60, 120]]
    static = (x0, y0, 0.3, 1.0, 0.2, 6.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    patrol = (x1, y1, 2.0, 0.8, 0.3, 5.0, 2.0, x1 + 1.0, y1 - 1.0, 8.0, 0.4)
    sweep = (x2, y2, -1.0, 0.3, 0.1, 7.0, 1.0, 2.5, 0.0, 4.0, 1.0)
    belief.particles[0].lights = [belief._make(p) for p in (static, patrol, sweep)]
    shifted = belief.shifted_visibility(0)
    offsets = belief.observed.offsets
    assert shifted.shape == (*world.samples.shape, len(offsets))
    assert np.array_equal(shifted[..., 0], belief.step_visibility(0))
    see = world.see(belief.lights(0))
    everywhere = world.samples.light_at(see, None, offsets)
    peaks = everywhere.reshape(everywhere.shape[0], len(offsets), -1).max(axis=2)
    np.testing.assert_allclose(shifted.reshape(-1, len(offsets)), peaks, rtol=0, atol=1e-12)
    off_node = shifted[..., 1:].max(axis=2) >= world.threshold
    assert np.any(off_node & (shifted[..., 0] < world.threshold))  # lit only walked off
    without = LightBelief(world, np.random.default_rng(0))
    without.particles[0].lights = [without._make(static)]
    assert np.array_equal(without.shifted_visibility(0)[..., 0], without.step_visibility(0))
