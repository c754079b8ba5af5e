"""The shared task core: states, judging, bounds and episode statistics."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from stealth_core.lighting import point_visibility
from stealth_core.reward import EpisodeOutcome, detection_reward, step_reward, success_reward
from stealth_core.scenario import load_scenario
from stealth_core.task import EpisodeSummaryFields, StealthTask

MSG_DIR = Path(__file__).resolve().parents[2] / 'stealth_interfaces' / 'msg'


def msg_fields(name: str) -> list[str]:
    """Field names of a .msg file, in order (no comments, no constants, no header)."""
    names = []
    for line in (MSG_DIR / f'{name}.msg').read_text().splitlines():
        words = line.split('#', 1)[0].split()
        if len(words) == 2 and '=' not in words[1] and words[1] != 'header':
            names.append(words[1])
    return names


@pytest.fixture(scope='module')
def map1():
    return load_scenario('map1')


@pytest.fixture(scope='module')
def lgfloor():
    return load_scenario('lgfloor')


@pytest.fixture(scope='module')
def task(map1):
    return StealthTask(map1)


def lit_node_point(task):
    """A lattice node at or above the detection threshold."""
    for node in task.lattice.valid_nodes():
        x, y = task.lattice.node_to_point(node)
        if task.visibility(x, y) >= task.scenario.detection_threshold:
            return x, y
    raise AssertionError('no lit node')


# --- states -------------------------------------------------------------------------------------


def test_state_cells_are_centred_on_the_start_and_its_multiples_of_the_cell(lgfloor):
    task = StealthTask(lgfloor)  # cell 0.5 m, start (-12, 0): coordinates on both sides of 0
    assert task.state_of(-12.0, 0.0) == (-12.0, 0.0)
    assert task.state_of(0.74, 0.26) == (0.5, 0.5)
    assert task.state_of(0.76, 0.24) == (1.0, 0.0)
    assert task.state_of(-0.01, -0.24) == (0.0, 0.0)  # a cell straddles 0, the same size
    assert task.state_of(-0.26, -0.74) == (-0.5, -0.5)
    assert task.state_of(0.25, -0.25) == (0.5, 0.0)  # half-way: the cell above


def test_estimates_within_half_a_cell_of_a_lattice_node_map_to_its_state():
    """What the ROS loop needs: a localisation error of up to 0.49 cell in any direction keeps
    the node's state, on every shipped scenario and for a cell that is not a binary fraction."""
    rng = np.random.default_rng(0)
    for name in ('simple-maze', 'map1', 'lgfloor', 'floorplan'):
        scenario = load_scenario(name)
        for cell in (scenario.state_cell, 0.1):
            changed = dataclasses.replace(scenario, step_distance=cell, state_cell=cell)
            task = StealthTask(changed)
            lattice = task.lattice
            nodes = list(lattice.valid_nodes())
            for index in rng.choice(len(nodes), size=min(len(nodes), 200), replace=False):
                x, y = lattice.node_to_point(nodes[index])
                state = task.state_of(x, y)
                assert state == (x, y)  # the node itself: the values are today's
                corners = [(dx, dy) for dx in (-0.49, 0.49) for dy in (-0.49, 0.49)]
                for dx, dy in [*corners, *rng.uniform(-0.49, 0.49, size=(8, 2))]:
                    assert task.state_of(x + dx * cell, y + dy * cell) == state
                assert task.state_of(x + 0.51 * cell, y)[0] > state[0]
                assert task.state_of(x, y - 0.51 * cell)[1] < state[1]


def test_each_lattice_node_has_its_own_state_when_the_step_is_the_cell(task):
    nodes = list(task.lattice.valid_nodes())
    states = {task.state_of(*task.lattice.node_to_point(n)) for n in nodes}
    assert len(states) == len(nodes)
    for node in nodes[:50]:
        x, y = task.lattice.node_to_point(node)
        assert task.state_of(x, y) == (x, y)  # each node is its cell's centre


