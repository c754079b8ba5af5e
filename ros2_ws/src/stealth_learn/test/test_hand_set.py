"""The generalist's hand-set twin: the environment's reward written into the same network is
the reward value iteration's step pays (read on the grid's inputs), it plays value iteration's
optimum, and it is a valid weights file of the architecture."""

import dataclasses

import numpy as np
import pytest
from stealth_core.reward import detection_reward, step_reward, success_reward
from stealth_learn import generalist_data as data
from stealth_learn import policy_file
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import GeneralistPolicy, rollout
from stealth_learn.hand_set import ScenarioReward, hand_set_params
from stealth_learn.jax_deps import jnp
from stealth_learn.obs_layout import layout_id
from stealth_learn.vin import FREE, GOAL, MOVE_RIGHT, MOVE_UP, Vin, move_features

SHIPPED = {'iterations': 240, 'hidden': 32, 'features': 8, 'threshold': 0.3}


def _rewards(policy: GeneralistPolicy, grid) -> np.ndarray:
    return np.asarray(policy.model.apply(policy.variables, grid[None], method=Vin.rewards))[0]


@pytest.mark.parametrize('name', ['still', 'wider'])
def test_the_written_reward_is_the_step_value_iteration_pays(generated, name):
    """Every move from a node that is not lit: detected (less the most a place is worth: no
    backup ends an episode) where value iteration's step is seen, the success reward (less the
    goal value the backup adds) onto the goal, else the step reward, on the grid's move light
    and the lattice's distance to the goal point."""
    scenario = generated[name]
    reward = ScenarioReward.of(scenario)
    policy = GeneralistPolicy.hand_set(SHIPPED, reward)
    arrays = TaskArrays(scenario)
    model, tables = arrays.model, arrays.tables()
    grid = data.grid_of(tables)
    nodes = len(model.nodes)
    rows, cols = arrays.sensing.grid_row, arrays.sensing.grid_col
    light = np.asarray(move_features(jnp.asarray(grid)[None])[0])[0][rows, cols]
    after = model.successors[:nodes]
    distance, goal = model.distance[after], model.goal[after]
    weights, radius = scenario.rewards, reward.goal_radius
    lit = light >= scenario.detection_threshold
    most = weights.goal_reward + weights.goal_distance_weight * radius
    expected = np.where(
        lit,
        detection_reward(distance, weights) - most,
        np.where(
            goal,
            success_reward(distance, radius, weights) - weights.goal_reward,
            step_reward(light.astype(np.float64), distance, weights),
        ),
    )
    moves = after != np.arange(nodes)[:, None]
    dark_nodes = (model.visibility[:nodes] < scenario.detection_threshold)[:, None]
    checked = moves & dark_nodes
    assert lit[checked].any() and goal[checked].any() and (~lit & ~goal)[checked].any()
    np.testing.assert_array_equal(lit[checked], model.step_seen[:nodes][checked])
    written = _rewards(policy, grid)[rows, cols]
    np.testing.assert_allclose(written[checked], expected[checked], rtol=0, atol=2e-3)
    assert float(policy.variables['params']['goal_value']) == weights.goal_reward


def test_the_hand_set_twin_plays_value_iterations_optimum(generated):
    for name in ('still', 'wider'):
        scenario = generated[name]
        episode = rollout(
            GeneralistPolicy.hand_set(SHIPPED, ScenarioReward.of(scenario)), scenario
        )
        assert episode.outcome == 0, episode
        assert episode.steps == episode.optimal_steps, episode
        assert episode.episode_return == pytest.approx(episode.optimal_return, rel=1e-5)
        dark = GeneralistPolicy.hand_set(SHIPPED, ScenarioReward.of(scenario), 'dark-steps')
        shortest = rollout(dark, scenario)
        assert shortest.outcome == 0 and shortest.steps <= episode.steps, shortest


def test_the_dark_steps_reward_is_minus_one_a_move_and_minus_1e4_a_lit_one(generated):
    scenario = generated['still']
    policy = GeneralistPolicy.hand_set(SHIPPED, ScenarioReward.of(scenario), 'dark-steps')
    grid = data.grid_of(TaskArrays(scenario).tables())
    lights, exists = (np.asarray(a)[0] for a in move_features(jnp.asarray(grid)[None]))
    written = _rewards(policy, grid)[exists]
    lit = lights[exists] >= scenario.detection_threshold
    assert lit.any() and (~lit).any()
    np.testing.assert_allclose(written, np.where(lit, -1e4, -1.0), rtol=1e-6)


def test_hand_set_weights_are_a_weights_file_of_the_architecture(tmp_path, generated):
    params, architecture = hand_set_params(SHIPPED, ScenarioReward.of(generated['still']))
    assert architecture == SHIPPED  # the generated scenario's threshold is the shipped one's
    path = policy_file.save(tmp_path / 'hand-set.npz', params, 'full', architecture)
    loaded, _ = policy_file.load(path, layout_id('grid', 'full', 40, 40))
    for module, values in params.items():
        for key, value in values.items() if isinstance(values, dict) else [('', values)]:
            stored = loaded[module][key] if key else loaded[module]
            np.testing.assert_array_equal(stored, value, err_msg=f'{module}/{key}')


