"""The covert planner's core: paths equal to value iteration's optimum, judged unseen, and every
Nav2 error with its reason (plain pytest, no rclpy)."""

import dataclasses
import math

import numpy as np
import pytest
from stealth_core.lattice_model import LatticeModel
from stealth_core.planners import follow, optimal_path, value_iteration, walk
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import load_scenario
from stealth_core.task import StealthTask
from stealth_nav2.covert_planning import (
    CovertPlanner,
    Pose,
    TaskNumbers,
    densify,
    scenario_of,
)
from stealth_nav2.plan_errors import PlanError
from stealth_nav2.scene_source import Scene, scene_from_scenario


@pytest.fixture(scope='module')
def lgfloor():
    return scene_from_scenario('lgfloor')


@pytest.fixture(scope='module')
def planner():
    return CovertPlanner()


def goal_pose(scene, name='hard', yaw=0.0):
    goal = scene.scenario.goals[name]
    return Pose(goal.x, goal.y, yaw)


def start_pose(scene):
    return Pose(*scene.scenario.start)


def error_of(call) -> PlanError:
    with pytest.raises(PlanError) as caught:
        call()
    assert '\n' not in str(caught.value)
    return caught.value


@pytest.mark.parametrize('name', ['lgfloor', 'simple-maze-moving', 'map1-exposure'])
def test_covert_path_is_value_iterations_optimum(name):
    scene = scene_from_scenario(name)
    plan = CovertPlanner().plan(scene, start_pose(scene), goal_pose(scene, yaw=1.0))
    points, result = optimal_path(scene.scenario, 'hard', poses=True)
    assert result.outcome is EpisodeOutcome.SUCCESS
    assert np.array_equal(plan.poses[:, :2], points[:, :2])
    assert plan.poses[-1, 2] == 1.0  # the goal's orientation
    assert plan.steps == len(points) - 1 and plan.planner_id == 'covert'
    step_seconds = StealthTask(scene.scenario).step_seconds
    assert np.allclose(np.diff(plan.times), step_seconds)


def test_poses_face_the_next_pose(lgfloor, planner):
    plan = planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor))
    xy, yaw = plan.poses[:, :2], plan.poses[:, 2]
    for k in range(len(xy) - 1):
        dx, dy = xy[k + 1] - xy[k]
        assert math.isclose(yaw[k], math.atan2(dy, dx))


def test_moving_lights_time_the_path_from_the_request_time():
    """Lights at another time of their cycle: the robot starts at the next bin boundary (the
    first pose's time), and the path is value iteration's optimum from that place, unseen."""
    scene = scene_from_scenario('simple-maze-moving')
    timing = scene.scenario.timing
    t = 2.5 * timing.bin_seconds  # mid-bin: the robot starts at bin 3
    planner = CovertPlanner()
    plan = planner.plan(scene, start_pose(scene), goal_pose(scene), t=t)
    assert math.isclose(plan.times[0], 0.5 * timing.bin_seconds)
    on_boundary = planner.plan(
        scene, start_pose(scene), goal_pose(scene), t=3 * timing.bin_seconds
    )
    assert np.array_equal(plan.poses, on_boundary.poses) and on_boundary.times[0] == 0.0
    at_zero = planner.plan(scene, start_pose(scene), goal_pose(scene), t=0.0)
    model = LatticeModel.build(StealthTask(scene.scenario, 'hard'))
    optimum = value_iteration(model)
    start = model.start + 3 * len(model.nodes)
    model = dataclasses.replace(model, start=start)
    path = follow(model, lambda i: int(optimum.policy[i]))
    assert np.array_equal(plan.poses[:, :2], model.points[path])
    assert not np.array_equal(plan.poses[:, :2], at_zero.poses[:, :2])  # the time matters
    assert plan.peak_visibility < scene.scenario.detection_threshold


def test_cached_goal_gives_the_same_path(lgfloor):
    planner = CovertPlanner()
    first = planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor))
    again = planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor))
    assert not first.cached and again.cached
    assert np.array_equal(first.poses, again.poses)


def test_a_start_off_the_lattice_snaps_to_its_node(lgfloor, planner):
    x, y, _ = lgfloor.scenario.start
    plan = planner.plan(lgfloor, Pose(x + 0.2, y - 0.1), goal_pose(lgfloor))
    assert np.array_equal(plan.poses[0, :2], [x, y])


@pytest.mark.parametrize('planner_id', ['dark_path', 'covert'])
def test_every_answer_is_unseen_when_walked(lgfloor, planner, planner_id):
    """Each path walked through the task, as an episode: it reaches the goal undetected."""
    plan = planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor), planner_id)
    model = LatticeModel.build(StealthTask(lgfloor.scenario, 'hard'))
    index = {tuple(p): i for i, p in enumerate(model.points)}
    path = [index[tuple(p)] for p in plan.poses[:, :2]]
    assert walk(model, path).outcome is EpisodeOutcome.SUCCESS
    assert plan.peak_visibility < lgfloor.scenario.detection_threshold


def test_through_poses_joins_legs_at_their_ends(lgfloor, planner):
    medium, hard = goal_pose(lgfloor, 'medium'), goal_pose(lgfloor, 'hard')
    plan = planner.plan_through(lgfloor, start_pose(lgfloor), [medium, hard])
    first = planner.plan(lgfloor, start_pose(lgfloor), medium)
    assert np.array_equal(plan.poses[: len(first.poses), :2], first.poses[:, :2])
    assert plan.steps > first.steps


