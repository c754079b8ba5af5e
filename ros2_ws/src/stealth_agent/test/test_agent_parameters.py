"""The agent's parameters: the values refused, and the learner settings they make."""

import pytest
from stealth_agent.agent_parameters import (
    PARAMETERS,
    change_problem,
    learner_config,
    startup_problem,
)

DEFAULTS = {name: param.default for name, param in PARAMETERS.items()}


def test_the_defaults_make_rl_agents_learner():
    config = learner_config(DEFAULTS)
    assert (config.gamma, config.initial_value, config.n_planning) == (0.99, 0.0, 10)
    assert (config.alpha.kind, config.alpha.start) == ('constant', 0.3)
    assert (config.epsilon.kind, config.epsilon.start) == ('constant', 0.1)
    assert startup_problem(DEFAULTS) is None


def test_schedules_come_from_their_parameters():
    values = {
        **DEFAULTS,
        'epsilon_schedule': 'linear',
        'epsilon_final': 0.02,
        'epsilon_decay_episodes': 50.0,
    }
    epsilon = learner_config(values).epsilon
    assert (epsilon.kind, epsilon.start, epsilon.final, epsilon.decay) == (
        'linear',
        0.1,
        0.02,
        50.0,
    )


@pytest.mark.parametrize(
    ('change', 'reason'),
    [
        (('agent', 'ppo'), "unknown learner 'ppo'"),
        (('alpha_schedule', 'cosine'), 'alpha_schedule must be one of constant, linear'),
        (('epsilon_decay_episodes', 0.0), 'epsilon_decay_episodes must be > 0, got 0.0'),
    ],
)
def test_unusable_values_are_refused_with_the_reason(change, reason):
    assert reason in change_problem([change], DEFAULTS)
    assert reason in change_problem([change], None)  # while declaring too


def test_learner_settings_are_checked_together_with_the_current_values():
    # linear from 0.1 to a final above 1 is refused only as a whole learner setting.
    current = {**DEFAULTS, 'epsilon_schedule': 'linear'}
    assert change_problem([('epsilon_final', 0.5)], current) is None
    assert 'epsilon must stay in [0, 1]' in change_problem([('epsilon', 1.5)], current)
    assert change_problem([('epsilon', 1.5)], None) is None  # declaring: checked at startup
    assert change_problem([('log_every', 3)], current) is None
    assert change_problem([('agent', 'Dyna-Q'), ('n', 3)], current) is None


def test_startup_needs_a_policy_file_to_evaluate_or_load():
    for name in ('evaluate', 'load_policy'):
        assert startup_problem({**DEFAULTS, name: True}) == (
            'evaluate and load_policy need policy_file'
        )
        assert startup_problem({**DEFAULTS, name: True, 'policy_file': 'p.npz'}) is None
    assert 'gamma must be in [0, 1]' in startup_problem({**DEFAULTS, 'gamma': 2.0})
