"""What the light model may know and what a step tells it: the samples of every lattice step,
each light's light at them, and the evidence read off a step's reward."""

import dataclasses
import math

import numpy as np
import pytest
from stealth_core.lattice_model import LatticeModel
from stealth_core.light_cycle import light_period
from stealth_core.light_world import (
    PATROL,
    SWEEP,
    LightWorld,
    UnmodelledLawError,
    evidence_of_step,
    hypothesis_light,
    light_from_parameters,
)
from stealth_core.reward import RewardWeights
from stealth_core.scenario import load_scenario
from stealth_core.task import StealthTask


@pytest.mark.parametrize(
    'name', ['map1', 'map1-exposure', 'map1-bounce', 'map1-moving', 'simple-maze-moving']
)
def test_the_lights_added_at_the_samples_are_the_models_step_visibility(name):
    """Light adds up: each light's light at every step's samples, summed and maximised over the
    step, is what the environment judges every step on (exposure's turns, the bounce and the
    moving lights, each sample at its time in the cycle, too)."""
    scenario = load_scenario(name)
    truth = LatticeModel.build(StealthTask(scenario)).step_visibility
    world = LightWorld(scenario)
    total = sum(world.samples.light_at(world.see([light])) for light in scenario.lights)
    peaks = world.samples.step_peaks(total).reshape(world.samples.shape)
    np.testing.assert_allclose(peaks, truth, rtol=0, atol=1e-12)


def test_the_world_holds_no_light_and_its_lattice_is_the_scenarios():
    scenario = load_scenario('map1')
    world = LightWorld(scenario)
    assert world.scenario.lights == () and world.task.scenario.lights == ()
    assert not np.any(world.model.step_visibility)
    truth = LatticeModel.build(StealthTask(scenario))
    np.testing.assert_array_equal(world.model.successors, truth.successors)
    np.testing.assert_array_equal(world.model.states, truth.states)


def test_every_step_reward_reads_back_as_its_light():
    """Exact for steps that go on, a bound for a detection and for the goal."""
    scenario = load_scenario('map1')
    task = StealthTask(scenario)
    model = LatticeModel.build(task)
    world = LightWorld(scenario)
    threshold = scenario.detection_threshold
    kinds = set()
    rng = np.random.default_rng(0)
    for place in rng.choice(model.size, 400, replace=False).tolist() + [model.start]:
        for direction in range(model.num_actions):
            arrival = int(model.successors[place, direction])
            judged = model.judge(arrival, 1, direction, previous=place)
            evidence = evidence_of_step(world, place, direction, judged.reward, judged.terminal)
            v = model.step_visibility[place, direction]
            assert evidence.low - 1e-9 <= v <= evidence.high + 1e-9  # the reward rounds
            if evidence.exact:
                assert evidence.low == pytest.approx(v, abs=1e-9)
                kinds.add('exact')
            else:
                kinds.add('detected' if evidence.high == math.inf else 'goal')
                assert (evidence.low == threshold) == (v >= threshold)
    assert {'exact', 'detected'} <= kinds
    goal_place = int(np.flatnonzero(model.goal)[0])
    for place in range(model.size):
        hits = np.flatnonzero(model.successors[place] == goal_place)
        lit = hits.size and model.step_visibility[place, hits[0]] >= threshold
        if hits.size and not lit and not model.goal[place]:
            judged = model.judge(goal_place, 1, int(hits[0]), previous=place)
            evidence = evidence_of_step(world, place, int(hits[0]), judged.reward, True)
            assert evidence.low == 0.0 and evidence.high < threshold
            break
    else:
        pytest.fail('no step into the goal')


@pytest.mark.parametrize(
    ('change', 'feature'),
    [
        ({'detection_mode': 'probabilistic'}, 'detection_mode'),
        ({'rewards': RewardWeights(visibility_weight=0.0)}, 'visibility_weight'),
    ],
)
def test_a_law_it_cannot_model_is_refused_in_one_line_naming_it(change, feature):
    scenario = dataclasses.replace(load_scenario('map1'), **change)
    with pytest.raises(UnmodelledLawError, match=feature) as error:
        LightWorld(scenario)
    assert '\n' not in str(error.value)


