"""Policy files: save, load, resume bit for bit, atomic writes, corrupt and mismatched files."""

import json
import zipfile

from grid_mdps import STEALTH_GRID, run_episode
import numpy as np
import pytest
from stealth_agent import policy_store
from stealth_agent.learners import TABULAR_LEARNERS, LearnerConfig, make_learner
from stealth_agent.policy_store import (
    PolicyFileError,
    PolicyMismatchError,
    check_compatible,
    load_policy,
    save_policy,
)
from stealth_agent.protocol import ProtocolAgent
from stealth_agent.schedules import Schedule
from stealth_agent.state_index import StateIndex, StateMapping

SCENARIO = {'title': 'stealth-nav: test grid', 'num_actions': 4}


def trained(name='qlearning', episodes=10, seed=0, mapping=None):
    config = LearnerConfig(epsilon=Schedule('linear', 0.3, 0.05, 20))
    learner = make_learner(name, 4, config)
    agent = ProtocolAgent(learner, StateIndex(mapping), np.random.default_rng(seed))
    results = [run_episode(agent, STEALTH_GRID) for _ in range(episodes)]
    return agent, results


@pytest.mark.parametrize('name', TABULAR_LEARNERS)  # light-model: test_light_model
def test_round_trip_keeps_table_index_and_metadata(tmp_path, name):
    agent, _ = trained(name)
    path = tmp_path / 'policy.npz'
    save_policy(path, agent.learner, agent.index, scenario=SCENARIO, rng=agent.rng)
    policy = load_policy(path)
    assert policy.learner.name == name
    assert policy.learner.q.tobytes() == agent.learner.q.tobytes()
    assert np.array_equal(policy.index.keys_array(), agent.index.keys_array())
    assert policy.learner.episodes == 10 and policy.learner.config == agent.learner.config
    assert policy.meta['state_dim'] == 2 and policy.meta['num_states'] == len(agent.index)
    assert policy.scenario['title'] == SCENARIO['title']
    assert [p.name for p in tmp_path.iterdir()] == ['policy.npz']  # no temporary file left
    if name == 'dyna':
        assert policy.learner.model_size == agent.learner.model_size > 0


@pytest.mark.parametrize('name', TABULAR_LEARNERS)  # light-model: test_light_model
def test_resume_continues_the_same_learning_curve_bit_for_bit(tmp_path, name):
    straight, curve = trained(name, episodes=20, seed=4)
    first, first_half = trained(name, episodes=10, seed=4)
    save_policy(tmp_path / 'p.npz', first.learner, first.index, rng=first.rng)
    policy = load_policy(tmp_path / 'p.npz')
    resumed = ProtocolAgent(policy.learner, policy.index, policy.restored_rng())
    second_half = [run_episode(resumed, STEALTH_GRID) for _ in range(10)]
    assert [(r.reward, r.actions) for r in first_half + second_half] == [
        (r.reward, r.actions) for r in curve
    ]
    assert resumed.learner.q.tobytes() == straight.learner.q.tobytes()
    assert resumed.learner.epsilon == straight.learner.epsilon


def test_grid_mapping_round_trip(tmp_path):
    agent, _ = trained(mapping=StateMapping('grid', (0.5,), (0.0, 0.0), (2.0, 2.0)))
    save_policy(tmp_path / 'p.npz', agent.learner, agent.index)
    policy = load_policy(tmp_path / 'p.npz')
    assert policy.index.mapping == agent.index.mapping
    assert policy.index.lookup([1.0, 0.5]) == agent.index.lookup([1.0, 0.5]) is not None


def test_evaluation_runs_the_saved_policy_greedily_without_learning(tmp_path):
    agent, _ = trained(episodes=60)
    save_policy(tmp_path / 'p.npz', agent.learner, agent.index)
    policy = load_policy(tmp_path / 'p.npz')
    before = policy.learner.q.copy()
    evaluator = ProtocolAgent(
        policy.learner, policy.index, np.random.default_rng(0), learning=False
    )
    results = [run_episode(evaluator, STEALTH_GRID) for _ in range(3)]
    assert np.array_equal(policy.learner.q[: len(before)], before)
    assert {r.actions for r in results} == {8} and all(r.epsilon == 0 for r in results)


