"""PPO on the JAX environment (``ppo``, ``train_ppo``): the belief it reads is the numpy one,
its actor starts as the lights-known network on that belief (the same decisions as the
benchmark's agent), an update trains the never-sensed input, and the command writes a weights
file the agents load (or refuses bad input in one line)."""

import jax
import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv
from stealth_learn import jax_env, policy_file
from stealth_learn.belief import believed_grid
from stealth_learn.generalist import GeneralistPolicy
from stealth_learn.generalist_agent import GeneralistAgent
from stealth_learn.ppo import ActorCritic, PpoConfig, Trainer, believe, initial_params
from stealth_learn.train_ppo import main
from stealth_learn.vin import AGE, LIGHT

ITERATIONS = 80  # enough backups for the 20 x 20 m building's values to settle


@pytest.fixture(scope='module')
def shipped():
    return policy_file.load(policy_file.SHIPPED, None)


@pytest.fixture(scope='module')
def sensed_env(generated):
    return jax_env.build([generated['still']], track='sensed', layout='grid')


def _walk(env, params, actions):
    """The observations of an episode of ``actions`` from a reset (one environment)."""
    one = env.scenario(params, 0)
    key = jax.random.PRNGKey(0)
    obs, state = env.reset(key, one)
    seen = [obs]
    for action in actions:
        obs, state, *_ = env.step(key, state, action, one)
        seen.append(obs)
    return seen


def test_the_belief_is_the_numpy_belief_with_the_never_sensed_input(sensed_env):
    env, params = sensed_env
    for obs in _walk(env, params, [3, 3, 0, 0, 3, 0]):
        grid = np.asarray(obs.grid)
        expected = believed_grid(grid, uncertain=True)
        np.testing.assert_array_equal(np.asarray(believe(jax.numpy.asarray(grid))), expected)
        unknown = grid[..., LIGHT] == -1
        assert unknown.sum() > 0 and (expected[..., AGE] == unknown).all()


def test_the_actor_starts_as_the_lights_known_network_on_the_belief(generated, shipped):
    """At the never-sensed input's weight 0 its moves are the benchmark agent's, step by step
    along an episode of the sensed Gym env (the JAX env judges the same steps)."""
    params, header = shipped
    architecture = {**header['architecture'], 'iterations': ITERATIONS}
    net = ActorCritic(architecture, ITERATIONS)
    actor_params = initial_params(params)
    policy = GeneralistPolicy(actor_params['actor'], {**architecture, 'uncertain': 1})
    gym = StealthNavEnv(generated['still'], track='sensed')
    agent = GeneralistAgent(policy, gym)
    env, env_params = jax_env.build([generated['still']], track='sensed', layout='grid')
    one = env.scenario(env_params, 0)
    key = jax.random.PRNGKey(0)
    obs, state = env.reset(key, one)
    observation, _ = gym.reset(seed=0)
    decide = jax.jit(lambda o: net(actor_params, o)[0])
    for _ in range(25):
        batch = jax.tree.map(lambda x: x[None], obs)
        action = int(np.argmax(np.asarray(decide(batch))[0]))
        assert action == agent.act(observation)
        observation, _, terminated, truncated, _ = gym.step(action)
        obs, state, _, done, _ = env.step(key, state, action, one)
        if terminated or truncated:
            break


def test_an_update_trains_the_never_sensed_input_and_counts_its_steps(generated, shipped):
    params, header = shipped
    env, env_params = jax_env.build([generated['still']] * 2, track='sensed', layout='grid')
    config = PpoConfig(num_steps=8, num_minibatches=2, iterations=30, gradient_backups=0)
    trainer = Trainer(env, env_params, params, header['architecture'], config)
    before = np.asarray(trainer.params['actor']['reward_hidden']['kernel'])
    metrics = trainer.update()
    after = np.asarray(trainer.params['actor']['reward_hidden']['kernel'])
    assert (before[-1] == 0).all() and not np.allclose(after[-1], 0)  # the new input learns
    assert metrics['env_steps'] == 16 and trainer.env_steps == 16
    assert np.isfinite([metrics['loss'], metrics['value_loss'], metrics['entropy']]).all()


def test_the_command_writes_a_sensed_weights_file_the_agent_loads(tmp_path, generated, capsys):
    out = tmp_path / 'ppo.npz'
    argv = ['--out', str(out), '--size', '20x20x3', '--train', '2', '--hardest-of', '3',
            '--validation', '1', '--updates', '1', '--num-steps', '4', '--minibatches', '2',
            '--iterations', '20', '--gradient-backups', '5']  # fmt: skip
    assert main(argv) == 0
    assert 'screened 3 buildings: kept the 2 hardest' in capsys.readouterr().out
    policy = GeneralistPolicy.load(out, None)
    assert policy.track == 'sensed' and policy.model.uncertain == 1
    training = policy.header['training']
    assert training['env_steps'] == 8 and training['env_steps_per_second'] > 0
    assert out.with_suffix('.png').stat().st_size > 0
    env = StealthNavEnv(generated['still'], track='sensed')
    agent = GeneralistAgent(policy, env)
    observation, _ = env.reset(seed=0)
    grid = agent.grid(observation)
    assert (grid[..., AGE] == (np.asarray(observation['light']) == -1)).all()
    assert agent.act(observation) in range(4)


@pytest.mark.parametrize(
    ('argv', 'message'),
    [
        (['--gradient-backups', '200', '--iterations', '100'], '--gradient-backups: expected'),
        (['--size', '20x20'], 'expected WIDTHxHEIGHTxLIGHTS'),
        (['--train', '3', '--num-steps', '5', '--minibatches', '2'], '--minibatches'),
        (['--train', '4', '--hardest-of', '3'], '--hardest-of: expected 0 or at least --train'),
    ],
)
def test_bad_arguments_are_refused_in_one_line(tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as stopped:
        main(['--out', str(tmp_path / 'p.npz'), *argv])
    assert stopped.value.code == 2
    assert message in capsys.readouterr().err


def test_time_aware_init_weights_are_refused_naming_the_file(tmp_path, capsys):
    moving = policy_file.SHIPPED.with_name('generalist-moving.npz')
    assert main(['--out', str(tmp_path / 'p.npz'), '--init', str(moving)]) == 2
    err = capsys.readouterr().err
    assert str(moving) in err and 'time-aware' in err and '\n' not in err.strip()
