"""The learned policy as a planner id: a saved tabular policy followed greedily, refused when it
was learned on another map or lights (plain pytest)."""

import numpy as np
import pytest
from stealth_agent.learners import make_learner
from stealth_agent.policy_store import save_policy
from stealth_agent.state_index import StateIndex
from stealth_core.lattice_model import LatticeModel
from stealth_core.planners import optimal_path, value_iteration
from stealth_core.scenario import content_identity, load_scenario
from stealth_core.task import StealthTask
from stealth_nav2.covert_planning import CovertPlanner, Pose
from stealth_nav2.plan_errors import PlanError
from stealth_nav2.policy_behaviour import read_policy
from stealth_nav2.scene_source import scene_from_scenario


def saved_optimum(path, scenario, identity, rows=None):
    """A policy file whose Q-table is value iteration's q on the scenario's hard goal (its
    greedy policy is the optimum); rows: only these places' states (None: every place)."""
    task = StealthTask(scenario, 'hard')
    model = LatticeModel.build(task)
    q = value_iteration(model).q
    learner = make_learner('qlearning', task.num_actions)
    index = StateIndex()
    places = range(model.size) if rows is None else rows
    for place in places:
        row = index.row(model.states[place])
        learner.ensure_rows(row + 1)
        learner.q[row] = q[place]
    save_policy(path, learner, index, scenario={'title': task.title, **identity})
    return path


@pytest.fixture(scope='module')
def simple_maze():
    return scene_from_scenario('simple-maze')


def request(scene):
    goal = scene.scenario.goals['hard']
    return Pose(*scene.scenario.start), Pose(goal.x, goal.y)


def test_the_policy_is_followed_greedily(tmp_path, simple_maze):
    scenario = simple_maze.scenario
    path = saved_optimum(tmp_path / 'p.npz', scenario, content_identity(scenario))
    planner = CovertPlanner(policy=read_policy(path))
    plan = planner.plan(simple_maze, *request(simple_maze), 'policy')
    points, _ = optimal_path(scenario, 'hard')
    assert np.array_equal(plan.poses[:, :2], points)
    assert plan.planner_id == 'policy'


def test_a_policy_of_other_lights_is_refused(tmp_path, simple_maze):
    other = content_identity(load_scenario('simple-maze-moving'))
    identity = {**content_identity(simple_maze.scenario), 'lights_sha256': other['lights_sha256']}
    path = saved_optimum(tmp_path / 'p.npz', simple_maze.scenario, identity)
    planner = CovertPlanner(policy=read_policy(path))
    with pytest.raises(PlanError) as caught:
        planner.plan(simple_maze, *request(simple_maze), 'policy')
    assert caught.value.code == 'INVALID_PLANNER'
    assert 'was learned on lights other than' in str(caught.value)


def test_a_policy_without_hashes_is_refused(tmp_path, simple_maze):
    path = saved_optimum(tmp_path / 'p.npz', simple_maze.scenario, {})
    with pytest.raises(PlanError, match='records no map or lights SHA-256'):
        CovertPlanner(policy=read_policy(path)).plan(simple_maze, *request(simple_maze), 'policy')


def test_a_policy_that_never_saw_the_way_gives_no_path(tmp_path, simple_maze):
    scenario = simple_maze.scenario
    start = LatticeModel.build(StealthTask(scenario)).start
    path = saved_optimum(tmp_path / 'p.npz', scenario, content_identity(scenario), [start])
    planner = CovertPlanner(policy=read_policy(path))
    with pytest.raises(PlanError) as caught:
        planner.plan(simple_maze, *request(simple_maze), 'policy')
    assert caught.value.code == 'NO_VALID_PATH'


def test_an_unreadable_policy_file_is_named(tmp_path):
    bad = tmp_path / 'bad.npz'
    bad.write_bytes(b'not a policy')
    with pytest.raises(PlanError, match='bad.npz: corrupt'):
        read_policy(bad)
