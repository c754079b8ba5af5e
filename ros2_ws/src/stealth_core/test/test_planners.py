"""Baselines: the lattice model, A*, Dark Path and value iteration, and what they prove about
every shipped scenario."""

import dataclasses

import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv, lattice_model
from stealth_core.lattice_model import PERPENDICULAR, action_distribution
from stealth_core.planners import (
    astar,
    dark_path,
    follow,
    optimal_path,
    step_terms,
    value_iteration,
    walk,
)
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import load_scenario, scenario_paths

SHIPPED = [path.stem for path in scenario_paths()]


@pytest.fixture(scope='module')
def model():
    return lattice_model('map1')


def test_the_model_is_the_lattice(model):
    lattice, task = model.task.lattice, model.task
    assert model.nodes == list(lattice.valid_nodes())
    for i in range(0, model.size, 37):
        for action in range(4):
            target = lattice.successor(model.nodes[i], action)
            expected = i if target is None else model.nodes.index(target)
            assert model.successors[i, action] == expected
        x, y = model.points[i]
        assert model.visibility[i] == task.visibility(x, y)
        assert tuple(model.states[i]) == tuple(np.float32(task.state_of(x, y)))
    assert model.points[model.start].tolist() == list(task.scenario.start[:2])


def test_slip_goes_sideways_only():
    moves = action_distribution(0.2)
    np.testing.assert_allclose(moves.sum(axis=1), 1.0)
    for action, sideways in enumerate(PERPENDICULAR[:4]):
        assert moves[action, action] == pytest.approx(0.8)
        assert all(moves[action, side] == pytest.approx(0.1) for side in sideways)
    with_wait = action_distribution(0.2, 5)
    np.testing.assert_allclose(with_wait[:4, :4], moves)
    assert with_wait[4].tolist() == [0, 0, 0, 0, 1]  # a wait never slips
    assert with_wait[:4, 4].tolist() == [0, 0, 0, 0]  # and no move turns into one
    with pytest.raises(ValueError, match='slip'):
        action_distribution(1.5)


def test_astar_is_a_shortest_path(model):
    path = astar(model)
    lattice = model.task.lattice
    targets = {model.nodes[i] for i in np.flatnonzero(model.goal)}
    shortest = lattice.bfs(model.nodes[model.start], goal=targets.__contains__)
    assert len(path) == len(shortest)
    assert path[0] == model.start and model.goal[path[-1]]
    for a, b in zip(path, path[1:], strict=False):
        assert b in model.successors[a] and a != b


def test_dark_path_never_enters_a_seen_node_and_trades_length_for_darkness(model):
    walked = {}
    for weight in (0.0, 10.0, 1000.0):
        path = dark_path(model, weight)
        assert not model.seen[path].any()
        walked[weight] = walk(model, path)
    lattice = model.task.lattice
    targets = {model.nodes[i] for i in np.flatnonzero(model.goal)}
    index = {node: i for i, node in enumerate(model.nodes)}
    unseen = lattice.bfs(
        model.nodes[model.start],
        goal=targets.__contains__,
        passable=lambda node: not model.seen[index[node]],
    )
    assert walked[0.0].steps == len(unseen) - 1  # weight 0: the shortest undetected path
    darkness = [walked[w].accumulated_visibility for w in (0.0, 10.0, 1000.0)]
    assert darkness == sorted(darkness, reverse=True)
    assert walked[0.0].steps <= walked[10.0].steps <= walked[1000.0].steps
    with pytest.raises(ValueError, match='weight'):
        dark_path(model, -1.0)


def test_value_iteration_beats_every_path_and_its_own_path_earns_it(model):
    optimum = value_iteration(model)
    assert optimum.converged and optimum.gamma == 1.0
    own = walk(model, follow(model, lambda i: int(optimum.policy[i])))
    assert own.outcome is EpisodeOutcome.SUCCESS
    assert own.total_reward == pytest.approx(optimum.optimal_return)
    for path in (astar(model), dark_path(model, 0.0), dark_path(model, 1000.0)):
        assert walk(model, path).total_reward <= optimum.optimal_return + 1e-9
    assert value_iteration(model, gamma=0.99).optimal_return < optimum.optimal_return


def test_follow_stops_at_a_place_without_an_action(model):
    """A policy with no action (-1) at a place (one that never saw it) ends the path there,
    rather than taking the last action (what index -1 would)."""
    best = value_iteration(model).policy
    full = follow(model, lambda i: int(best[i]))
    assert len(full) > 3
    actions = best.copy()
    actions[full[2]] = -1
    assert follow(model, lambda i: actions[i]) == full[:3]


def test_a_short_horizon_binds(model):
    short = value_iteration(model, horizon=10)
    assert not short.converged and short.optimal_return < 0  # the goal is out of reach


def test_value_iteration_with_slip_is_the_expected_return_in_the_env(model):
    slip = 0.1
    optimum = value_iteration(model, slip=slip)
    assert optimum.optimal_return < value_iteration(model).optimal_return
    env = StealthNavEnv('map1', slip=slip)
    env.reset(seed=0)
    returns = []
    for _ in range(300):
        env.reset()
        node, total, done = model.start, 0.0, False
        while not done:
            _, reward, terminated, truncated, _ = env.step(int(optimum.policy[node]))
            node, total, done = env.node, total + reward, terminated or truncated
        returns.append(total)
    error = np.std(returns) / np.sqrt(len(returns))
    assert abs(np.mean(returns) - optimum.optimal_return) < 4 * error + 1e-6


def test_probabilistic_detection_is_an_expectation(model):
    scenario = dataclasses.replace(model.task.scenario, detection_mode='probabilistic')
    probabilistic = lattice_model(scenario)
    p_detected, _, _ = step_terms(probabilistic)
    lit = probabilistic.step_visibility > 0
    assert ((p_detected > 0) & (p_detected < 1))[lit].all() and (p_detected[~lit] == 0).all()
    assert value_iteration(probabilistic).optimal_return <= value_iteration(model).optimal_return


def test_the_optimum_with_moving_lights_reaches_the_goal():
    scenario = load_scenario('simple-maze-moving')
    points, _ = optimal_path(scenario, None)
    goal = scenario.goal
    assert np.hypot(*(points[-1] - goal.point)) <= goal.radius


@pytest.mark.parametrize('name', SHIPPED)
def test_every_shipped_scenario_is_a_stealth_problem_the_planners_solve(name):
    """Value iteration and Dark Path reach the goal undetected; A* is seen."""
    model = lattice_model(load_scenario(name))
    threshold = model.task.scenario.detection_threshold
    optimum = value_iteration(model)
    best = walk(model, follow(model, lambda i: int(optimum.policy[i])))
    assert best.outcome is EpisodeOutcome.SUCCESS and best.peak_visibility < threshold
    assert best.total_reward == pytest.approx(optimum.optimal_return)
    if name != 'map1-exposure':  # there exposure makes the straight way through the door covert
        assert walk(model, astar(model)).outcome is EpisodeOutcome.DETECTED
    dark = walk(model, dark_path(model))
    assert dark.outcome is EpisodeOutcome.SUCCESS and dark.peak_visibility < threshold
