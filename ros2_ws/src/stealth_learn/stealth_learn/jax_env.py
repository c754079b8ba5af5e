"""stealth-nav as pure JAX functions, gymnax / PureJaxRL style: jit and vmap over many
environments and over many generated scenarios at once, explicit PRNG keys.

    env, params = build(['map1'], track='full', layout='vector')   # params: a batch of 1
    one = env.scenario(params, 0)                                  # unbatched, one scenario
    obs, state = env.reset(key, one)
    obs, state, reward, done, info = env.step(key, state, action, one)
    # many environments of one scenario, and many scenarios (one each):
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, one)
    obs, state, reward, done, info = jax.vmap(env.step)(keys, state, actions, params)

The step is a handful of gathers in tables computed once by the numpy core
(``stealth_learn.env_tables``, from ``stealth_core``'s lattice model: the light law, occlusion,
moving lights' bins, exposure, step sampling and rewards of ``StealthTask``), so it judges every
step as the Gym env does: the same arrivals, float32 of the same rewards, the same outcomes,
the same states and, on track 'sensed', the same sensed light (``test_jax_env`` checks it on
generated scenarios). Only the random draws differ: slip and 'probabilistic' detection draw from
the key, not NumPy's generator (an env without either, ``stochastic`` False, draws nothing).

Semantics (gymnax's): ``step`` resets an environment whose episode ended, returning the new
episode's first observation and state; ``info`` holds the finished step's ``outcome`` (-1 none,
else ``reward.EpisodeOutcome``: 0 success, 1 detected, 2 timeout), ``terminated`` (goal or
detection), ``truncated`` (the step limit), ``visibility`` (the light the step was judged on),
``steps`` and ``episode_return`` (undiscounted, so far, this step included), ``direction`` (the
move made, after any slip) and ``final_observation``. ``done`` = terminated or truncated.
Actions are 0-3 the moves, then wait and turns as ``task.action_names``; an action beyond a
scenario's own (``params.action_mask``) stays in place, out-of-range ones are clipped.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Any, NamedTuple

import numpy as np

from stealth_learn.env_tables import Dims, Tables, TaskArrays, unknown_grids
from stealth_learn.jax_deps import jax, jnp, struct
from stealth_learn.obs_layout import CHANNELS, VECTOR, layout_id

NO_OUTCOME = -1


@struct.dataclass
class EnvParams:
    """One scenario's tables as jax arrays (a leading batch axis when stacked): see
    ``env_tables.Tables`` for each field."""

    successors: jax.Array
    step_visibility: jax.Array
    detect_p: jax.Array
    free_reward: jax.Array
    lit: jax.Array
    caught_reward: jax.Array
    goal: jax.Array
    position: jax.Array
    node_light: jax.Array
    move_light: jax.Array
    free: jax.Array
    goal_cells: jax.Array
    sense_bits: jax.Array
    perpendicular: jax.Array
    action_mask: jax.Array
    unknown_light: jax.Array  # (R, C) the sensed memory at a start (-1 nodes, -2 none)
    unknown_moves: jax.Array  # (2, R, C)
    start: jax.Array
    start_lit: jax.Array
    step_limit: jax.Array
    time_step: jax.Array  # float32 1 / step_limit (a product, the same in and out of vmap)
    vector_base: jax.Array  # (P, 8) float32: the vector of each place, lit and time_used 0
    slip: jax.Array
    goal_xy: jax.Array
    # Track 'sensed': the memory after sensing at the start (node_memory, node_seen,
    # move_memory), filled by ``StealthJaxEnv.with_first_memory`` (``build`` does),
    # so an auto-reset reads it instead of sensing again; None: sensed at each reset.
    first_memory: Any = None


@struct.dataclass
class EnvState:
    place: jax.Array  # int32: layer * rows * cols + row * cols + col
    steps: jax.Array  # int32: actions taken this episode
    lit: jax.Array  # bool: the last judged light reached the threshold
    episode_return: jax.Array  # float32
    node_memory: jax.Array  # (R, C) float32: last light sensed; (0, 0) on track 'full'
    node_seen: jax.Array  # (R, C) int32: the step it was sensed at, -1 never
    move_memory: jax.Array  # (2, R, C) float32


class Observation(NamedTuple):
    """Layout 'grid' (``obs_layout``): the (rows, cols, 7) grid and the (8,) vector."""

    grid: jax.Array
    vector: jax.Array


def params_of(tables: Tables) -> EnvParams:
    """One scenario's EnvParams (jax arrays) from its padded tables."""
    light, moves = unknown_grids(tables)
    fields = {name: getattr(tables, name) for name in EnvParams.__dataclass_fields__
              if hasattr(tables, name)}  # fmt: skip
    fields.update(
        unknown_light=light,
        unknown_moves=moves,
        start=np.int32(tables.start),
        start_lit=np.bool_(tables.start_lit),
        step_limit=np.int32(tables.step_limit),
        time_step=np.float32(1.0 / tables.step_limit),
        slip=np.float32(tables.slip),
        goal_xy=np.asarray(tables.goal_xy, np.float32),
        vector_base=_vector_base(tables),
    )
    return EnvParams(**{name: jnp.asarray(value) for name, value in fields.items()})


