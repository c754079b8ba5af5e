"""PPO on the JAX environment, PureJaxRL style (Lu et al. 2022; Schulman et al. 2017): the
generalist's network trained for the static lights-sensed track by reinforcement learning,
many generated buildings stepped at once (``jax_env``, one building per environment, vmapped).

    env, params = jax_env.build(buildings, track='sensed', layout='grid')
    trainer = Trainer(env, params, init_params, PpoConfig())
    for _ in range(updates): metrics = trainer.update()        # rollout, then the PPO epochs

- **Actor**: ``vin.Vin`` with the never-sensed input (``uncertain``) over the robot's belief
  (``believe``: a node never sensed read as dark, a move never sensed as the larger of its
  ends' light, as ``belief.believed``; the age channel 1 where the node was never sensed),
  the logits at the robot's cell (masked moves never drawn). It starts from lights-known
  weights (the never-sensed input at 0: then it is exactly that network on the belief).
- **Critic**: a linear head (the episode's time used, lit, and the actor's value at the
  robot's cell, not differentiated into the actor), so the actor's parameters stay the ones a
  weights file holds.
- **Loss**: the clipped surrogate, the value error (clipped), an entropy bonus; GAE(lambda);
  advantages normalised per minibatch; Adam with the global norm clipped (PureJaxRL's).
- **Throughput**: ``update`` returns the environment steps it took and the seconds, so env
  steps a second are those of the whole training (rollout and learning), as measured.
"""

from __future__ import annotations

import dataclasses
import time

from stealth_learn.hand_set import INPUTS
from stealth_learn.jax_deps import jax, jnp
from stealth_learn.obs_layout import VECTOR
from stealth_learn.vin import AGE, LIGHT, MASKED, MOVE_RIGHT, MOVE_UP, ROBOT, Vin

UNKNOWN = -1.0  # the sensed grid: never sensed
REWARD_SCALE = 0.01  # the env's rewards (goal ~1000) scaled into the critic's range
VALUE_SCALE = 0.01  # the actor's values (the learned reward's units) read by the critic
_LIT, _TIME = VECTOR.index('lit'), VECTOR.index('time_used')  # the critic's other inputs


@dataclasses.dataclass(frozen=True)
class PpoConfig:
    """PureJaxRL's PPO settings (its names), and the backups the actor makes in training."""

    num_steps: int = 64  # environment steps per rollout, per environment
    update_epochs: int = 2
    num_minibatches: int = 8
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_eps: float = 0.2
    ent_coef: float = 0.003
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    lr: float = 3e-4
    iterations: int = 150  # Bellman backups of the actor in training (tied weights)
    gradient_backups: int = 20  # of them, the last N differentiated (``vin.Vin``)
    critic_lr: float = 1e-2  # the critic's own Adam (its gradient never clips the actor's)


def believe(grid):
    """(..., R, C, 7) the sensed grid believed (module docstring): unknown nodes dark, unknown
    moves the larger end's light, the age channel 1 on never-sensed nodes."""
    light = grid[..., LIGHT]
    unknown = light == UNKNOWN
    light = jnp.where(unknown, 0.0, light)
    up = jnp.pad(light[..., 1:, :], [(0, 0)] * (light.ndim - 2) + [(0, 1), (0, 0)],
                 constant_values=-2.0)  # fmt: skip
    right = jnp.pad(light[..., :, 1:], [(0, 0)] * (light.ndim - 2) + [(0, 0), (0, 1)],
                    constant_values=-2.0)  # fmt: skip
    move_up, move_right = grid[..., MOVE_UP], grid[..., MOVE_RIGHT]
    move_up = jnp.where(move_up == UNKNOWN, jnp.maximum(light, up), move_up)
    move_right = jnp.where(move_right == UNKNOWN, jnp.maximum(light, right), move_right)
    grid = grid.at[..., LIGHT].set(light)
    grid = grid.at[..., MOVE_UP].set(move_up).at[..., MOVE_RIGHT].set(move_right)
    return grid.at[..., AGE].set(unknown.astype(jnp.float32))


