"""The lights-known generalist: its weights file (round trip, refusals), the network's geometry,
shapes and padding, a tiny training run, and the shipped weights on test scenarios."""

from pathlib import Path

import numpy as np
import pytest
from stealth_core.scenario_generator import Options
from stealth_learn import generalist_data as data
from stealth_learn import policy_file
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import DEFAULT_POLICY, GeneralistPolicy, rollout, unseen_scenarios
from stealth_learn.jax_deps import jax, jnp
from stealth_learn.obs_layout import LayoutError, layout_id
from stealth_learn.train_generalist import loss_fn
from stealth_learn.vin import ROBOT, Vin, move_features

ARCH = {'iterations': 60, 'hidden': 8, 'features': 4, 'threshold': 0.3}


@pytest.fixture(scope='module')
def still_sample(generated):
    return data.sample_of(0, generated['still'])


def _params(seed=0):
    grid = jnp.zeros((1, 5, 5, 7), jnp.float32)
    return Vin(**ARCH).init(jax.random.PRNGKey(seed), grid)['params']


def test_policy_file_round_trip(tmp_path):
    params = _params()
    path = policy_file.save(tmp_path / 'p.npz', params, 'full', ARCH, {'steps': 2, 'seed': 1})
    loaded, header = policy_file.load(path, layout_id('grid', 'full', 40, 40))
    assert header['layout'] == 'stealth-grid-v1/full' and header['training']['seed'] == 1
    assert header['architecture'] == ARCH
    flat = jax.tree_util.tree_leaves_with_path(params)
    assert len(flat) == len(jax.tree_util.tree_leaves(loaded))
    for (key, value), other in zip(flat, jax.tree_util.tree_leaves(loaded), strict=True):
        np.testing.assert_array_equal(np.asarray(value), other, err_msg=str(key))


def test_policy_file_refuses_another_track_naming_both_layouts(tmp_path):
    path = policy_file.save(tmp_path / 'p.npz', _params(), 'full', ARCH)
    with pytest.raises(LayoutError) as error:
        policy_file.load(path, layout_id('grid', 'sensed', 40, 40))
    message = str(error.value)
    assert str(path) in message
    assert 'stealth-grid-v1/full' in message and 'stealth-grid-v1/sensed' in message
    with pytest.raises(LayoutError, match='stealth-vector-v1/full'):
        policy_file.load(path, layout_id('vector', 'full', 0, 0))


def test_policy_file_missing_or_corrupt_named_with_its_path(tmp_path):
    missing = tmp_path / 'none.npz'
    with pytest.raises(policy_file.PolicyFileError, match=str(missing)):
        policy_file.load(missing, 'stealth-grid-v1/full')
    corrupt = tmp_path / 'corrupt.npz'
    corrupt.write_bytes(b'not a zip at all')
    with pytest.raises(policy_file.PolicyFileError, match=str(corrupt)):
        policy_file.load(corrupt, 'stealth-grid-v1/full')
    other = tmp_path / 'other.npz'
    np.savez(other, weights=np.zeros(3))
    with pytest.raises(policy_file.PolicyFileError, match=str(other)):
        policy_file.load(other, 'stealth-grid-v1/full')


def test_moves_match_the_lattice(generated):
    """The network's four shifts and masks are the lattice model's moves (targets, walls)."""
    tables = TaskArrays(generated['still']).tables()
    _, exists = move_features(data.grid_of(tables)[None])
    exists = np.asarray(exists)[0]
    rows, cols = tables.free.shape
    for row, col in zip(*np.nonzero(tables.free), strict=True):
        place = row * cols + col
        for action, (d_row, d_col) in enumerate(((1, 0), (-1, 0), (0, -1), (0, 1))):
            after = tables.successors[place, action]
            assert (after != place) == exists[row, col, action]
            if after != place:
                assert after == (row + d_row) * cols + col + d_col