def stack(params: Sequence[EnvParams]) -> EnvParams:
    """A batch of scenarios' params (same Dims) along a new leading axis, for vmap."""
    return jax.tree.map(lambda *leaves: jnp.stack(leaves), *params)


_LIT, _TIME = (
    np.eye(len(VECTOR), dtype=np.float32)[VECTOR.index(k)] for k in ('lit', 'time_used')
)


def _vector_base(tables: Tables) -> np.ndarray:
    """(P, 8) float32: x, y, phase, heading, 0, 0, and the goal's offset, per place."""
    base = np.zeros((len(tables.position), len(VECTOR)), np.float32)
    base[:, :4] = tables.position
    base[:, 6] = np.float32(tables.goal_xy[0]) - tables.position[:, 0]
    base[:, 7] = np.float32(tables.goal_xy[1]) - tables.position[:, 1]
    return base


class StealthJaxEnv:
    """The environment's static side: dims, track, layout and whether it draws random numbers.
    Its methods are pure functions of (key, state, action, params); jit-compiled per instance.
    """

    def __init__(self, dims: Dims, track: str = 'full', layout: str = 'grid', stochastic=False):
        self.layout_id = layout_id(layout, track, dims.rows, dims.cols)
        self.dims, self.track, self.layout = dims, track, layout
        self.stochastic = bool(stochastic)

    @property
    def num_actions(self) -> int:
        return self.dims.actions

    def scenario(self, params: EnvParams, index: int) -> EnvParams:
        """Scenario ``index``'s params out of a stacked batch."""
        return jax.tree.map(lambda leaf: leaf[index], params)

    # --- the gymnax interface --------------------------------------------------------------

    @partial(jax.jit, static_argnums=0)
    def reset(self, key: jax.Array, params: EnvParams):
        """(obs, state) of a new episode at the scenario's start (the key is unused: the start
        is fixed; kept for gymnax's signature)."""
        return self.reset_env(key, params)

    @partial(jax.jit, static_argnums=0)
    def step(self, key: jax.Array, state: EnvState, action, params: EnvParams):
        """(obs, state, reward, done, info), resetting an environment whose episode ended."""
        key_step, key_reset = jax.random.split(key)
        obs_st, state_st, reward, done, info = self.step_env(key_step, state, action, params)
        _, state_re = self.reset_env(key_reset, params)
        state = jax.tree.map(lambda r, s: jax.lax.select(done, r, s), state_re, state_st)
        # The observation of the state kept (the reset's or the step's): one observation built,
        # not two selected between (the grid is most of a sensed step's memory traffic).
        obs = self.observe(state, params)
        return obs, state, reward, done, {**info, 'final_observation': obs_st}

    def reset_env(self, key: jax.Array, params: EnvParams):
        del key
        light, moves = params.unknown_light, params.unknown_moves
        if self.track == 'full':  # nothing sensed, nothing remembered: no memory to carry
            light, moves = jnp.zeros((0, 0), jnp.float32), jnp.zeros((2, 0, 0), jnp.float32)
        state = EnvState(
            place=params.start,
            steps=jnp.int32(0),
            lit=params.start_lit,
            episode_return=jnp.float32(0.0),
            node_memory=light,
            node_seen=jnp.full(light.shape, -1, jnp.int32),
            move_memory=moves,
        )
        if self.track == 'sensed' and params.first_memory is not None:
            memory = dict(zip(('node_memory', 'node_seen', 'move_memory'),
                              params.first_memory, strict=True))  # fmt: skip
            state = state.replace(**memory)
        elif self.track == 'sensed':
            state = self._sense(state, params)
        return self.observe(state, params), state

    def with_first_memory(self, params: EnvParams, batched: bool = True) -> EnvParams:
        """``params`` with ``first_memory`` filled (track 'sensed'; unchanged otherwise)."""
        if self.track != 'sensed':
            return params

        def first(one):
            state = self.reset_env(None, one.replace(first_memory=None))[1]
            return (state.node_memory, state.node_seen, state.move_memory)

        return params.replace(first_memory=jax.jit(jax.vmap(first) if batched else first)(params))

    def step_env(self, key: jax.Array, state: EnvState, action, params: EnvParams):
        """One step without the reset: (obs, state, reward, done, info)."""
        action = jnp.clip(jnp.asarray(action, jnp.int32), 0, self.dims.actions - 1)
        direction, detected = action, None
        place = state.place
        if self.stochastic:
            k_slip, k_side, k_detect = jax.random.split(key, 3)
            sideways = params.perpendicular[action]
            slips = (sideways[0] >= 0) & (jax.random.uniform(k_slip) < params.slip)
            side = sideways[jax.random.randint(k_side, (), 0, 2)]
            direction = jnp.where(slips, side, action)
            detected = jax.random.uniform(k_detect) < params.detect_p[place, direction]
        else:  # threshold detection: the probability is 1 or 0
            detected = params.detect_p[place, direction] > 0.5
        arrival = params.successors[place, direction]
        goal = params.goal[arrival]
        reward = jnp.where(
            detected, params.caught_reward[arrival], params.free_reward[place, direction]
        )
        steps = state.steps + 1
        terminated = detected | goal
        truncated = ~terminated & (steps >= params.step_limit)
        outcome = jnp.where(detected, 1, jnp.where(goal, 0, jnp.where(truncated, 2, NO_OUTCOME)))
        episode_return = state.episode_return + reward
        state = state.replace(
            place=arrival,
            steps=steps,
            lit=params.lit[place, direction],
            episode_return=episode_return,
        )
        if self.track == 'sensed':
            state = self._sense(state, params)
        info = {
            'outcome': outcome.astype(jnp.int32),
            'terminated': terminated,
            'truncated': truncated,
            'visibility': params.step_visibility[place, direction],
            'steps': steps,
            'episode_return': episode_return,
            'direction': direction,
        }
        return self.observe(state, params), state, reward, terminated | truncated, info

    # --- sensing and observations ----------------------------------------------------------

    def _where(self, place):
        """(layer, row, col) of a place."""
        dims = self.dims
        layer, cell = jnp.divmod(place, dims.cells)
        row, col = jnp.divmod(cell, dims.cols)
        return layer, row, col

    def _sense(self, state: EnvState, params: EnvParams) -> EnvState:
        """Remember what is in sight from the robot's node: the light of its layer (bin and
        heading) on the nodes and moves the cell's mask marks. The mask covers the whole grid,
        so the update is one elementwise pass (no window slicing: vmapped, that is a scatter)."""
        dims = self.dims
        layer, cell = jnp.divmod(state.place, dims.cells)
        bits = jnp.unpackbits(params.sense_bits[cell], count=3 * dims.cells)
        mask = bits.reshape(3, dims.rows, dims.cols).astype(bool)
        return state.replace(
            node_memory=jnp.where(mask[0], params.node_light[layer], state.node_memory),
            node_seen=jnp.where(mask[0], state.steps, state.node_seen),
            move_memory=jnp.where(mask[1:], params.move_light[layer], state.move_memory),
        )

    def vector(self, state: EnvState, params: EnvParams) -> jax.Array:
        """(8,) float32, ``obs_layout.VECTOR``: the place's row of ``vector_base`` with lit and
        the time used (one gather and a fused update: the step's largest cost otherwise)."""
        time_used = state.steps.astype(jnp.float32) * params.time_step
        lit = state.lit.astype(jnp.float32)
        return params.vector_base[state.place] + lit * _LIT + time_used * _TIME

    def observe(self, state: EnvState, params: EnvParams) -> Any:
        """The observation of a state in this env's layout (``obs_layout``)."""
        vector = self.vector(state, params)
        if self.layout == 'vector':
            return vector
        dims = self.dims
        layer, cell = jnp.divmod(state.place, dims.cells)
        if self.track == 'sensed':
            light, moves, seen = state.node_memory, state.move_memory, state.node_seen
            age = jnp.where(seen >= 0, state.steps - seen, -1)
        else:
            light, moves = params.node_light[layer], params.move_light[layer]
            age = jnp.zeros((dims.rows, dims.cols), jnp.int32)
        cells = jnp.arange(dims.cells, dtype=jnp.int32).reshape(dims.rows, dims.cols)
        robot = (cells == cell).astype(jnp.float32)  # a compare, not a scatter: cheap in vmap
        grid = jnp.stack(
            [params.free.astype(jnp.float32), robot, params.goal_cells.astype(jnp.float32),
             light, moves[0], moves[1], age.astype(jnp.float32)],
            axis=-1,
        )  # fmt: skip
        return Observation(grid, vector)


def build(
    scenarios: Sequence,
    track: str = 'full',
    layout: str = 'grid',
    slip: float = 0.0,
    dims: Dims | None = None,
) -> tuple[StealthJaxEnv, EnvParams]:
    """An env and the stacked params of ``scenarios`` (each a scenario name, path or
    ``Scenario``, or a (scenario, goal) pair), padded to ``dims`` (default: the least covering
    them all). ``stochastic`` is set when slip > 0 or any scenario detects by chance."""
    arrays = [
        TaskArrays(*(item if isinstance(item, tuple) else (item, None)), track=track)
        for item in scenarios
    ]
    if not arrays:
        raise ValueError('scenarios: expected at least one scenario')
    dims = Dims.union(a.dims for a in arrays) if dims is None else dims
    params = stack([params_of(a.tables(dims, slip)) for a in arrays])
    probabilistic = any(a.task.scenario.detection_mode != 'threshold' for a in arrays)
    env = StealthJaxEnv(dims, track, layout, stochastic=slip > 0 or probabilistic)
    return env, env.with_first_memory(params)


__all__ = ['CHANNELS', 'VECTOR', 'EnvParams', 'EnvState', 'Observation', 'StealthJaxEnv', 'build']