class ActorCritic:
    """The actor (``Vin``) and the critic's linear head as pure functions of
    ``{'actor': vin params, 'critic': {'w': (3,), 'b': ()}}``."""

    def __init__(self, architecture: dict, iterations: int, gradient_backups: int = 0):
        self.vin = Vin(**{**architecture, 'iterations': iterations, 'uncertain': 1,
                          'gradient_backups': gradient_backups})  # fmt: skip

    def __call__(self, params, observation):
        """(logits (B, A), value (B,)) of a batch of sensed observations."""
        grid = believe(observation.grid)
        q = self.vin.apply({'params': params['actor']}, grid, method=Vin.q_map)
        robot = grid[..., ROBOT]
        at_robot = jnp.einsum('brc,brca->ba', robot, q)
        masked = at_robot <= MASKED / 2  # Vin.__call__'s rule
        logits = jnp.where(masked, MASKED, params['actor']['scale'] * at_robot)
        best = jax.lax.stop_gradient(jnp.where(masked, -jnp.inf, at_robot).max(axis=-1))
        vector = observation.vector
        features = jnp.stack([best * VALUE_SCALE, vector[:, _LIT], vector[:, _TIME]], axis=-1)
        value = features @ params['critic']['w'] + params['critic']['b']
        return logits, value


def initial_params(actor_params) -> dict:
    """The trainer's parameters from a network's (lights-known weights get the never-sensed
    input at weight 0: the same decisions on the belief)."""
    actor = jax.tree.map(jnp.asarray, actor_params)
    kernel = actor['reward_hidden']['kernel']
    if kernel.shape[0] == INPUTS + actor['context']['bias'].shape[0]:  # no never-sensed input
        actor = {**actor, 'reward_hidden': {**actor['reward_hidden'],
                 'kernel': jnp.concatenate([kernel, jnp.zeros_like(kernel[:1])])}}  # fmt: skip
    critic = {'w': jnp.array([1.0, 0.0, 0.0], jnp.float32), 'b': jnp.zeros((), jnp.float32)}
    return {'actor': actor, 'critic': critic}


class Trainer:
    """PPO over ``env`` (a ``jax_env.StealthJaxEnv``, track 'sensed', layout 'grid') and
    ``params`` (stacked EnvParams: one building per environment)."""

    def __init__(self, env, params, actor_params, architecture: dict, config: PpoConfig,
                 seed: int = 0):  # fmt: skip
        import optax

        self.env, self.env_params, self.config = env, params, config
        self.net = ActorCritic(architecture, config.iterations, config.gradient_backups)
        self.num_envs = int(params.start.shape[0])
        actor = optax.chain(
            optax.clip_by_global_norm(config.max_grad_norm), optax.adam(config.lr, eps=1e-5)
        )
        self.optimiser = optax.multi_transform(
            {'actor': actor, 'critic': optax.adam(config.critic_lr)},
            {'actor': 'actor', 'critic': 'critic'},
        )
        self.params = initial_params(actor_params)
        self.opt_state = self.optimiser.init(self.params)
        key, reset_key = jax.random.split(jax.random.PRNGKey(seed))
        keys = jax.random.split(reset_key, self.num_envs)
        self.obs, self.state = jax.vmap(env.reset)(keys, params)
        self.key = key
        self._update = jax.jit(self._update_fn)
        self.env_steps = 0

    def update(self) -> dict:
        """One rollout of ``num_steps`` in every environment, then the PPO epochs; the
        metrics (episode outcomes finished in the rollout, losses, steps, seconds)."""
        started = time.monotonic()
        carry = (self.params, self.opt_state, self.obs, self.state, self.key)
        (self.params, self.opt_state, self.obs, self.state, self.key), metrics = self._update(
            carry
        )
        metrics = jax.device_get(metrics)
        steps = self.config.num_steps * self.num_envs
        self.env_steps += steps
        return {**metrics, 'env_steps': steps, 'seconds': time.monotonic() - started}

    def _update_fn(self, carry):
        params, opt_state, obs, state, key = carry
        config, env, env_params = self.config, self.env, self.env_params

        def env_step(carry, _):
            obs, state, key = carry
            key, act_key, step_key = jax.random.split(key, 3)
            logits, value = self.net(params, obs)
            action = jax.random.categorical(act_key, logits)
            log_prob = jax.nn.log_softmax(logits)[jnp.arange(self.num_envs), action]
            step_keys = jax.random.split(step_key, self.num_envs)
            next_obs, state, reward, done, info = jax.vmap(env.step)(
                step_keys, state, action, env_params
            )
            transition = (obs, action, log_prob, value, reward * REWARD_SCALE, done,
                          info['outcome'])  # fmt: skip
            return (next_obs, state, key), transition

        (obs, state, key), batch = jax.lax.scan(
            env_step, (obs, state, key), None, length=config.num_steps
        )
        observations, actions, log_probs, values, rewards, dones, outcomes = batch
        _, last_value = self.net(params, obs)
        advantages, targets = _gae(values, rewards, dones, last_value, config)

        def loss_fn(params, minibatch):
            obs, action, old_log_prob, old_value, advantage, target = minibatch
            logits, value = self.net(params, obs)
            log_softmax = jax.nn.log_softmax(logits)
            log_prob = jnp.take_along_axis(log_softmax, action[:, None], axis=-1)[:, 0]
            clipped = old_value + jnp.clip(value - old_value, -config.clip_eps, config.clip_eps)
            value_loss = 0.5 * jnp.maximum((value - target) ** 2, (clipped - target) ** 2).mean()
            ratio = jnp.exp(log_prob - old_log_prob)
            advantage = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
            surrogate = jnp.minimum(
                ratio * advantage,
                jnp.clip(ratio, 1 - config.clip_eps, 1 + config.clip_eps) * advantage,
            )
            probs = jnp.exp(log_softmax)
            entropy = -(probs * jnp.where(probs > 0, log_softmax, 0.0)).sum(-1).mean()
            loss = -surrogate.mean() + config.vf_coef * value_loss - config.ent_coef * entropy
            return loss, (value_loss, entropy)

        flat = jax.tree.map(
            lambda x: x.reshape((-1, *x.shape[2:])),
            (observations, actions, log_probs, values, advantages, targets),
        )
        samples = config.num_steps * self.num_envs
        size = samples // config.num_minibatches

        def epoch(carry, _):
            params, opt_state, key = carry
            key, shuffle_key = jax.random.split(key)
            order = jax.random.permutation(shuffle_key, samples)
            minibatches = jax.tree.map(
                lambda x: x[order].reshape((config.num_minibatches, size, *x.shape[1:])), flat
            )

            def minibatch_step(carry, minibatch):
                params, opt_state = carry
                (loss, aux), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, minibatch)
                updates, opt_state = self.optimiser.update(grads, opt_state, params)
                params = jax.tree.map(lambda p, u: p + u, params, updates)
                return (params, opt_state), (loss, *aux)

            (params, opt_state), losses = jax.lax.scan(
                minibatch_step, (params, opt_state), minibatches
            )
            return (params, opt_state, key), losses

        (params, opt_state, key), losses = jax.lax.scan(
            epoch, (params, opt_state, key), None, length=config.update_epochs
        )
        finished = outcomes >= 0
        metrics = {
            'episodes': finished.sum(),
            'successes': (outcomes == 0).sum(),
            'detections': (outcomes == 1).sum(),
            'timeouts': (outcomes == 2).sum(),
            'loss': losses[0].mean(),
            'value_loss': losses[1].mean(),
            'entropy': losses[2].mean(),
        }
        return (params, opt_state, obs, state, key), metrics