def test_a_moving_world_keeps_the_phase_and_the_wait_but_no_light():
    """The phase's meaning (the timing) and the time-expanded lattice are the scenario's."""
    scenario = load_scenario('map1-moving')
    world = LightWorld(scenario)
    assert world.scenario.lights == () and world.timing == scenario.timing
    truth = LatticeModel.build(StealthTask(scenario))
    assert world.model.num_actions == 5 and world.model.size == truth.size
    np.testing.assert_array_equal(world.model.successors, truth.successors)
    np.testing.assert_array_equal(world.model.states, truth.states)


def _motion_parameters(light, timing):
    """A true moving light as the hypothesis parameters that should reproduce it."""
    motion = light.motion
    period = round(light_period(light) / timing.bin_seconds)
    if hasattr(motion, 'min_direction'):
        span = motion.max_direction - motion.min_direction
        offset = motion.start_offset(light.name, light.direction)
        kind, a, b, low = SWEEP, span, 0.0, motion.min_direction
        return (
            light.x,
            light.y,
            low,
            light.fov,
            light.beta,
            light.range,
            kind,
            a,
            b,
            period,
            offset,
        )
    (end,) = motion.waypoints
    return (
        light.x,
        light.y,
        light.direction,
        light.fov,
        light.beta,
        light.range,
        PATROL,
        *end,
        period,
        0.0,
    )


@pytest.mark.parametrize('name', ['simple-maze-moving', 'map1-moving'])
def test_a_hypothesis_moves_as_the_light_it_names(name):
    """A sweep (simple-maze-moving's) and a patrol (map1-moving's) rebuilt from hypothesis
    parameters are where the scenario's light is, at every time."""
    scenario = load_scenario(name)
    (light,) = [light for light in scenario.lights if light.is_moving]
    rebuilt = hypothesis_light('h', _motion_parameters(light, scenario.timing), scenario.timing)
    for t in np.linspace(0.0, 60.0, 41):
        truth, guess = light.at(t), rebuilt.at(t)
        assert guess.x == pytest.approx(truth.x, abs=1e-9)
        assert guess.y == pytest.approx(truth.y, abs=1e-9)
        turn = math.remainder(guess.direction - truth.direction, 2 * math.pi)
        assert turn == pytest.approx(0.0, abs=1e-9)


def test_a_patrol_may_start_anywhere_on_its_loop():
    """Offset 3/4 of the way round a 4 m rail: 1 m short of the start, on the way back."""
    timing = load_scenario('map1-moving').timing
    params = (12.0, 10.0, 4.7, 0.8, 0.36, 5.0, PATROL, 16.0, 10.0, 8, 6.0)
    light = hypothesis_light('h', params, timing)
    assert (light.x, light.y) == pytest.approx((14.0, 10.0))
    seconds = 8 * timing.bin_seconds  # one lap of 8 m
    assert light.at(seconds / 4).x == pytest.approx(12.0)  # 2 m later: the start
    assert light.at(seconds / 2).x == pytest.approx(14.0)  # on the way out again
    assert light.at(seconds).x == pytest.approx(14.0)


def test_a_light_from_its_search_parameters_has_that_beta_and_range():
    light = light_from_parameters('h', 1.0, 2.0, 7.0, 0.5, 0.25, 6.0)
    assert light.beta == pytest.approx(0.25)
    assert light.range == 6.0 and 0 <= light.direction < 2 * math.pi


def test_sight_from_one_place_is_the_line_of_sight_from_its_cell():
    """The one-call trace a birth uses agrees with the per-lamp lines of sight."""
    world = LightWorld(load_scenario('map1'))
    points = world.points
    rng = np.random.default_rng(0)
    xs, ys = rng.uniform(0.1, 19.9, 300), rng.uniform(0.1, 19.9, 300)
    seen = points.sight_from(13.0, 8.5, xs, ys)
    source = points.frame.cell_of(13.0, 8.5)
    cells = [points.frame.cell_of(x, y) for x, y in zip(xs, ys, strict=True)]
    expected = [points.line_of_sight(source, cell) for cell in cells]
    np.testing.assert_array_equal(seen, expected)
    assert seen.any() and not seen.all()
