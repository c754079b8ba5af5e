"""The agent's core built for an environment: fresh, resumed, evaluated, or refused."""

import numpy as np
from stealth_agent.agent_parameters import PARAMETERS
from stealth_agent.agent_setup import set_up_agent
from stealth_agent.learners import LearnerConfig, make_learner
from stealth_agent.policy_store import save_policy
from stealth_agent.protocol import ProtocolAgent, parse_description
from stealth_agent.state_index import StateIndex, mapping_from_description

DEFAULTS = {name: param.default for name, param in PARAMETERS.items()}
GRID = parse_description(4, 0, [0.0, 0.0], [3.0, 3.0], 10.0, 11.0, False, True, 'grid')


def saved(path, learner_name='qlearning', episodes=3, title='grid'):
    mapping, _ = mapping_from_description(GRID.min_state_range, GRID.max_state_range)
    learner = make_learner(learner_name, 4, LearnerConfig())
    agent = ProtocolAgent(learner, StateIndex(mapping), np.random.default_rng(8))
    for _ in range(episodes):
        agent.handle([0.0, 0.0], 0.0, False)
        agent.handle([1.0, 0.0], -1.0, False)
        agent.handle([2.0, 0.0], 10.0, True)
    save_policy(path, agent.learner, agent.index, scenario={'title': title}, rng=agent.rng)
    return agent


def test_a_fresh_table_seeded_and_numbered_from_first_episode():
    setup = set_up_agent(GRID, {**DEFAULTS, 'agent': 'sarsa', 'seed': 5, 'first_episode': 7})
    assert setup.core is not None and setup.error == '' and setup.warnings == ()
    assert setup.core.learner.name == 'sarsa' and setup.core.learning
    assert setup.core.episode == 7 and len(setup.core.index) == 0
    assert setup.core.rng.random() == np.random.default_rng(5).random()
    assert setup.summary.startswith("environment 'grid': 4 actions, state ranges [0.0, 0.0]..")
    assert 'learner sarsa (gamma 0.99, alpha 0.3 (constant), epsilon 0.1 (constant)' in (
        setup.summary
    )
    assert setup.summary.endswith('from a fresh table; learning')


def test_load_policy_without_a_file_yet_starts_fresh_with_a_warning(tmp_path):
    path = tmp_path / 'p.npz'
    setup = set_up_agent(GRID, {**DEFAULTS, 'load_policy': True, 'policy_file': str(path)})
    assert setup.core is not None
    assert setup.warnings == (f'no policy file at {path} yet; starting with a fresh table',)


def test_a_resumed_policy_continues_its_table_and_random_stream(tmp_path):
    path = tmp_path / 'p.npz'
    trained = saved(path)
    values = {**DEFAULTS, 'load_policy': True, 'policy_file': str(path), 'epsilon': 0.2}
    setup = set_up_agent(GRID, values)
    core = setup.core
    assert core.learner.episodes == 3 and len(core.index) == len(trained.index)
    assert core.learner.epsilon == 0.2  # the parameters' settings, not the file's
    assert core.rng.random() == trained.rng.random()
    assert f'from {path} (3 episodes, {len(trained.index)} states), continuing its random' in (
        setup.summary
    )


def test_evaluation_is_greedy_whatever_the_learner(tmp_path):
    path = tmp_path / 'p.npz'
    saved(path, learner_name='dyna')
    setup = set_up_agent(GRID, {**DEFAULTS, 'evaluate': True, 'policy_file': str(path)})
    assert not setup.core.learning and setup.core.learner.name == 'dyna'
    assert '(greedy, ties broken with seed 1)' in setup.summary
    assert setup.summary.endswith('evaluating (no learning)')


def test_an_unusable_policy_file_leaves_no_core(tmp_path):
    missing = tmp_path / 'missing.npz'
    setup = set_up_agent(GRID, {**DEFAULTS, 'evaluate': True, 'policy_file': str(missing)})
    assert setup.core is None and 'no such file' in setup.error and setup.summary == ''
    other = tmp_path / 'other.npz'
    saved(other, title='another scenario')
    setup = set_up_agent(GRID, {**DEFAULTS, 'load_policy': True, 'policy_file': str(other)})
    assert setup.core is None and 'another scenario' in setup.error


def test_warnings_about_the_ranges_come_with_the_core():
    bad = parse_description(2, 0, [0.0], [1.0, 2.0], 1.0, 2.0, False, True, 'bad')
    setup = set_up_agent(bad, DEFAULTS)
    assert setup.core is not None and 'differ in length' in setup.warnings[0]