def test_a_move_targets_the_lattice_successor_or_stays_on_its_node(task):
    """Every action is a drive to a lattice node: the one the lattice model moves to, found
    from a pose up to half a step off its node, or the node itself when the map blocks it."""
    from stealth_core.move_lattice import ACTIONS

    lattice = task.lattice
    rng = np.random.default_rng(4)
    nodes = list(lattice.valid_nodes())
    blocked = free = 0
    for index in rng.choice(len(nodes), 200, replace=False):
        node = nodes[index]
        x, y = lattice.node_to_point(node)
        dx, dy = rng.uniform(-0.49, 0.49, 2) * lattice.step
        for action, (_, delta) in enumerate(ACTIONS):
            target = task.move_target(x + dx, y + dy, action)
            successor = lattice.successor(node, action)
            assert target == lattice.node_to_point(node if successor is None else successor)
            assert lattice.can_move(node, delta) == (successor is not None)
            blocked += successor is None
            free += successor is not None
    assert blocked and free  # both cases were met


def test_a_pose_near_no_valid_node_still_gets_the_nearest_one(task):
    lattice = task.lattice
    node = next(n for n in lattice.valid_nodes() if not lattice.is_valid((n[0] - 1, n[1])))
    x, y = lattice.node_to_point((node[0] - 1, node[1]))  # an invalid node beside a valid one
    target = task.move_target(x, y, 1)
    assert lattice.is_valid(lattice.point_to_node(*target))
    assert math.dist(target, (x, y)) <= 1.5 * lattice.step + 1e-9
    # An estimate far off every valid node (lost localisation) still gets a target, no error.
    x_min, y_min, _, _ = task.scenario.map.bounds
    far = task.move_target(x_min, y_min, 0)
    nearest = lattice.nearest_valid_node(x_min, y_min)
    assert lattice.is_valid(lattice.point_to_node(*far))
    assert math.dist(lattice.node_to_point(nearest), (x_min, y_min)) == min(
        math.dist(lattice.node_to_point(n), (x_min, y_min)) for n in lattice.valid_nodes()
    )


def test_state_bounds_cover_every_point_of_the_map(lgfloor):
    task = StealthTask(lgfloor)
    low, high = task.state_bounds()
    x_min, y_min, x_max, y_max = lgfloor.map.bounds
    assert low == task.state_of(x_min, y_min)
    almost = (x_max - 1e-6, y_max - 1e-6)
    assert high == task.state_of(*almost)
    for node in task.lattice.valid_nodes():
        state = task.state_of(*task.lattice.node_to_point(node))
        assert low[0] <= state[0] <= high[0] and low[1] <= state[1] <= high[1]


def test_description_has_the_rl_env_description_fields(task):
    description = task.description(stochastic=True)
    assert list(description) == msg_fields('RLEnvDescription')
    assert description['num_actions'] == 4
    assert description['title'] == 'stealth-nav: map1 (hard)'
    assert description['stochastic'] is True
    assert description['num_states'] == sum(1 for _ in task.lattice.valid_nodes())


# --- rewards ------------------------------------------------------------------------------------


def test_reward_bounds_span_success_at_the_goal_and_detection_far_away(task, map1):
    max_reward, reward_range = task.reward_bounds()
    assert max_reward == success_reward(0.0, map1.goal.radius, map1.rewards)
    far = max(math.hypot(x - 18.0, y - 14.5) for x in (0, 20) for y in (0, 20))
    assert task.max_distance == pytest.approx(far)
    assert reward_range == pytest.approx(max_reward - detection_reward(far, map1.rewards))


def test_an_ordinary_step_pays_the_step_reward(task, map1):
    x, y = map1.start[:2]
    judgement = task.judge(x, y, 0.0, 1)
    visibility = point_visibility(
        map1.map.blocked, map1.map.resolution, map1.map.origin, map1.lights, x, y
    )
    distance = math.hypot(x - 18.0, y - 14.5)
    assert judgement.visibility == visibility
    assert judgement.distance_to_goal == pytest.approx(distance)
    assert judgement.reward == pytest.approx(step_reward(visibility, distance, map1.rewards))
    assert (judgement.terminal, judgement.outcome, judgement.detected) == (False, None, False)


