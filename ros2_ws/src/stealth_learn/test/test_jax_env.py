"""The JAX environment against the Gym env and StealthTask, step for step, on generated and
shipped scenarios: same arrivals, float32 of the same rewards, same outcomes, same states, same
sensed light; then batches, padding and gymnax's auto-reset."""

import jax
import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv
from stealth_core.planners import astar, follow, value_iteration, walk
from stealth_core.reward import EpisodeOutcome
from stealth_learn.env_tables import Dims
from stealth_learn.jax_env import build

STEPS = 400


def gym_env(scenario, track='full'):
    return StealthNavEnv(scenario=scenario, track=track)


def scripted_actions(scenario, steps, seed=0):
    """A*'s route (seen: it ends detected), the optimum's (it reaches the goal unseen), then
    random actions: every outcome, and the darker corners a random walk misses."""
    model = gym_env(scenario).model
    optimum = value_iteration(model)

    def moves(path):
        ended = walk(model, path).steps
        return [
            model.direction(a, b) for a, b in zip(path[:ended], path[1 : ended + 1], strict=True)
        ]

    scripted = moves(astar(model)) + moves(follow(model, lambda i: int(optimum.policy[i])))
    rng = np.random.default_rng(seed)
    return scripted + rng.integers(model.num_actions, size=steps).tolist()


def walk_both(scenario, track, steps=STEPS, seed=0, layout='grid'):
    """Step the Gym env and the JAX env with the same actions (``scripted_actions``; the JAX
    env's auto-reset against the Gym env's reset); yield (gym step, jax step) pairs."""
    env, params = build([scenario], track=track, layout=layout)
    one = env.scenario(params, 0)
    theirs = gym_env(scenario, track)
    their_obs, _ = theirs.reset(seed=seed)
    our_obs, state = env.reset(jax.random.key(seed), one)
    yield (their_obs, None), (our_obs, state, None)
    step = jax.jit(env.step)
    for t, action in enumerate(scripted_actions(scenario, steps, seed)):
        observation, reward, terminated, truncated, info = theirs.step(action)
        our_obs, state, our_reward, done, our_info = step(jax.random.key(t), state, action, one)
        yield (
            (observation, (reward, terminated, truncated, info)),
            (our_info['final_observation'], state, (our_reward, done, our_info)),
        )
        if terminated or truncated:
            theirs.reset()


def check_state(their_state, vector, task):
    """The Gym state (x, y, then phase and heading where the task has them) in our vector."""
    ours = [vector[0], vector[1]]
    if task.timing is not None:
        ours.append(vector[2])
    if task.footprint is not None:
        ours.append(vector[3])
    np.testing.assert_array_equal(np.asarray(ours, np.float32), their_state)


# A*'s route is seen on each (map1-exposure's is not: its lights weigh the robot's side).
SEEN = {'DETECTED', 'SUCCESS'}


@pytest.mark.parametrize(
    ('name', 'expected'),
    [
        ('still', SEEN),
        ('moving', SEEN),
        ('simple-maze-moving', SEEN),
        ('map1-exposure', {'SUCCESS'}),
    ],
)
def test_full_track_equals_gym(generated, name, expected):
    scenario = generated.get(name, name)
    task = gym_env(scenario).task
    outcomes = set()
    for (their_obs, theirs), (our_obs, _, ours) in walk_both(scenario, 'full', layout='vector'):
        check_state(their_obs, np.asarray(our_obs), task)
        if theirs is None:
            continue
        reward, terminated, truncated, info = theirs
        our_reward, done, our_info = ours
        assert float(our_reward) == np.float32(reward)
        assert bool(done) == (terminated or truncated)
        assert bool(our_info['terminated']) == terminated
        assert bool(our_info['truncated']) == truncated
        outcome = int(our_info['outcome'])
        assert (None if outcome < 0 else EpisodeOutcome(outcome).name) == info['outcome']
        assert float(our_info['visibility']) == np.float32(info['visibility'])
        assert int(our_info['steps']) == info['steps']
        assert bool(np.asarray(our_obs)[4]) == (
            info['visibility'] >= task.scenario.detection_threshold
        )
        outcomes.add(info['outcome'])
    assert expected <= outcomes


