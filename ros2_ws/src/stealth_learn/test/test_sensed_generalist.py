"""The time-aware generalist for the lights-sensed track: the never-sensed input (``vin.Vin``'s
``uncertain``) changes nothing at weight 0 (so the hand-set twin is the same network) and
prices entering an unknown place otherwise; its weights file; the belief snapshots it trains
on (``sensed_data``); and the training command's ``--sensed``."""

import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv
from stealth_learn import generalist_data as data
from stealth_learn import policy_file, sensed_data
from stealth_learn.generalist import GeneralistPolicy
from stealth_learn.generalist_agent import GeneralistAgent
from stealth_learn.hand_set import ScenarioReward
from stealth_learn.obs_layout import phased_layout_id
from stealth_learn.vin import AGE

TIMED = {'iterations': 60, 'hidden': 32, 'features': 8, 'threshold': 0.3, 'layers': 8}
TIMED['advance'] = 1
SENSED = {**TIMED, 'uncertain': 1}


@pytest.fixture(scope='module')
def belief(generated):
    """(scenario, a phased belief grid 20 steps into a sensed episode of the hand-set twin)."""
    scenario = generated['moving']
    env = StealthNavEnv(scenario, track='sensed')
    agent = GeneralistAgent(GeneralistPolicy.hand_set(TIMED, ScenarioReward.of(scenario)), env)
    observation, _ = env.reset(seed=0)
    for _ in range(20):
        observation, *_ = env.step(agent.act(observation))
    return scenario, agent.grid(observation)


def test_the_never_sensed_input_at_weight_0_is_the_network_without_it(belief):
    scenario, grid = belief
    assert 0 < grid[..., AGE].sum() < (grid[..., 0] > 0).sum()  # some layers sensed, not all
    reward = ScenarioReward.of(scenario)
    plain = GeneralistPolicy.hand_set(TIMED, reward).cell_logits(grid)
    twin = GeneralistPolicy.hand_set(SENSED, reward)
    np.testing.assert_array_equal(twin.cell_logits(grid), plain)
    # a price on entering a place never sensed: rewards change only where a step enters one
    params = {key: dict(value) if isinstance(value, dict) else value
              for key, value in twin.variables['params'].items()}  # fmt: skip
    kernel = np.array(params['reward_hidden']['kernel'])
    kernel[-1, 0] = 5.0  # unit 0 carries the step's light, paid at -visibility_weight
    params['reward_hidden'] = {**params['reward_hidden'], 'kernel': kernel}
    priced = GeneralistPolicy(params, twin.header['architecture'])
    batch = np.asarray(grid)[None]
    before = np.asarray(twin.model.apply(twin.variables, batch, method=twin.model.rewards))[0]
    after = np.asarray(priced.model.apply(priced.variables, batch, method=priced.model.rewards))
    changed = ~np.isclose(after[0], before)
    unknown_after = np.roll(grid[..., AGE] > 0.5, -1, axis=0)  # the layer a step arrives at
    waits = changed[..., 4]
    assert waits.any() and (waits <= unknown_after).all()
    assert (after[0][changed] < before[changed]).all()  # entering the unknown costs more


def test_a_sensed_weights_file_round_trips_and_its_field_is_checked(tmp_path, belief):
    scenario, _ = belief
    twin = GeneralistPolicy.hand_set(SENSED, ScenarioReward.of(scenario))
    path = policy_file.save(tmp_path / 's.npz', twin.variables['params'], 'sensed', SENSED)
    params, header = policy_file.load(path, phased_layout_id('sensed', 8, 1, 40, 40))
    assert header['architecture']['uncertain'] == 1 and header['track'] == 'sensed'
    loaded = GeneralistPolicy.load(path, None)
    assert loaded.layout == 'stealth-phased-v1/sensed/8phases-1perstep'
    loaded.check_scenario(scenario)
    header['architecture']['uncertain'] = 2
    with pytest.raises(policy_file.PolicyFileError, match='uncertain') as error:
        policy_file.check_header(path, header)
    assert str(path) in str(error.value) and '\n' not in str(error.value)


def test_snapshots_are_the_agents_belief_with_the_buildings_targets(belief, tmp_path):
    scenario, _ = belief
    sample = data.sample_of(0, scenario)
    twin = GeneralistPolicy.hand_set(TIMED, ScenarioReward.of(scenario))
    shots = sensed_data.episode_snapshots(scenario, sample, twin, every=10, robot_weight=20.0)
    assert len(shots) >= 2
    first, later = shots[0], shots[1]
    assert first.optimal is sample.optimal and first.grid.shape == sample.grid.shape
    # at the start one layer is sensed: every other layer is unknown there
    assert (first.grid[1:, ..., AGE] >= first.grid[0, ..., AGE]).all()
    assert later.grid[..., AGE].sum() < first.grid[..., AGE].sum()  # it has sensed more
    boosted = first.weight != sample.weight
    assert boosted.sum() == 1 and first.weight[boosted] == 21.0 * sample.weight[boosted]
    assert 0.0 < sensed_data.unknown_share(shots) < 1.0
    # --labels robot: the robot's (layer, cell) is a snapshot's only label, weighed as before
    alone = sensed_data.episode_snapshots(
        scenario, sample, twin, every=10, robot_weight=20.0, robot_only=True
    )
    assert [s.grid.tolist() for s in alone[:2]] == [s.grid.tolist() for s in shots[:2]]
    assert (alone[0].weight > 0).sum() == 1
    np.testing.assert_array_equal(alone[0].weight[boosted], first.weight[boosted])


def test_the_training_command_trains_the_sensed_network(tmp_path, capsys):
    from stealth_learn import train_generalist

    out = tmp_path / 's.npz'
    argv = ['--moving', 'mixed', '--sensed', '--sizes', '20x20x3', '--train', '1']
    argv += ['--validation', '1', '--steps', '4', '--every', '2', '--iterations', '30']
    argv += ['--rounds', '2', '--snapshot-every', '20', '--out', str(out)]
    assert train_generalist.main(argv) == 0
    assert 'round 2' in capsys.readouterr().err
    policy = GeneralistPolicy.load(out, None)
    assert policy.track == 'sensed' and policy.model.uncertain == 1
    assert policy.model.distance_cap == 4.0  # the --init weights' (the shipped ones)
    with pytest.raises(SystemExit):
        train_generalist.parse_args(['--sensed'])  # static lights: nothing to be time-aware of
    assert '--sensed: expected --moving' in capsys.readouterr().err


def test_an_init_file_that_cannot_start_the_network_is_refused_first(tmp_path, capsys):
    """--init is read before any building is generated: a missing file or weights of another
    size stop the run in one line naming the path."""
    from stealth_learn import train_generalist

    missing = tmp_path / 'none.npz'
    argv = ['--moving', 'mixed', '--sensed', '--sizes', '20x20x3', '--train', '1']
    argv += ['--validation', '1', '--steps', '2', '--out', str(tmp_path / 's.npz')]
    assert train_generalist.main([*argv, '--init', str(missing)]) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert str(missing) in error and 'no such policy file' in error
    assert train_generalist.main([*argv, '--hidden', '16', '--iterations', '10']) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert '--init' in error and str(train_generalist.MOVING_OUT) in error
    assert not (tmp_path / 's.npz').exists()
