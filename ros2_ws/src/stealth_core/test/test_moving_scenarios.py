"""The shipped moving-light variants need timing, and the time-expanded planners solve them.

For each ``scenarios/<map>-moving.yaml``: no route to the goal stays dark at every time (each
one takes a step that some phase of the lights' cycle catches), so whatever ignores time is seen
for some start time; and with time in the state a covert route exists: value iteration on the
time-expanded lattice (node x phase) and the time-aware Dark Path reach the goal unseen, while
A* is detected.
"""

from collections import deque

import numpy as np
import pytest
from stealth_core.gym_env import lattice_model
from stealth_core.light_cycle import lattice_step_seconds
from stealth_core.planners import astar, dark_path, follow, value_iteration, walk
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import load_scenario, scenario_paths
from stealth_core.searchlight import PatrolMotion, SweepMotion

MOVING = [path.stem for path in scenario_paths() if path.stem.endswith('-moving')]


def dark_at_every_time(model, path_nodes=None) -> list[int] | None:
    """A route over nodes taking only steps that no phase catches (BFS), or None."""
    n = len(model.nodes)
    caught = model.step_seen.reshape(model.cycle_bins, n, -1).any(axis=0)
    moves = model.successors[:n] % n
    came_from = {model.start: None}
    frontier = deque([model.start])
    while frontier:
        i = frontier.popleft()
        if model.goal[i]:
            return [i]
        for direction, j in enumerate(moves[i]):
            if not caught[i, direction] and j not in came_from:
                came_from[j] = i
                frontier.append(j)
    return None


def test_every_map_has_a_moving_variant_with_a_sweep_and_a_patrol_among_them():
    statics = {path.stem for path in scenario_paths()} - set(MOVING)
    statics = {name for name in statics if not name.endswith(('-exposure', '-bounce'))}
    assert {f'{name}-moving' for name in statics} == set(MOVING)
    kinds = set()
    for name in MOVING:
        scenario = load_scenario(name)
        assert scenario.timing is not None and scenario.timing.cycle_bins > 1
        # every lattice move fits a step (the half turn and drive, with time to settle), and a
        # step is no longer than that needs
        longest = lattice_step_seconds(0.5)
        assert longest < scenario.timing.step_seconds < longest + 0.5
        kinds |= {type(light.motion) for light in scenario.lights if light.is_moving}
    assert kinds == {SweepMotion, PatrolMotion}


@pytest.fixture(scope='module', params=MOVING)
def model(request):
    return lattice_model(request.param)


def test_no_route_is_dark_at_every_time(model):
    assert dark_at_every_time(model) is None
    # ... while the static variant's own covert route exists (the check can say yes).
    static = lattice_model(model.task.scenario.name.removesuffix('-moving'))
    assert dark_at_every_time(static) is not None


def test_with_timing_a_covert_route_exists(model):
    threshold = model.task.scenario.detection_threshold
    optimum = value_iteration(model)
    best = walk(model, follow(model, lambda i: int(optimum.policy[i])))
    assert best.outcome is EpisodeOutcome.SUCCESS and best.peak_visibility < threshold
    assert best.total_reward == pytest.approx(optimum.optimal_return)
    dark = walk(model, dark_path(model))
    assert dark.outcome is EpisodeOutcome.SUCCESS and dark.peak_visibility < threshold
    assert dark.total_reward <= optimum.optimal_return + 1e-9
    assert walk(model, astar(model)).outcome is EpisodeOutcome.DETECTED


def test_the_optimal_route_is_seen_when_walked_at_another_time(model):
    """The same moves started some bins later are caught: the route is covert by its timing."""
    optimum = value_iteration(model)
    path = follow(model, lambda i: int(optimum.policy[i]))
    n = len(model.nodes)
    directions = [model.direction(a, b) for a, b in zip(path, path[1:], strict=False)]
    caught_at = []
    for delay in range(1, model.cycle_bins):
        place = model.start + delay * n
        seen = False
        for direction in directions:
            seen |= bool(model.step_seen[place, direction])
            place = int(model.successors[place, direction])
        caught_at.append(seen)
    assert any(caught_at)


def test_a_step_is_caught_between_lattice_nodes_and_bins(model):
    """Some steps start and end dark yet are caught on the way (a beam crossed between two
    nodes, or swept over a waiting robot between two bins): judging only the ends would let
    the robot through."""
    ends_dark = ~model.seen[:, None] & ~model.seen[model.successors]
    assert np.any(model.step_seen & ends_dark)