@pytest.mark.parametrize('name', ['moving', 'still', 'simple-maze-moving'])
def test_sensed_track_equals_gym(generated, name):
    """Including simple-maze-moving, whose 30 x 30 lattice is padded to the 33-node window."""
    scenario = generated.get(name, name)
    rows, cols = gym_env(scenario, 'sensed').sensor.sensing.shape
    task = gym_env(scenario).task
    sensed_any = False
    for (their_obs, theirs), (our_obs, _, ours) in walk_both(scenario, 'sensed', steps=250):
        grid = np.asarray(our_obs.grid)
        np.testing.assert_array_equal(grid[:rows, :cols, 3], their_obs['light'])
        np.testing.assert_array_equal(grid[:rows, :cols, 4], their_obs['moves'][0])
        np.testing.assert_array_equal(grid[:rows, :cols, 5], their_obs['moves'][1])
        check_state(their_obs['state'], np.asarray(our_obs.vector), task)
        assert np.asarray(our_obs.vector)[4] == their_obs['lit'][0]
        sensed_any |= bool((their_obs['light'] > 0).any())
        if theirs is not None:
            assert float(ours[0]) == np.float32(theirs[0])
    assert sensed_any  # some light was sensed on the way


def test_steps_judged_by_stealth_task(generated):
    """Independent of the lattice tables: each step's light by ``StealthTask.step_visibility``
    between the poses the JAX env reports, in space and time, and its reward by ``judge``."""
    scenario = generated['moving']
    task = gym_env(scenario).task
    env, params = build([scenario], layout='vector')
    one = env.scenario(params, 0)
    obs, state = env.reset(jax.random.key(0), one)
    x0, y0 = (float(v) for v in np.asarray(obs)[:2])
    actions = np.random.default_rng(3).integers(env.num_actions, size=40).tolist()
    for k, action in enumerate(actions, start=1):
        obs, state, reward, done, info = env.step(jax.random.key(k), state, action, one)
        x1, y1 = (float(v) for v in np.asarray(info['final_observation'])[:2])
        t0, t1 = (k - 1) * task.step_seconds, k * task.step_seconds
        visibility = task.step_visibility(x0, y0, t0, x1, y1, t1)
        judgement = task.judge(x1, y1, t1, k, visibility=visibility)
        assert float(reward) == np.float32(judgement.reward)
        assert float(info['visibility']) == np.float32(visibility)
        if done:
            assert int(info['outcome']) == int(judgement.outcome)
            break
        x0, y0 = x1, y1


def test_batch_of_scenarios_equals_one_at_a_time(generated):
    """vmap over three scenarios of different sizes (padded to one) gives, for each, what that
    scenario gives alone at its own size."""
    scenarios = [generated['still'], generated['moving'], generated['wider']]
    env, params = build(scenarios, track='sensed')
    keys = jax.random.split(jax.random.key(7), len(scenarios))
    obs, state = jax.vmap(env.reset)(keys, params)
    step = jax.jit(jax.vmap(env.step))
    alone = [build([s], track='sensed') for s in scenarios]
    alone_state = [e.reset(k, e.scenario(p, 0))[1] for (e, p), k in zip(alone, keys, strict=True)]
    rng = np.random.default_rng(5)
    for t in range(120):
        actions = rng.integers(4, size=len(scenarios))  # the moves every scenario has
        keys = jax.random.split(jax.random.key(t), len(scenarios))
        obs, state, reward, done, info = step(keys, state, actions, params)
        for i, ((e, p), key) in enumerate(zip(alone, keys, strict=True)):
            one_obs, alone_state[i], one_reward, one_done, _ = e.step(
                key, alone_state[i], int(actions[i]), e.scenario(p, 0)
            )
            rows, cols = e.dims.rows, e.dims.cols
            assert float(reward[i]) == float(one_reward)
            assert bool(done[i]) == bool(one_done)
            np.testing.assert_array_equal(obs.vector[i], one_obs.vector)
            np.testing.assert_array_equal(obs.grid[i, :rows, :cols], one_obs.grid)


def test_padding_is_wall(generated):
    """A scenario padded to a larger grid: the padding has no node, no light, no move; the
    robot never enters it, and the steps are those of the scenario at its own size."""
    scenario = generated['still']
    own_env, own = build([scenario])
    big = Dims(own_env.dims.rows + 9, own_env.dims.cols + 13, 3, 7, own_env.dims.window + 2)
    env, params = build([scenario], dims=big)
    assert env.layout_id.endswith(f'/{big.rows}x{big.cols}')
    one, own_one = env.scenario(params, 0), own_env.scenario(own, 0)
    obs, state = env.reset(jax.random.key(0), one)
    own_obs, own_state = own_env.reset(jax.random.key(0), own_one)
    rows, cols = own_env.dims.rows, own_env.dims.cols
    grid = np.asarray(obs.grid)
    assert not grid[rows:, :, 0].any() and not grid[:, cols:, 0].any()
    assert (grid[rows:, :, 3:6] == -2).all() and (grid[:, cols:, 3:6] == -2).all()
    rng = np.random.default_rng(2)
    for t in range(200):
        action = int(rng.integers(4))
        key = jax.random.key(t)
        obs, state, reward, done, _ = env.step(key, state, action, one)
        own_obs, own_state, own_reward, own_done, _ = own_env.step(key, own_state, action, own_one)
        assert float(reward) == float(own_reward) and bool(done) == bool(own_done)
        np.testing.assert_array_equal(obs.vector, own_obs.vector)
        np.testing.assert_array_equal(np.asarray(obs.grid)[:rows, :cols], own_obs.grid)
    # Actions beyond the scenario's own four stay in place, as a blocked move does.
    assert np.asarray(one.action_mask).tolist() == [True] * 4 + [False] * 3
    after, state2, *_ = env.step_env(jax.random.key(0), state, 6, one)
    assert int(state2.place) == int(state.place)