def test_forward_shapes_and_wall_padding(still_sample):
    model = Vin(**ARCH)
    grid = still_sample.grid.copy()
    row, col = np.argwhere(still_sample.weight > 0)[0]
    grid[row, col, ROBOT] = 1.0
    variables = {'params': _params(1)}
    logits = model.apply(variables, grid[None])
    assert logits.shape == (1, 4)
    q = model.apply(variables, grid[None], method=Vin.q_map)
    assert q.shape == (1, *grid.shape[:2], 4)
    rows, cols = grid.shape[:2]
    padded, _, _ = data.batch([dataclass_with(still_sample, grid)], (rows + 7, cols + 5))
    assert padded.shape == (1, rows + 7, cols + 5, 7)
    np.testing.assert_allclose(model.apply(variables, padded), logits, rtol=1e-5)


def dataclass_with(sample, grid):
    import dataclasses

    return dataclasses.replace(sample, grid=grid)


def test_tiny_training_reduces_the_loss(still_sample, generated):
    import optax

    model = Vin(**ARCH)
    grid, optimal, weight = data.batch([still_sample])
    variables = {'params': _params(2)}
    optimiser = optax.adam(1e-2)
    state = optimiser.init(variables)
    loss = jax.jit(lambda v: loss_fn(model, v, grid, optimal, weight))
    step = jax.jit(jax.value_and_grad(lambda v: loss_fn(model, v, grid, optimal, weight)))
    first = float(loss(variables))
    for _ in range(15):
        _, grads = step(variables)
        updates, state = optimiser.update(grads, state, variables)
        variables = optax.apply_updates(variables, updates)
    assert float(loss(variables)) < 0.8 * first


def test_act_is_the_rollouts_attention(still_sample):
    """``act`` on each step's grid and the per-cell argmax ``rollout`` uses agree."""
    policy = GeneralistPolicy.untrained(ARCH, seed=3)
    logits = policy.cell_logits(still_sample.grid)
    for row, col in np.argwhere(still_sample.weight > 0)[:20]:
        grid = still_sample.grid.copy()
        grid[row, col, ROBOT] = 1.0
        assert policy.act(grid) == int(logits[row, col].argmax())


def test_a_moving_light_scenario_is_refused_naming_the_weights_and_the_scenario(generated):
    policy = GeneralistPolicy.untrained(ARCH)
    scenario = generated['moving']
    with pytest.raises(LayoutError, match=r'the untrained network \(seed 0\): the policy was '
                       r"trained for static lights .*, scenario 'gen-0000002' \("):  # fmt: skip
        rollout(policy, scenario)


@pytest.mark.skipif(not Path(DEFAULT_POLICY).is_file(), reason='no shipped weights')
def test_shipped_weights_cross_unseen_test_buildings(tmp_path):
    """Four generated test-range buildings (30 x 30 m, 4 static lights; seeds 1,000,000 on),
    never trained on: measured on 30 of them, the shipped policy crossed all undetected at
    value iteration's return (1.000), so each of these must reach the goal undetected within
    the issue's 0.97 of value iteration's return (and the untrained network must not)."""
    policy = GeneralistPolicy.load(DEFAULT_POLICY, layout_id('grid', 'full', 60, 60))
    untrained = GeneralistPolicy.untrained(policy.header['architecture'])
    scenarios = unseen_scenarios(4, Options(), tmp_path, offset=20)
    assert len(scenarios) == 4
    for scenario in scenarios:
        episode = rollout(policy, scenario)
        assert episode.outcome == 0, episode
        assert episode.episode_return >= 0.97 * episode.optimal_return, episode
    assert rollout(untrained, scenarios[0]).outcome != 0


def test_the_training_command_writes_a_loadable_policy_and_its_curve(tmp_path, capsys):
    """The one command, tiny: training seeds generated, validation selects, weights and PNG
    written, the weights load for the grid layout with their architecture and training record."""
    from stealth_learn import train_generalist

    out = tmp_path / 'g.npz'
    argv = ['--train', '2', '--validation', '1', '--steps', '2', '--every', '1', '--iterations']
    assert train_generalist.main([*argv, '20', '--out', str(out)]) == 0
    params, header = policy_file.load(out, layout_id('grid', 'full', 40, 40))
    assert header['training']['train_scenarios'] == 2 * len(train_generalist.SIZES)
    assert header['training']['selected_step'] in (1, 2)
    assert out.with_suffix('.png').read_bytes()[:4] == b'\x89PNG'
    assert 'wrote' in capsys.readouterr().out
    with pytest.raises(SystemExit) as error:
        train_generalist.main(['--steps', '0'])
    assert error.value.code == 2
