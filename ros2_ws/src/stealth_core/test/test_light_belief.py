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


def test_a_stop_between_taking_a_step_and_the_lights_learning_it_leaves_the_belief_whole():
    """A stop signal can land anywhere in an agent's callback, and the agent saves its belief
    at shutdown (the posterior weights with it). Two beliefs fitted alike; one takes the last
    two steps whole, the other only into its evidence (as a stop after that line leaves it):
    their weights agree, where a light short of the evidence once raised an IndexError."""
    scenario = load_scenario('simple-maze')
    truth = LatticeModel.build(StealthTask(scenario)).step_visibility
    world = LightWorld(scenario)
    light = scenario.lights[0]
    places, directions = steps_near(
        world.model, (light.x, light.y), 5.0, np.random.default_rng(2), 42
    )
    steps = [
        StepEvidence(
            place, direction, float(truth[place, direction]), float(truth[place, direction])
        )
        for place, direction in zip(places.tolist(), directions.tolist(), strict=True)
    ]
    whole, stopped = (LightBelief(world, np.random.default_rng(0)) for _ in range(2))
    for belief in (whole, stopped):
        for step in steps[:40]:
            belief.observe(step)
        belief.fit(moves=60)
        belief.observe(steps[40])
    whole.observe(steps[41])
    stopped.observed.observe(steps[41])
    assert len(whole.observed.distinct) == 42
    np.testing.assert_array_equal(stopped.weights(), whole.weights())
