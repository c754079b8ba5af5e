"""The distance cap (``vin.Vin``'s ``distance_cap``): the reward reads the goal distance as at
most the cap, so it changes only steps entering a cell beyond it; its weights-file field; the
hand-set twin reads the distance uncapped; ``train_generalist --distance-cap`` stores it."""

import numpy as np
import pytest
from stealth_learn import generalist_data as data
from stealth_learn import policy_file
from stealth_learn.env_tables import TaskArrays
from stealth_learn.generalist import GeneralistPolicy
from stealth_learn.hand_set import ScenarioReward
from stealth_learn.jax_deps import jnp
from stealth_learn.obs_layout import layout_id
from stealth_learn.vin import GOAL, Vin, goal_distance

PLAIN = {'iterations': 60, 'hidden': 32, 'features': 8, 'threshold': 0.3}
CAP = 0.8  # 8 cells: a 20 x 20 m building (40 x 40 cells) has cells on both sides of it


def _rewards(policy: GeneralistPolicy, grid) -> np.ndarray:
    return np.asarray(policy.model.apply(policy.variables, grid[None], method=Vin.rewards))[0]


@pytest.fixture(scope='module')
def grid(generated):
    return data.grid_of(TaskArrays(generated['still']).tables())


def test_the_cap_changes_only_steps_entering_a_cell_beyond_it(grid):
    plain = GeneralistPolicy.untrained(PLAIN, seed=3)
    capped = GeneralistPolicy(plain.variables['params'], {**PLAIN, 'distance_cap': CAP})
    distance = np.asarray(goal_distance(jnp.asarray(grid[..., GOAL])))
    # the distance each move enters (up: row + 1, down, left: col - 1, right), inf off the grid
    padded = np.pad(distance, 1, constant_values=np.inf)
    entered = np.stack(
        [padded[2:, 1:-1], padded[:-2, 1:-1], padded[1:-1, :-2], padded[1:-1, 2:]], axis=-1
    )
    before, after = _rewards(plain, grid), _rewards(capped, grid)
    within = entered <= CAP
    assert within.any() and (entered[np.isfinite(entered)] > CAP).any()
    np.testing.assert_array_equal(after[within], before[within])
    beyond = (entered > CAP) & np.isfinite(entered)
    assert (after[beyond] != before[beyond]).mean() > 0.9  # random weights read the distance
    # a cap beyond every distance is no cap
    far = GeneralistPolicy(plain.variables['params'], {**PLAIN, 'distance_cap': 1e3})
    np.testing.assert_array_equal(far.cell_logits(grid), plain.cell_logits(grid))


def test_the_weights_file_carries_the_cap_and_checks_it(tmp_path, grid):
    architecture = {**PLAIN, 'distance_cap': CAP}
    policy = GeneralistPolicy.untrained(architecture)
    path = policy_file.save(tmp_path / 'c.npz', policy.variables['params'], 'full', architecture)
    params, header = policy_file.load(path, layout_id('grid', 'full', 40, 40))
    assert header['architecture']['distance_cap'] == CAP
    loaded = GeneralistPolicy.load(path, None)
    np.testing.assert_array_equal(loaded.cell_logits(grid), policy.cell_logits(grid))
    for bad in (0.0, -1.0, 'far'):
        header['architecture']['distance_cap'] = bad
        with pytest.raises(policy_file.PolicyFileError, match='distance_cap') as error:
            policy_file.check_header(path, header)
        assert str(path) in str(error.value) and '\n' not in str(error.value)


def test_the_hand_set_twin_reads_the_distance_uncapped(generated, grid):
    reward = ScenarioReward.of(generated['still'])
    twin = GeneralistPolicy.hand_set({**PLAIN, 'distance_cap': CAP}, reward)
    assert 'distance_cap' not in twin.header['architecture'] and twin.model.distance_cap == 0
    exact = GeneralistPolicy.hand_set(PLAIN, reward)
    np.testing.assert_array_equal(twin.cell_logits(grid), exact.cell_logits(grid))


def test_the_training_command_stores_the_cap(tmp_path, capsys):
    from stealth_learn import train_generalist

    out = tmp_path / 'c.npz'
    argv = ['--sizes', '20x20x3', '--train', '1', '--validation', '1', '--steps', '2']
    argv += ['--every', '1', '--iterations', '30', '--distance-cap', '4', '--out', str(out)]
    assert train_generalist.main(argv) == 0
    policy = GeneralistPolicy.load(out, None)
    assert policy.model.distance_cap == 4.0
    assert policy.header['architecture']['distance_cap'] == 4.0
    for bad in ('-1', 'nan'):
        with pytest.raises(SystemExit):
            train_generalist.parse_args(['--distance-cap', bad])
        assert '--distance-cap: expected a finite number >= 0' in capsys.readouterr().err


def test_a_sensed_training_keeps_the_cap_of_its_init_weights(tmp_path, capsys):
    """--sensed starts from --init's weights: their cap is taken, and another one refused in one
    line naming the file (those weights learned the distance with their own cap)."""
    from stealth_learn import train_generalist

    argv = ['--moving', 'mixed', '--sensed', '--sizes', '20x20x3', '--train', '1']
    argv += ['--validation', '1', '--steps', '2', '--out', str(tmp_path / 's.npz')]
    assert train_generalist.main([*argv, '--distance-cap', '2']) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert str(train_generalist.MOVING_OUT) in error and 'give --distance-cap 4' in error
    assert not (tmp_path / 's.npz').exists()
