"""The time-aware generalist (moving lights, lights known): the network over phase layers is the
static one with one layer, its steps go where the lattice model's go (the hand-set twin's values
are the layered value iteration's), the hand-set twin plays value iteration's optimum on
sweeping and patrolling buildings, the phased grid is the lattice's steps, and a policy of
another cycle or kind of lights is refused naming both."""

from pathlib import Path

import numpy as np
import pytest
from stealth_core.grid_observation import LIGHT
from stealth_core.gym_env import StealthNavEnv
from stealth_core.planners import value_iteration
from stealth_core.scenario_generator import Options
from stealth_learn import generalist_data as data
from stealth_learn import policy_file
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import DEFAULT_POLICY, GeneralistPolicy, rollout
from stealth_learn.generalist_agent import GeneralistAgent
from stealth_learn.hand_set import ScenarioReward
from stealth_learn.jax_deps import jax, jnp
from stealth_learn.obs_layout import CHANNELS, LayoutError, layout_id, phased_layout_id
from stealth_learn.vin import NO_MOVE, ROBOT, WAIT, Vin, logits_of_cells, move_features

STATIC = {'iterations': 240, 'hidden': 32, 'features': 8, 'threshold': 0.3}
TIMED = {**STATIC, 'layers': 8, 'advance': 1}  # the generator's cycle: 8 bins, a step one bin


def _moving(tmp_path, moving: str, count: int, seed: int = 10):
    """``count`` 20 x 20 m training-range buildings whose lights do move."""
    out = []
    for offset in range(40):
        scenario = data.scenario_of(
            seed + offset, Options(width=20, height=20, lights=3, moving=moving), tmp_path
        )
        if scenario.has_moving_lights:
            out.append(scenario)
        if len(out) == count:
            return out
    raise AssertionError(f'fewer than {count} {moving} buildings')


def test_one_layer_repeated_is_the_static_network(generated):
    """A static building laid over 8 layers (step lights the grid's moves, no wait) has, at
    every layer, exactly the static network's action values: the layered recurrence reduces to
    the static one (the shipped weights, if present, else an initialisation)."""
    shipped = Path(DEFAULT_POLICY).is_file()
    static = (
        GeneralistPolicy.load(DEFAULT_POLICY, None)
        if shipped
        else GeneralistPolicy.untrained(STATIC, seed=1)
    )
    assert not static.model.phased and static.layout == 'stealth-grid-v1/full'
    grid = data.grid_of(TaskArrays(generated['still']).tables())
    lights, _ = move_features(jnp.asarray(grid)[None])
    wait = np.full((*grid.shape[:2], 1), NO_MOVE, np.float32)
    layer = np.concatenate([grid, np.asarray(lights)[0], wait], -1)
    phased = np.repeat(layer[None], 8, axis=0)
    timed = Vin(**{**static.header['architecture'], 'layers': 8, 'advance': 1})
    q_static = np.asarray(static.model.apply(static.variables, grid[None], method=Vin.q_map))
    q_timed = np.asarray(timed.apply(static.variables, phased[None], method=Vin.q_map))
    for t in range(8):
        np.testing.assert_array_equal(q_timed[0, t, ..., :WAIT], q_static[0])


@pytest.mark.parametrize('moving', ['sweeping', 'patrolling'])
def test_the_hand_set_values_are_the_layered_value_iterations(tmp_path, moving):
    """With as many backups as the step limit, the hand-set twin's value at every layer and
    cell from which the goal is reached undetected is value iteration's over the lattice
    model's (node, bin) places: the layer a step reaches, the wait, the step lights."""
    scenario = _moving(tmp_path, moving, 1)[0]
    arrays = TaskArrays(scenario)
    model = arrays.model
    optimum = value_iteration(model)
    architecture = {**TIMED, 'iterations': int(model.task.step_limit)}
    policy = GeneralistPolicy.hand_set(architecture, ScenarioReward.of(scenario))
    phased = data.phased_grid(arrays)
    q = np.asarray(policy.model.apply(policy.variables, phased[None], method=Vin.q_map))[0]
    n = len(model.nodes)
    rows, cols = arrays.sensing.grid_row, arrays.sensing.grid_col
    values = optimum.values.reshape(model.layers, n)
    reached = (values > 0) & ~model.goal[:n]
    assert reached.sum() > 0.5 * reached.size
    network = q.max(-1)[:, rows, cols]
    np.testing.assert_allclose(network[reached], values[reached], rtol=0, atol=0.02)


@pytest.mark.parametrize('moving', ['sweeping', 'patrolling'])
def test_the_hand_set_twin_plays_the_layered_optimum(tmp_path, moving):
    """Greedy in the JAX environment, the hand-set twin's return is value iteration's (exact
    with time) on three buildings."""
    for scenario in _moving(tmp_path, moving, 3):
        policy = GeneralistPolicy.hand_set(TIMED, ScenarioReward.of(scenario))
        episode = rollout(policy, scenario)
        assert episode.outcome == 0, episode
        assert episode.episode_return == pytest.approx(episode.optimal_return, rel=1e-5)


