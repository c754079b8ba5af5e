"""The shipped one-bounce variants (``scenarios/<map>-bounce.yaml``): the bounce changes the
optimal route.

For each variant and its default goal, value iteration on the move lattice is solved twice: on
the scenario as shipped (direct + bounce) and on the same scenario with the bounce taken out
(albedo 0). The optima differ: the route that is best without the bounce is seen once the
bounce is counted (walked through the bounce model, it is detected), while the bounce's own
optimum still reaches the goal unseen; and the judged values equal the per-point reference.
"""

import dataclasses

import numpy as np
import pytest
from stealth_core.bounce import point_bounce, received_light, wall_emitters
from stealth_core.gym_env import lattice_model
from stealth_core.lattice_model import LatticeModel
from stealth_core.lighting import point_visibility
from stealth_core.planners import follow, value_iteration, walk
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import load_scenario, scenario_paths
from stealth_core.task import StealthTask

BOUNCE = [path.stem for path in scenario_paths() if path.stem.endswith('-bounce')]


def test_two_maps_have_a_bounce_variant_of_their_static_scenario():
    assert len(BOUNCE) >= 2
    for name in BOUNCE:
        scenario = load_scenario(name)
        base = load_scenario(name.removesuffix('-bounce'))
        assert scenario.bounce is not None and scenario.bounce.albedo > 0
        assert base.bounce is None and not scenario.has_moving_lights
        assert scenario.lights == base.lights and scenario.map_path == base.map_path


def optimum(scenario):
    model = LatticeModel.build(StealthTask(scenario))
    solved = value_iteration(model)
    return model, solved, follow(model, lambda i: int(solved.policy[i]))


@pytest.fixture(scope='module', params=BOUNCE)
def solved(request):
    scenario = load_scenario(request.param)
    direct = dataclasses.replace(scenario, bounce=None)
    return scenario, optimum(scenario), optimum(direct)


def test_the_bounce_changes_the_optimal_route(solved):
    _, (model, with_bounce, route), (_, without, direct_route) = solved
    assert route != direct_route
    assert with_bounce.optimal_return != without.optimal_return
    own = walk(model, route)
    assert own.outcome is EpisodeOutcome.SUCCESS and not own.detected
    old = walk(model, direct_route)  # the direct-light optimum, judged with the bounce
    assert old.detected, 'the route that is best without the bounce should be seen with it'
    assert old.peak_visibility >= model.task.scenario.detection_threshold


def test_without_the_bounce_the_old_route_was_unseen(solved):
    _, _, (direct_model, _, direct_route) = solved
    result = walk(direct_model, direct_route)
    assert result.outcome is EpisodeOutcome.SUCCESS and not result.detected


def test_the_planners_judge_with_the_bounce_as_the_reference_does(solved):
    scenario, (model, _, route), _ = solved
    occupancy = scenario.map
    grid = (occupancy.blocked, occupancy.resolution, occupancy.origin)
    emitters = wall_emitters(occupancy.blocked)
    received = received_light(*grid, scenario.lights, emitters)
    points = walk(model, route).points
    for x, y in points[:: max(1, len(points) // 6)]:
        x, y = float(x) + 0.013, float(y) - 0.021  # off the lattice too
        expected = point_visibility(*grid, scenario.lights, x, y) + point_bounce(
            *grid, emitters, received, scenario.bounce, x, y
        )
        assert model.task.visibility(x, y) == expected
    gym_model = lattice_model(scenario.name)  # the Gym environment's table: the same model
    np.testing.assert_array_equal(gym_model.visibility, model.visibility)