def test_auto_reset_and_truncation():
    """gymnax's semantics: the step that ends an episode returns the next episode's first
    observation (the finished one in info), and the step limit truncates."""
    env, params = build(['simple-maze'], layout='vector')
    one = env.scenario(params, 0)
    first, state = env.reset(jax.random.key(0), one)
    limit = int(one.step_limit)
    # Back and forth between the start and a dark neighbour: nothing ends it but the limit.
    start = int(one.start)
    successors, detect_p = np.asarray(one.successors), np.asarray(one.detect_p)
    there, back = next(
        (a, b)
        for a, b in ((0, 1), (1, 0), (2, 3), (3, 2))
        if successors[start, a] != start
        and successors[successors[start, a], b] == start
        and detect_p[start, a] == 0.0
        and detect_p[successors[start, a], b] == 0.0
        and not np.asarray(one.goal)[successors[start, a]]
    )
    for k in range(1, limit + 1):
        action = there if k % 2 else back
        obs, state, reward, done, info = env.step(jax.random.key(k), state, action, one)
        if k < limit:
            assert not bool(done) and int(state.steps) == k
    assert bool(done) and bool(info['truncated']) and not bool(info['terminated'])
    assert int(info['outcome']) == EpisodeOutcome.TIMEOUT
    assert int(state.steps) == 0 and int(state.place) == int(one.start)  # reset
    np.testing.assert_array_equal(obs, first)
    assert np.asarray(info['final_observation'])[5] == 1.0  # the finished one: all time used
    assert float(info['episode_return']) < 0.0 and float(state.episode_return) == 0.0


def test_many_environments_of_one_scenario(generated):
    """vmap over environments of one scenario (params not batched), each its own actions,
    equals stepping each alone."""
    env, params = build([generated['moving']], layout='vector')
    one = env.scenario(params, 0)
    n = 16
    keys = jax.random.split(jax.random.key(1), n)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, one)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    singles = [env.reset(k, one)[1] for k in keys]
    rng = np.random.default_rng(0)
    for t in range(60):
        actions = rng.integers(env.num_actions, size=n)
        keys = jax.random.split(jax.random.key(100 + t), n)
        obs, state, reward, done, _ = step(keys, state, actions, one)
        for i in range(n):
            o, singles[i], r, d, _ = env.step(keys[i], singles[i], int(actions[i]), one)
            assert float(r) == float(reward[i]) and bool(d) == bool(done[i])
            np.testing.assert_array_equal(o, obs[i])


def test_slip_moves_sideways():
    """slip 1: every move goes at right angles to the one chosen, both sides drawn."""
    env, params = build(['map1'], layout='vector', slip=1.0)
    assert env.stochastic
    one = env.scenario(params, 0)
    _, state = env.reset(jax.random.key(0), one)
    keys = jax.random.split(jax.random.key(3), 200)
    directions = jax.vmap(lambda k: env.step_env(k, state, 0, one)[4]['direction'])(keys)
    assert set(np.asarray(directions).tolist()) == {2, 3}  # up slips left or right
    deterministic, _ = build(['map1'], layout='vector')
    assert not deterministic.stochastic


def test_padded_actions_wait_where_lights_move():
    """Where lights move, an action beyond the scenario's own is its wait, step for step."""
    own_env, _ = build(['simple-maze-moving'])
    dims = own_env.dims
    env, params = build(['simple-maze-moving'], dims=Dims(dims.rows, dims.cols, 8, 7, 16))
    one = env.scenario(params, 0)
    for table in ('successors', 'step_visibility', 'detect_p', 'free_reward', 'lit'):
        values = np.asarray(getattr(one, table))
        np.testing.assert_array_equal(values[:, 5], values[:, 4])
        np.testing.assert_array_equal(values[:, 6], values[:, 4])
    assert np.asarray(one.action_mask).tolist() == [True] * 5 + [False] * 2