def _gae(values, rewards, dones, last_value, config: PpoConfig):
    """(advantages, value targets) by GAE(lambda) over a rollout (T, N): a terminated step
    bootstraps nothing, a truncated one (the step limit) is treated as terminated too
    (PureJaxRL's simplification: the auto-reset's observation is the next episode's)."""

    def backwards(carry, step):
        advantage, next_value = carry
        value, reward, done = step
        delta = reward + config.gamma * next_value * (1 - done) - value
        advantage = delta + config.gamma * config.gae_lambda * (1 - done) * advantage
        return (advantage, value), advantage

    _, advantages = jax.lax.scan(
        backwards,
        (jnp.zeros_like(last_value), last_value),
        (values, rewards, dones.astype(jnp.float32)),
        reverse=True,
    )
    return advantages, advantages + values


def greedy_episodes(net: ActorCritic, params, env, env_params, key, steps: int):
    """Each environment's first episode under the actor's most likely actions, from a reset:
    (outcome (N,) int32: ``jax_env``'s, -1 unfinished within ``steps``; return (N,), the
    env's rewards unscaled). Jitted by the caller (``steps`` static)."""
    count = env_params.start.shape[0]
    obs, state = jax.vmap(env.reset)(jax.random.split(key, count), env_params)

    def step(carry, step_key):
        obs, state, outcome, total = carry
        logits, _ = net(params, obs)
        action = jnp.argmax(logits, axis=-1)
        keys = jax.random.split(step_key, count)
        obs, state, reward, done, info = jax.vmap(env.step)(keys, state, action, env_params)
        running = outcome < 0
        total = total + jnp.where(running, reward, 0.0)
        outcome = jnp.where(running & done, info['outcome'], outcome)
        return (obs, state, outcome, total), None

    start = (obs, state, jnp.full((count,), -1, jnp.int32), jnp.zeros((count,), jnp.float32))
    (_, _, outcome, total), _ = jax.lax.scan(step, start, jax.random.split(key, steps))
    return outcome, total