def test_the_goal_ends_the_episode_with_success(task, map1):
    judgement = task.judge(18.0, 14.5, 0.0, 7)
    assert judgement.outcome is EpisodeOutcome.SUCCESS and judgement.terminal
    assert judgement.reward == success_reward(0.0, 0.5, map1.rewards)


def test_a_lit_pose_is_detected(task):
    x, y = lit_node_point(task)
    judgement = task.judge(x, y, 0.0, 3)
    assert (
        judgement.outcome is EpisodeOutcome.DETECTED and judgement.detected and judgement.terminal
    )
    assert judgement.visibility >= task.scenario.detection_threshold


def test_the_step_limit_times_out(task, map1):
    x, y = map1.start[:2]
    assert not task.judge(x, y, 0.0, map1.step_limit - 1).terminal
    judgement = task.judge(x, y, 0.0, map1.step_limit)
    assert judgement.outcome is EpisodeOutcome.TIMEOUT and judgement.terminal


def test_a_given_visibility_is_used_as_is(task, map1):
    x, y = map1.start[:2]
    assert task.judge(x, y, 0.0, 1, visibility=0.5).outcome is EpisodeOutcome.DETECTED


@pytest.mark.parametrize('bad', [0, -1, 1.0, True])
def test_step_index_counts_from_one(task, bad):
    with pytest.raises(ValueError, match='step_index'):
        task.judge(2.5, 2.5, 0.0, bad)


def test_probabilistic_detection_draws_from_the_task_rng(map1):
    scenario = dataclasses.replace(map1, detection_mode='probabilistic')
    probe = StealthTask(scenario)
    x, y = lit_node_point(probe)

    def draws(seed):
        task = StealthTask(scenario, rng=np.random.default_rng(seed))
        return [task.judge(x, y, 0.0, 1).detected for _ in range(200)]

    assert draws(1) == draws(1)
    assert 0 < sum(draws(1)) < 200  # seen sometimes, not always
    with pytest.raises(ValueError, match='rng'):
        probe.judge(x, y, 0.0, 1)


def test_goals_by_name_and_default(map1):
    assert StealthTask(map1).goal == map1.goals['hard']
    assert StealthTask(map1, 'easy').goal == map1.goals['easy']
    assert StealthTask(map1, map1.goals['medium']).goal.name == 'medium'
    with pytest.raises(ValueError, match='easy, medium, hard'):
        StealthTask(map1, 'impossible')


# --- episode statistics -------------------------------------------------------------------------


def test_episode_stats_accumulate_what_episode_summary_reports(task, map1):
    stats = task.start_episode(2.5, 2.5, episode=4)
    poses = [(2.5, 3.0), (2.5, 3.5), (3.0, 3.5)]
    judgements = [task.judge(x, y, 0.0, i) for i, (x, y) in enumerate(poses, start=1)]
    for (x, y), judgement in zip(poses, judgements, strict=True):
        stats.add(x, y, judgement)
    summary = stats.summary(EpisodeOutcome.TIMEOUT)
    assert summary.episode == 4 and summary.goal == 'hard' and summary.steps == 3
    assert summary.outcome == EpisodeOutcome.TIMEOUT == 2
    assert summary.total_reward == pytest.approx(sum(j.reward for j in judgements))
    assert summary.accumulated_visibility == pytest.approx(sum(j.visibility for j in judgements))
    assert summary.peak_visibility == max(j.visibility for j in judgements)
    assert summary.path_length == pytest.approx(1.5)
    assert summary.final_distance_to_goal == judgements[-1].distance_to_goal


def test_a_fresh_episode_summary_is_at_the_start(task):
    summary = task.start_episode(2.5, 2.5).summary(EpisodeOutcome.ABORTED)
    assert (summary.steps, summary.total_reward, summary.path_length) == (0, 0.0, 0.0)
    assert summary.final_distance_to_goal == pytest.approx(math.hypot(15.5, 12.0))


def test_summary_fields_are_episode_summary_msg_fields():
    assert list(EpisodeSummaryFields._fields) == msg_fields('EpisodeSummary')
