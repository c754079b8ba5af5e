"""The JAX environment through gymnax's Environment interface: step for step the same
observations, rewards and ends as ``jax_env`` on generated buildings, both tracks, and a
PureJaxRL-style rollout (``lax.scan`` over ``vmap(env.step)``, jitted) that runs unchanged on it
and on gymnax's own CartPole."""

import numpy as np
import pytest
from stealth_learn.jax_deps import jax, jnp
from stealth_learn.jax_env import build

gymnax = pytest.importorskip('gymnax')
from stealth_learn.gymnax_env import StealthGymnax  # noqa: E402

STEPS = 300  # several episodes of the small buildings under random actions


def _random_actions(seed: int, count: int, actions: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, actions, count)


@pytest.mark.parametrize(('names', 'track', 'layout'), [
    (('still', 'moving'), 'full', 'grid'),
    (('wider',), 'full', 'vector'),
    (('still',), 'sensed', 'grid'),
])  # fmt: skip
def test_it_is_the_jax_env_step_for_step(generated, names, track, layout):
    scenarios = [generated[name] for name in names]
    env, batch = StealthGymnax.build(scenarios, track=track, layout=layout)
    core, core_batch = build(scenarios, track=track, layout=layout)
    assert env.num_actions == core.num_actions and env.name == 'StealthNav-v0'
    gymnax_step, core_step = jax.jit(env.step), jax.jit(core.step)
    for index in range(len(scenarios)):
        params, core_params = core.scenario(batch, index), core.scenario(core_batch, index)
        key = jax.random.key(index)
        obs, state = env.reset(key, params)
        core_obs, core_state = core.reset(key, core_params)
        ends = 0
        for t, action in enumerate(_random_actions(index, STEPS, env.num_actions)):
            jax.tree.map(np.testing.assert_array_equal, obs, core_obs)
            key = jax.random.key(1000 + t)
            obs, state, reward, terminated, truncated, info = gymnax_step(
                key, state, action, params
            )
            core_obs, core_state, core_reward, done, core_info = core_step(
                key, core_state, action, core_params
            )
            assert float(reward) == float(core_reward)
            assert bool(terminated | truncated) == bool(done)
            assert bool(terminated) == bool(core_info['terminated'])
            assert int(info['outcome']) == int(core_info['outcome'])
            jax.tree.map(np.testing.assert_array_equal, state, core_state)
            ends += bool(done)
        assert ends >= 1  # the auto-reset was exercised
    space = env.observation_space(env.default_params)
    assert bool(space.contains(obs))
    assert bool(env.action_space(env.default_params).contains(env.num_actions - 1))


def make_rollout(env, env_params, num_envs: int, num_steps: int):
    """PureJaxRL's environment loop (make_train's _env_step), random actions for the policy."""

    def rollout(rng):
        rng, _rng = jax.random.split(rng)
        reset_rng = jax.random.split(_rng, num_envs)
        obsv, env_state = jax.vmap(env.reset, in_axes=(0, None))(reset_rng, env_params)

        def _env_step(runner_state, unused):
            env_state, last_obs, rng = runner_state
            rng, _rng = jax.random.split(rng)
            n = env.action_space(env_params).n
            action = jax.random.randint(_rng, (num_envs,), 0, n)
            rng, _rng = jax.random.split(rng)
            rng_step = jax.random.split(_rng, num_envs)
            obsv, env_state, reward, terminated, truncated, info = jax.vmap(
                env.step, in_axes=(0, 0, 0, None)
            )(rng_step, env_state, action, env_params)
            done = jnp.logical_or(terminated, truncated)
            return (env_state, obsv, rng), (action, reward, done)

        runner_state = (env_state, obsv, rng)
        _, transitions = jax.lax.scan(_env_step, runner_state, None, num_steps)
        return transitions

    return rollout


def test_a_purejaxrl_rollout_runs_unchanged_on_it_under_jit(generated):
    cartpole, cartpole_params = gymnax.make('CartPole-v1')
    _, rewards, dones = jax.jit(make_rollout(cartpole, cartpole_params, 4, 50))(jax.random.key(0))
    assert rewards.shape == (50, 4) and bool(dones.any())

    scenario = generated['still']
    env, _ = StealthGymnax.build([scenario], track='sensed')
    params = env.default_params
    actions, rewards, dones = jax.jit(make_rollout(env, params, 8, STEPS))(jax.random.key(1))
    assert rewards.shape == (STEPS, 8) and bool(dones.any())
    # the same actions through jax_env's own vmapped step: the same rewards and ends
    core, batch = build([scenario], track='sensed')
    one = core.scenario(batch, 0)
    keys = jax.random.split(jax.random.key(2), 8)
    _, state = jax.vmap(core.reset, in_axes=(0, None))(keys, one)

    def core_step(state, action):
        _, state, reward, done, _ = jax.vmap(core.step, in_axes=(0, 0, 0, None))(
            keys, state, action, one
        )
        return state, (reward, done)

    _, (core_rewards, core_dones) = jax.jit(lambda s: jax.lax.scan(core_step, s, actions))(state)
    np.testing.assert_array_equal(rewards, core_rewards)
    np.testing.assert_array_equal(dones, core_dones)