def test_saving_again_replaces_the_file_atomically(tmp_path, monkeypatch):
    agent, _ = trained()
    path = tmp_path / 'p.npz'
    save_policy(path, agent.learner, agent.index)
    good = path.read_bytes()

    def exploding_savez(f, **arrays):
        f.write(b'half a file')
        raise OSError('disk full')

    monkeypatch.setattr(policy_store.np, 'savez', exploding_savez)
    with pytest.raises(OSError, match='disk full'):
        save_policy(path, agent.learner, agent.index)
    assert path.read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ['p.npz']


def test_missing_file(tmp_path):
    with pytest.raises(PolicyFileError, match=r'nowhere\.npz: no such file'):
        load_policy(tmp_path / 'nowhere.npz')


@pytest.mark.parametrize('variant', ['garbage', 'empty', 'truncated'])
def test_corrupt_files_are_rejected_naming_the_file(tmp_path, variant):
    agent, _ = trained()
    save_policy(tmp_path / 'good.npz', agent.learner, agent.index)
    good = (tmp_path / 'good.npz').read_bytes()
    contents = {
        'garbage': b'this is not a policy at all\n' * 10,
        'empty': b'',
        'truncated': good[: len(good) // 2],
    }
    path = tmp_path / f'{variant}.npz'
    path.write_bytes(contents[variant])
    with pytest.raises(PolicyFileError, match=rf'{variant}\.npz: corrupt'):
        load_policy(path)


def _rewrite(path, **changes):
    """Rewrite a policy archive with some arrays or metadata entries changed."""
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    meta = json.loads(str(arrays['meta'][()]))
    meta.update(changes.pop('meta', {}))
    arrays['meta'] = np.array(json.dumps(meta))
    arrays.update(changes)
    np.savez(path, **arrays)


@pytest.mark.parametrize(
    ('changes', 'message'),
    [
        ({'meta': {'version': 99}}, 'format version 99'),
        ({'meta': {'format': 'something else'}}, 'not a stealth-nav tabular policy file'),
        ({'meta': {'learner': 'texplore'}}, "unknown learner 'texplore'"),
        ({'q': np.zeros((3, 4))}, 'corrupt'),
        ({'q': np.full((1, 1), np.nan)}, 'corrupt'),
        ({'state_keys': np.zeros((2, 2, 2))}, 'corrupt'),
        ({'meta': {'config': {'gamma': 2.0}}}, 'corrupt'),
    ],
)
def test_inconsistent_contents_are_rejected(tmp_path, changes, message):
    agent, _ = trained()
    path = tmp_path / 'p.npz'
    save_policy(path, agent.learner, agent.index)
    _rewrite(path, **changes)
    with pytest.raises(PolicyFileError, match=message):
        load_policy(path)


def test_missing_array_is_named(tmp_path):
    path = tmp_path / 'p.npz'
    with zipfile.ZipFile(path, 'w') as archive:
        archive.writestr('unrelated.npy', b'')
    with pytest.raises(PolicyFileError, match='corrupt'):
        load_policy(path)
    np.savez(path, q=np.zeros((1, 4)))
    with pytest.raises(PolicyFileError, match="'meta' is missing"):
        load_policy(path)


def test_mismatches_are_all_named_with_the_file(tmp_path):
    agent, _ = trained('dyna')
    path = tmp_path / 'p.npz'
    save_policy(path, agent.learner, agent.index, scenario=SCENARIO)
    policy = load_policy(path)
    check_compatible(
        policy,
        num_actions=4,
        state_dim=2,
        learner='dyna',
        scenario_title=SCENARIO['title'],
        mapping=StateMapping(),
    )
    with pytest.raises(PolicyMismatchError) as caught:
        check_compatible(
            policy,
            num_actions=5,
            state_dim=3,
            learner='sarsa',
            scenario_title='stealth-nav: other map',
            mapping=StateMapping('grid', (0.5,)),
        )
    text = str(caught.value)
    assert str(path) in text
    for expected in (
        'action count 4 in the file, 5 expected',
        'state dimension 2 in the file, 3 expected',
        "learner 'dyna' in the file, 'sarsa' expected",
        "scenario 'stealth-nav: test grid' in the file, 'stealth-nav: other map' expected",
        'state mapping exact',
    ):
        assert expected in text