def test_the_phased_grid_is_the_lattices_steps(generated):
    """Each layer's grid is that layer's lights; each step channel is the light the lattice
    model judges that step on, where the step moves (or waits); -2 where it is blocked."""
    arrays = TaskArrays(generated['moving'])
    model, tables = arrays.model, arrays.tables()
    phased = data.phased_grid(arrays)
    assert phased.shape == (model.layers, *tables.free.shape, len(CHANNELS) + 5)
    n = len(model.nodes)
    rows, cols = arrays.sensing.grid_row, arrays.sensing.grid_col
    for layer in (0, 3, model.layers - 1):
        np.testing.assert_array_equal(phased[layer, ..., : len(CHANNELS)],
                                      data.grid_of(tables, layer))  # fmt: skip
        steps = phased[layer, rows, cols, len(CHANNELS) :]
        places = slice(layer * n, (layer + 1) * n)
        after = model.successors[places] % n
        moved = np.concatenate([after[:, :4] != np.arange(n)[:, None], np.ones((n, 1), bool)], 1)
        truth = model.step_visibility[places].astype(np.float32)
        np.testing.assert_array_equal(steps[moved], truth[moved])
        assert (steps[~moved] == NO_MOVE).all()
        assert (model.successors[places] // n == (layer + 1) % model.layers).all()


def test_the_agent_acts_at_the_robots_layer_as_the_rollout(tmp_path):
    """The Gym agent (the benchmark's) decides at the robot's layer and cell; its episode is
    the JAX rollout's, waits included."""
    scenario = _moving(tmp_path, 'sweeping', 1)[0]
    policy = GeneralistPolicy.hand_set(TIMED, ScenarioReward.of(scenario))
    episode = rollout(policy, scenario)
    env = StealthNavEnv(scenario)
    agent = GeneralistAgent(policy, env)
    observation, _ = env.reset(seed=0)
    total, steps, actions = 0.0, 0, set()
    while True:
        action = agent.act(observation)
        actions.add(action)
        observation, reward, terminated, truncated, info = env.step(action)
        total, steps = total + reward, steps + 1
        if terminated or truncated:
            break
    assert steps == episode.steps and total == pytest.approx(episode.episode_return, rel=1e-5)
    assert agent.value_maps == 1
    grid = agent.grid(observation).copy()
    grid[2, 5, 7, ROBOT] = 1.0
    logits = policy.cell_logits(grid)
    assert policy.act(grid) == int(logits[2, 5, 7].argmax())


def test_lights_of_another_kind_or_cycle_are_refused_naming_both(generated, tmp_path):
    static = GeneralistPolicy.untrained(STATIC)
    timed = GeneralistPolicy.untrained(TIMED)
    moving, still = generated['moving'], generated['still']
    with pytest.raises(LayoutError) as error:
        rollout(static, moving)
    assert "'stealth-grid-v1/full'" in str(error.value)
    assert f'scenario {moving.name!r}' in str(error.value)
    assert 'has moving lights' in str(error.value)
    assert (
        "a time-aware policy is needed there (layout 'stealth-phased-v1/full/8phases-1perstep')"
        in str(error.value)
    )
    with pytest.raises(LayoutError) as error:
        GeneralistAgent(timed, StealthNavEnv(still))
    message = str(error.value)
    assert "time-aware (layout 'stealth-phased-v1/full/8phases-1perstep')" in message
    assert f'scenario {still.name!r}' in message and 'static lights' in message
    four = GeneralistPolicy.untrained({**TIMED, 'layers': 4})
    with pytest.raises(LayoutError) as error:
        rollout(four, moving)
    message = str(error.value)
    assert "'stealth-phased-v1/full/4phases-1perstep'" in message
    assert "'stealth-phased-v1/full/8phases-1perstep'" in message and '\n' not in message


def test_on_the_sensed_track_it_reads_only_what_was_sensed_at_each_layer(tmp_path):
    """Sensed, the time-aware agent reads the phased belief of the robot's phased memory: at
    the start only bin 0 is known, so every layer reads bin 0's values (the brightest known
    elsewhere stands in for a layer never sensed), not the lights' other bins; the memory of
    each bin grows as the robot goes, and it reaches the goal undetected."""
    scenario = _moving(tmp_path, 'sweeping', 1)[0]
    policy = GeneralistPolicy.hand_set(TIMED, ScenarioReward.of(scenario))
    env = StealthNavEnv(scenario, track='sensed')
    agent = GeneralistAgent(policy, env)
    observation, _ = env.reset(seed=0)
    truth = data.phased_grid(TaskArrays(scenario, model=env.model))
    first = agent.grid(observation)
    assert first.shape == truth.shape
    light = first[..., LIGHT]
    assert all(np.array_equal(light[0], layer) for layer in light[1:])
    assert not all(np.array_equal(truth[0, ..., LIGHT], layer) for layer in truth[1:, ..., LIGHT])
    while True:
        observation, _, terminated, truncated, info = env.step(agent.act(observation))
        if terminated or truncated:
            break
    assert info['outcome'] == 'SUCCESS'
    sensed_layers = (env.sensor.phased.node_light >= 0).any(axis=1)
    assert sensed_layers.all()  # it saw every bin of the cycle on its way
    assert agent.value_maps > 1


def test_a_phased_weights_file_is_refused_at_load_for_another_cycle(tmp_path):
    """Its layout names the phase count and step; load refuses another (naming both), a header
    whose layout is not its architecture's, and half a time-aware architecture."""
    params = GeneralistPolicy.untrained(TIMED).variables['params']
    path = policy_file.save(tmp_path / 'timed.npz', params, 'full', TIMED)
    loaded, header = policy_file.load(path, phased_layout_id('full', 8, 1, 40, 40))
    assert header['layout'] == 'stealth-phased-v1/full/8phases-1perstep'
    assert header['architecture'] == TIMED
    assert policy_file.load(path, None)[1] == header
    from stealth_learn import ros_policy

    plugin = ros_policy.load(str(path))  # the agent node's: it reads the phased grid sent
    assert plugin.layout == 'stealth-phased-v1/full/8phases-1perstep'
    plugin.check(phased_layout_id('full', 8, 1, 30, 30))  # any size
    for other in (
        phased_layout_id('full', 16, 1, 30, 30),
        phased_layout_id('full', 8, 2, 30, 30),
        layout_id('grid', 'full', 30, 30),
        layout_id('grid', 'sensed', 30, 30),
    ):
        with pytest.raises(LayoutError) as error:
            plugin.check(other)
        message = str(error.value)
        assert str(path) in message and "'stealth-phased-v1/full/8phases-1perstep'" in message
        assert repr(policy_file.without_size(other)) in message and '\n' not in message
    for other in (phased_layout_id('full', 16, 1, 40, 40), layout_id('grid', 'full', 40, 40)):
        with pytest.raises(LayoutError) as error:
            policy_file.load(path, other)
        message = str(error.value)
        assert str(path) in message and '8phases-1perstep' in message
        assert policy_file.without_size(other) in message
    import json

    for change, field in (
        ({'layout': 'stealth-phased-v1/full/4phases-1perstep'}, 'layout'),
        ({'architecture': {**TIMED, 'layers': 1}}, 'architecture.layers'),
        ({'architecture': {k: v for k, v in TIMED.items() if k != 'advance'}}, 'advance'),
        ({'architecture': {**TIMED, 'advance': 8}}, 'architecture.advance'),
    ):
        with np.load(path) as stored:
            arrays = {name: stored[name] for name in stored.files}
        header = {**json.loads(str(arrays['__header__'])), **change}
        arrays['__header__'] = np.array(json.dumps(header))
        bad = tmp_path / 'bad.npz'
        np.savez(bad, **arrays)
        with pytest.raises(policy_file.PolicyFileError, match=field) as error:
            policy_file.load(bad, None)
        assert str(bad) in str(error.value) and '\n' not in str(error.value)


def test_the_training_command_trains_the_time_aware_network(tmp_path):
    """``--moving``: phased samples of moving buildings only, a phased weights file whose
    network learns (validation loss below the untrained one's)."""
    from stealth_learn import train_generalist

    out = tmp_path / 'm.npz'
    argv = ['--moving', 'mixed', '--sizes', '20x20x3', '--train', '3', '--validation', '1']
    argv += ['--steps', '8', '--every', '4', '--iterations', '30', '--out', str(out)]
    assert train_generalist.main(argv) == 0
    params, header = policy_file.load(out, phased_layout_id('full', 8, 1, 40, 40))
    assert header['architecture']['layers'] == 8 and header['architecture']['advance'] == 1
    assert header['training']['samples_per_second'] > 0
    policy = GeneralistPolicy(params, header['architecture'], header, source=out)
    assert policy.model.phased and policy.layout.endswith('8phases-1perstep')


def test_the_imitation_targets_are_the_layered_optimum(tmp_path):
    """A moving sample: the phased grid, five actions, every optimal action a step that
    exists, and the network's loss reading all layers."""
    scenario = _moving(tmp_path, 'patrolling', 1)[0]
    sample = data.sample_of(0, scenario)
    assert sample.grid.shape[0] == 8 and sample.optimal.shape[-1] == 5 and sample.advance == 1
    exists = sample.grid[..., len(CHANNELS) :] > NO_MOVE + 0.5
    assert not (sample.optimal & ~exists).any()
    assert (sample.optimal.any(-1) >= (sample.weight > 0)).all()
    model = Vin(**{**TIMED, 'iterations': 20})
    grid, optimal, weight = data.batch([sample, sample])
    variables = model.init(jax.random.PRNGKey(0), jnp.asarray(grid[:1]))
    logits = np.asarray(logits_of_cells(model, variables, grid))
    assert logits.shape == (*optimal.shape,)