def test_what_cannot_be_written_is_refused_in_one_line(generated):
    reward = ScenarioReward.of(generated['still'])
    with pytest.raises(
        ValueError, match="hand-set reward: expected one of env, dark-steps, got 'x'"
    ):
        hand_set_params(SHIPPED, reward, 'x')
    with pytest.raises(ValueError, match='needs a reward network of 8 hidden units or more, the '
                       'architecture has 7'):  # fmt: skip
        hand_set_params({**SHIPPED, 'hidden': 7}, reward)
    hand_set_params({**SHIPPED, 'hidden': 1}, reward, 'dark-steps')
    chance = dataclasses.replace(reward, detection_mode='probabilistic')
    with pytest.raises(ValueError, match="has detection_mode 'probabilistic'; the weights are"):
        hand_set_params(SHIPPED, chance)


def test_a_decision_backs_up_to_the_fixed_point_past_the_files_iterations(generated):
    """A horizon (10 backups) shorter than the building's covert path does not shorten the
    decision: its values are backed up until they stop changing (``Vin.q_and_backups``), so
    the twin still plays value iteration's optimum, and more backups change no value."""
    scenario = generated['still']
    short = {**SHIPPED, 'iterations': 10}
    policy = GeneralistPolicy.hand_set(short, ScenarioReward.of(scenario))
    episode = rollout(policy, scenario)
    assert episode.outcome == 0 and episode.steps == episode.optimal_steps > 10, episode
    grid = data.grid_of(TaskArrays(scenario).tables())[None]
    q, backups = policy.model.apply(policy.variables, grid, True, method=Vin.q_and_backups)
    assert 10 < int(backups) == policy.backups <= 10 + int(grid[..., FREE].sum())
    longer = Vin(**{**short, 'iterations': int(backups) + 50})
    np.testing.assert_array_equal(q, longer.apply(policy.variables, grid, method=Vin.q_map))
    ten = policy.model.apply(policy.variables, grid, method=Vin.q_map)  # the fixed count
    assert not np.array_equal(ten, q)


def test_a_closed_room_does_not_hold_the_fixed_point_back(generated):
    """A closed room's values fall by a step cost each backup forever; the fixed point is
    judged on the nodes the goal can be reached from, so the plan stops with those (22 steps
    from the far corner) instead of running to Bellman-Ford's bound."""
    grid = np.zeros((12, 12, 7), np.float32)
    grid[..., FREE] = 1.0
    grid[0, 0, GOAL] = 1.0
    grid[-1, :, MOVE_UP] = grid[:, -1, MOVE_RIGHT] = -2.0  # the edges
    grid[8, 8:10, MOVE_UP] = grid[7, 8:10, MOVE_UP] = -2.0  # the room (8, 8)-(8, 9): its
    grid[8, 7, MOVE_RIGHT] = grid[8, 9, MOVE_RIGHT] = -2.0  # walls, one move inside
    reward = ScenarioReward.of(generated['still'])
    policy = GeneralistPolicy.hand_set({**SHIPPED, 'iterations': 5}, reward, 'dark-steps')
    policy.cell_logits(grid)
    assert 22 < policy.backups < 30, policy.backups
    q = np.asarray(policy.model.apply(policy.variables, grid[None], True, method=Vin.q_map))[0]
    longer = Vin(**{**policy.header['architecture'], 'iterations': policy.backups + 20})
    more = np.asarray(longer.apply(policy.variables, grid[None], method=Vin.q_map))[0]
    room = np.zeros((12, 12), bool)
    room[8, 8:10] = True
    np.testing.assert_array_equal(q[~room], more[~room])
    assert more[8, 8, 3] < q[8, 8, 3]  # the move inside the room: still falling


def _paying_a_cycle(policy: GeneralistPolicy) -> GeneralistPolicy:
    """``policy`` with every move's reward raised by 2: the dark-step twin's -1 a move becomes
    +1, a reward that pays for walking in circles (as an untrained network's can)."""
    params = dict(policy.variables['params'])
    params['reward_out'] = dict(params['reward_out'])
    params['reward_out']['bias'] = params['reward_out']['bias'] + 2.0
    architecture = policy.header['architecture']
    return GeneralistPolicy(params, architecture, source='a reward paying for a cycle')


def test_the_step_limit_caps_a_plan_whose_reward_pays_for_a_cycle(generated):
    """Values that never settle (a reward paying for a cycle) ran a decision to Bellman-Ford's
    bound, thousands of backups on a large building; with the episode's step limit as the
    horizon the plan stops there (k backups: the best k-step return), and a reward that does
    not pay for a cycle, whose fixed point comes first, plans exactly as without it."""
    grid = np.zeros((12, 12, 7), np.float32)
    grid[..., FREE] = 1.0
    grid[0, 0, GOAL] = 1.0
    grid[-1, :, MOVE_UP] = grid[:, -1, MOVE_RIGHT] = -2.0  # the edges
    reward = ScenarioReward.of(generated['still'])
    twin = GeneralistPolicy.hand_set({**SHIPPED, 'iterations': 5}, reward, 'dark-steps')
    settled = twin.cell_logits(grid)
    assert 22 < twin.backups < 40, twin.backups
    np.testing.assert_array_equal(twin.cell_logits(grid, horizon=40), settled)
    assert 22 < twin.backups < 40, twin.backups

    paying = _paying_a_cycle(twin)
    paying.cell_logits(grid)
    assert paying.backups == 5 + 144, paying.backups  # the bound: iterations + free cells
    for horizon, backups in ((40, 40), (3, 5)):  # never fewer than the file's iterations
        capped = paying.cell_logits(grid, horizon=horizon)
        assert paying.backups == backups, (horizon, paying.backups)
        k_steps = Vin(**{**twin.header['architecture'], 'iterations': backups})
        q = k_steps.apply(paying.variables, grid[None], method=Vin.q_map)
        np.testing.assert_array_equal(capped.argmax(-1), np.asarray(q)[0].argmax(-1))
