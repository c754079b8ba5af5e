"""The JAX environment (``jax_env``) through gymnax's ``Environment`` interface, so code written
for gymnax environments (PureJaxRL's ``make_train``, its wrappers) runs on it unchanged.

    env, params = StealthGymnax.build(['map1'], track='sensed')    # params: a batch of scenarios
    obs, state = env.reset(key, env.default_params)                # scenario 0, or any one
    obs, state, reward, terminated, truncated, info = env.step(key, state, action, params_i)

``reset_env`` and ``step_env`` are ``StealthJaxEnv``'s (the same tables, rewards and outcomes);
``step`` is gymnax's own (1.0.1): the step, then an auto-reset where the episode ended, the
6-tuple of gymnasium's convention (``truncated``: the step limit reached). A batch of scenarios
is vmapped over its params, as ``jax_env``'s: ``jax.vmap(env.step)(keys, states, actions,
params)``; one scenario's many environments over keys: ``in_axes=(0, 0, 0, None)``.

- ``observation_space``: layout 'vector', a Box (8,); layout 'grid', a Dict of the grid Box
  (rows, cols, 7; lights -2 where no node or move is, age -1 never sensed) and the vector Box
  (``obs_layout``); observations are ``jax_env.Observation`` (grid, vector), which gymnax's
  Dict space reads by name.
- ``action_space``: Discrete(actions of the padded batch; an action beyond a scenario's own
  stays in place: ``params.action_mask``).

gymnax imports gymnasium, seaborn and six at ``import gymnax``: the learning extra pins them
(``requirements-learn.in``); without gymnax this module says so in one line.
"""

from __future__ import annotations

from collections.abc import Sequence

from stealth_learn.jax_deps import INSTALL_HINT, MissingExtraError, jax, jnp
from stealth_learn.jax_env import EnvParams, EnvState, StealthJaxEnv, build
from stealth_learn.obs_layout import CHANNELS, VECTOR

try:
    from gymnax.environments import environment, spaces
except ImportError as error:  # one line, not the import machinery's traceback chain
    missing = getattr(error, 'name', None) or 'gymnax'
    raise MissingExtraError(
        f'stealth_learn.gymnax_env needs gymnax, in the learning extra ({missing} is missing): '
        f'install it with {INSTALL_HINT}'
    ) from None

NAME = 'StealthNav-v0'  # the Gym env's id (stealth_core.gym_env)
NO_PLACE = -2.0  # obs_layout: the light where no node or move is


class StealthGymnax(environment.Environment):
    """``StealthJaxEnv`` as a gymnax Environment (module docstring). ``core``: the JAX env;
    ``params``: the default scenario's params (unbatched)."""

    def __init__(self, core: StealthJaxEnv, params: EnvParams):
        super().__init__()
        self.core = core
        self._default_params = params

    @classmethod
    def build(
        cls, scenarios: Sequence, track: str = 'full', layout: str = 'grid', **options
    ) -> tuple[StealthGymnax, EnvParams]:
        """(env, the stacked params of ``scenarios``) as ``jax_env.build`` makes them; the
        default params are the first scenario's."""
        core, params = build(scenarios, track=track, layout=layout, **options)
        return cls(core, core.scenario(params, 0)), params

    @property
    def default_params(self) -> EnvParams:
        return self._default_params

    def reset_env(self, key: jax.Array, params: EnvParams):
        return self.core.reset_env(key, params)

    def step_env(self, key: jax.Array, state: EnvState, action, params: EnvParams):
        """(obs, state, reward, terminated, info): the goal or a detection terminates; the
        step limit is ``is_truncated``'s (gymnax's ``step`` asks it)."""
        obs, state, reward, _, info = self.core.step_env(key, state, action, params)
        return obs, state, reward, info['terminated'], info

    def is_truncated(self, state: EnvState, params: EnvParams) -> jax.Array:
        return state.steps >= params.step_limit

    def is_terminated(self, state: EnvState, params: EnvParams) -> jax.Array:
        """At the goal; a detection is the step's, not the state's (``step_env`` says it)."""
        return params.goal[state.place]

    def get_obs(self, state: EnvState, params=None, key=None):
        return self.core.observe(state, self.default_params if params is None else params)

    @property
    def name(self) -> str:
        return NAME

    @property
    def num_actions(self) -> int:
        return self.core.num_actions

    def action_space(self, params: EnvParams | None = None) -> spaces.Discrete:
        return spaces.Discrete(self.core.num_actions)

    def observation_space(self, params: EnvParams | None = None) -> spaces.Space:
        vector = spaces.Box(-jnp.inf, jnp.inf, (len(VECTOR),), jnp.float32)
        if self.core.layout == 'vector':
            return vector
        dims = self.core.dims
        grid = spaces.Box(NO_PLACE, jnp.inf, (dims.rows, dims.cols, len(CHANNELS)), jnp.float32)
        return spaces.Dict({'grid': grid, 'vector': vector})


__all__ = ['NAME', 'StealthGymnax']