# --- errors ---------------------------------------------------------------------------------


def test_goal_outside_the_map(lgfloor, planner):
    error = error_of(lambda: planner.plan(lgfloor, start_pose(lgfloor), Pose(500.0, 0.0)))
    assert error.code == 'GOAL_OUTSIDE_MAP' and 'goal (500.00, 0.00) is outside the map' in str(
        error
    )


def test_start_outside_the_map(lgfloor, planner):
    error = error_of(lambda: planner.plan(lgfloor, Pose(0.0, -500.0), goal_pose(lgfloor)))
    assert error.code == 'START_OUTSIDE_MAP' and 'start (0.00, -500.00)' in str(error)


def wall_point(scene):
    rows, cols = np.nonzero(scene.map.occupied)
    x, y = scene.map.cell_to_world(cols[0], rows[0])
    return Pose(float(x), float(y))


def test_goal_in_a_wall(lgfloor, planner):
    error = error_of(lambda: planner.plan(lgfloor, start_pose(lgfloor), wall_point(lgfloor)))
    assert error.code == 'GOAL_OCCUPIED' and 'in an occupied cell' in str(error)


def test_start_in_a_wall(lgfloor, planner):
    error = error_of(lambda: planner.plan(lgfloor, wall_point(lgfloor), goal_pose(lgfloor)))
    assert error.code == 'START_OCCUPIED' and 'in an occupied cell' in str(error)


def lit_goal(scene) -> Pose:
    """A point every lattice node within the goal radius of which is in the light."""
    model = LatticeModel.build(StealthTask(scene.scenario))
    radius = scene.scenario.goal_radius
    for x, y in model.points[model.seen]:
        near = np.hypot(model.points[:, 0] - x, model.points[:, 1] - y) <= radius
        if model.seen[near].all():
            return Pose(float(x), float(y))
    raise AssertionError('no lit goal in the scenario')


def test_no_covert_route(lgfloor, planner):
    """A goal in the light: every way there is seen, so no path, never a seen one."""
    error = error_of(lambda: planner.plan(lgfloor, start_pose(lgfloor), lit_goal(lgfloor)))
    assert error.code == 'NO_VALID_PATH' and 'no covert route' in str(error)


def test_astar_refuses_its_seen_path(lgfloor, planner):
    error = error_of(
        lambda: planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor), 'astar')
    )
    assert error.code == 'NO_VALID_PATH' and 'is seen at' in str(error)
    assert '>= detection threshold 0.3' in str(error)


def test_unknown_planner_id(lgfloor, planner):
    error = error_of(lambda: planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor), 'x'))
    assert error.code == 'INVALID_PLANNER'
    assert str(error) == (
        "planner id 'x' is invalid; planner ids are: covert dark_path astar policy (and "
        "GridBased, Nav2's default, for covert)"
    )


@pytest.mark.parametrize('planner_id', ['', 'GridBased'])
def test_the_default_ids_are_the_covert_optimum(lgfloor, planner, planner_id):
    plan = planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor), planner_id)
    covert = planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor), 'covert')
    assert plan.planner_id == 'covert' and np.array_equal(plan.poses, covert.poses)


def test_no_goals(lgfloor, planner):
    error = error_of(lambda: planner.plan_through(lgfloor, start_pose(lgfloor), []))
    assert error.code == 'NO_VIAPOINTS_GIVEN'


def test_planning_longer_than_the_limit(lgfloor):
    planner = CovertPlanner()
    error = error_of(
        lambda: planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor), max_time=1e-9)
    )
    assert error.code == 'TIMEOUT' and 'more than max_planning_time' in str(error)


def test_policy_without_a_file(lgfloor, planner):
    error = error_of(
        lambda: planner.plan(lgfloor, start_pose(lgfloor), goal_pose(lgfloor), 'policy')
    )
    assert error.code == 'INVALID_PLANNER' and 'policy_file' in str(error)


# --- a scene from topics ----------------------------------------------------------------------


def test_a_scene_without_a_scenario_plans_with_the_task_numbers():
    scenario = load_scenario('simple-maze')
    scene = Scene(map=scenario.map, lights=scenario.lights, source='topics')
    numbers = TaskNumbers(robot_radius=scenario.robot_radius, step_limit=300)
    built = scenario_of(scene, numbers, scenario.start[:2])
    assert built.start[:2] == scenario.start[:2]
    assert built.step_limit == 300 and built.lights == scenario.lights
    plan = CovertPlanner(numbers).plan(
        scene,
        start_pose(scene_from_scenario('simple-maze')),
        goal_pose(scene_from_scenario('simple-maze')),
    )
    assert plan.peak_visibility < numbers.detection_threshold


def test_densify_keeps_the_nodes_and_interpolates_times():
    poses = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.5, 0.5, 1.0]])
    times = np.array([0.0, 1.0, 2.0])
    dense, dense_times = densify(poses, times, 0.1)
    assert len(dense) == 11
    assert np.allclose(dense[5], [0.5, 0.0, 0.0]) and dense_times[5] == 1.0
    assert np.allclose(dense_times, np.linspace(0.0, 2.0, 11))
    assert densify(poses, times, 0.0)[0] is poses
