"""The lights-known generalist as a policy, its twins (the same network untrained, or with the
environment's reward written in: ``hand_set``), and one greedy episode in the JAX environment.

    policy = GeneralistPolicy.load(path, env.layout_id)     # refused for another layout
    twin = GeneralistPolicy.hand_set(policy.header['architecture'], ScenarioReward.of(scenario))
    action = policy.act(observation.grid)                   # the grid of jax_env's 'grid' layout
    episode = rollout(policy, scenario)                     # against value iteration's optimum

The lights are known on this track, so the value map depends only on the grid's static
channels: ``rollout`` computes it once per episode and attends at the robot's cell each step,
which is exactly what ``act`` gives step by step (``test_generalist`` checks they agree). With
moving lights the network is the time-aware one (``vin.Vin`` with phase layers: the phased
grid in, the wait among the actions) and the attention is at the robot's layer and cell.
The evaluation beside the baselines is `stealth generalist` (``stealth_experiments``: the
benchmark's methods, which this package may not import).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
from pathlib import Path

import numpy as np
from stealth_core.planners import follow, value_iteration
from stealth_core.scenario_generator import GenerationError, Options

from stealth_learn import generalist_data as data
from stealth_learn import policy_file
from stealth_learn.env_tables import TaskArrays
from stealth_learn.hand_set import ScenarioReward, hand_set_params
from stealth_learn.interruptible import interruptible
from stealth_learn.jax_deps import jax, jnp
from stealth_learn.jax_env import build
from stealth_learn.obs_layout import LayoutError, check_layout, phased_layout_id
from stealth_learn.vin import ROBOT, Vin, logits_of_values

DEFAULT_POLICY = policy_file.SHIPPED
NO_HORIZON = np.iinfo(np.int32).max  # no horizon given: backups up to Bellman-Ford's bound


class GeneralistPolicy:
    """The network and its parameters; decisions come from the parameters alone. ``source``
    names them in messages: the weights file, or how they were set."""

    def __init__(self, params, architecture: dict, header: dict | None = None, source=''):
        self.model = Vin(**architecture)
        self.variables = {'params': jax.tree_util.tree_map(jnp.asarray, params)}
        self.header = header or {'architecture': dict(architecture)}
        self.source = str(source) or 'the generalist'
        self.backups = 0  # the last plan's Bellman backups (``cell_logits``)
        self._logits = _compiled(tuple(sorted(architecture.items())))

    @classmethod
    def load(cls, path, env_layout: str) -> GeneralistPolicy:
        params, header = policy_file.load(path, env_layout)
        return cls(params, header['architecture'], header, source=path)

    @classmethod
    def untrained(cls, architecture: dict, seed: int = 0) -> GeneralistPolicy:
        """The same architecture at its initialisation (the issue's untrained comparison)."""
        model = Vin(**architecture)
        grid = jnp.zeros((1, *model.grid_shape(4, 4)), jnp.float32)
        params = model.init(jax.random.PRNGKey(seed), grid)['params']
        return cls(params, architecture, source=f'the untrained network (seed {seed})')

    @classmethod
    def hand_set(
        cls, architecture: dict, reward: ScenarioReward, kind: str = 'env'
    ) -> GeneralistPolicy:
        """The same architecture with the scenario's reward written into its weights
        (``hand_set``: ``kind`` 'env', the environment's reward, or 'dark-steps', -1 a move and
        -1e4 a lit one), nothing learned: the baseline a trained network must beat."""
        params, architecture = hand_set_params(architecture, reward, kind)
        source = f'the hand-set network ({kind} reward of {reward.scenario or "the scenario"})'
        return cls(params, architecture, source=source)

    @property
    def track(self) -> str:
        """The track the weights were trained for: 'full', or 'sensed' (a network reading the
        never-sensed input, ``vin.Vin``'s ``uncertain``)."""
        return self.header.get('track', 'full')

    @property
    def layout(self) -> str:
        """The observation layout the network reads (``policy_file.policy_layout``)."""
        return policy_file.policy_layout(self.track, self.header['architecture'])

    def check_scenario(self, scenario, model=None) -> None:
        """LayoutError, one line naming these weights and the scenario, unless the network can
        play it: a static network reads no phase and cannot wait (static lights only); a
        time-aware one reads the phased grid of its phase count and step, so it needs moving
        lights of the same cycle (``model``: the scenario's lattice model, built if None)."""
        where = f'scenario {scenario.name!r} ({scenario.path})'
        phased = self.model.phased
        if not phased and not scenario.has_moving_lights:
            return
        if not phased:
            raise LayoutError(
                f'{self.source}: the policy was trained for static lights (layout '
                f'{self.layout!r}: no phase input, no wait), {where} has moving lights; a '
                f'time-aware policy is needed there (layout {_scenario_layout(scenario, model)!r})'
            )
        if not scenario.has_moving_lights:
            raise LayoutError(
                f'{self.source}: the policy is time-aware (layout {self.layout!r}), {where} has '
                f'static lights (layout {policy_file.policy_layout("full")!r}); use a static '
                'policy there'
            )
        check_layout(
            self.layout, _scenario_layout(scenario, model, self.track), f'{self.source} ({where})'
        )

    def cell_logits(self, grid, horizon: int | None = None) -> np.ndarray:
        """(R, C, 4) the logits of every cell of one grid (R, C, 7), or (L, R, C, 5) of every
        cell and layer of a phased grid (L, R, C, 12), from values backed up until they are
        a fixed point (``vin.Vin.q_and_backups``; ``backups`` says how many that took), at most
        max(iterations, ``horizon``) backups where a horizon is given (None: up to
        Bellman-Ford's bound); Ctrl-C stops it at once, compile or run (``interruptible``)."""
        batch = jnp.asarray(grid)[None]
        cap = jnp.asarray(NO_HORIZON if horizon is None else horizon, jnp.int32)
        plan = lambda: jax.device_get(self._logits(self.variables, batch, cap))  # noqa: E731
        logits, backups = interruptible(plan)
        self.backups = int(backups)
        return np.asarray(logits)[0]

    def act(self, grid) -> int:
        """The move (0 up, 1 down, 2 left, 3 right; 4 wait: time-aware) at the robot's cell
        (and layer) of one grid."""
        return int(np.argmax(self.cell_logits(grid)[robot_cell(grid)]))


def _scenario_layout(scenario, model=None, track: str = 'full') -> str:
    """The phased grid layout of a scenario with moving lights on ``track``: its lattice
    model's phase layers and the layers a step advances (``model``: built if None)."""
    model = TaskArrays(scenario).model if model is None else model
    timing = model.task.timing
    return phased_layout_id(track, model.layers, 0 if timing is None else timing.bins_per_step)


@functools.lru_cache(maxsize=8)
def _compiled(architecture: tuple):
    """The jitted (logits of every cell, backups made) of the decision for one architecture,
    shared by every policy of it (a hand-set twin per scenario compiles once per grid shape,
    not once per policy)."""
    model = Vin(**dict(architecture))

    def decide(variables, grid, horizon):
        q, backups = model.apply(variables, grid, True, horizon, method=Vin.q_and_backups)
        return logits_of_values(variables, q), backups

    return jax.jit(decide)


def robot_cell(grid) -> tuple[int, ...]:
    """(row, col) of the robot in one grid (R, C, 7), (layer, row, col) in a phased grid: its
    robot channel's maximum."""
    robot = np.asarray(grid)[..., ROBOT]
    return tuple(int(i) for i in np.unravel_index(int(np.argmax(robot)), robot.shape))


class PlanCache:
    """Every cell's move (``GeneralistPolicy.act`` at each cell) for a grid, computed by the
    network once per distinct grid (``horizon``: ``GeneralistPolicy.cell_logits``') and then
    looked up: with static lights a whole episode (or run) reads one plan, and a decision costs
    a lookup. The robot channel is ignored (the
    decision is read at the robot's cell); the last grid is compared in place (a decision's
    common case, about 10x cheaper than hashing a copy), another looked up by the hash of its
    static channels; the ``keep`` latest distinct plans are kept. ``prepare``: the grid the
    network reads for a grid (e.g. ``belief.believed_grid``; default the grid itself), applied
    once per grid that is not the last; plans are keyed on the grid read, so grids that differ
    only in what their belief fills in share one."""

    def __init__(
        self, policy: GeneralistPolicy, keep: int = 64, prepare=None, horizon: int | None = None
    ):
        self.policy = policy
        self.horizon = horizon
        self.keep = keep
        self.prepare = prepare
        self.computed = 0  # plans computed (each a full pass of the network)
        self._plans: dict[bytes, np.ndarray] = {}
        self._last: tuple[np.ndarray, np.ndarray] | None = None  # (static grid, its moves)

    def __len__(self) -> int:
        return len(self._plans)

    def moves(self, grid) -> np.ndarray:
        """(R, C) int8: the move at every cell of ``grid`` (R, C, 7); (L, R, C) of a phased
        grid."""
        grid = np.asarray(grid)
        last = self._last
        if (
            last is not None
            and last[0].shape == grid.shape
            and np.array_equal(grid[..., :ROBOT], last[0][..., :ROBOT])
            and np.array_equal(grid[..., ROBOT + 1 :], last[0][..., ROBOT + 1 :])
        ):
            return last[1]
        static = np.array(grid, dtype=np.float32)
        static[..., ROBOT] = 0.0
        read = static if self.prepare is None else self.prepare(static)
        key = hashlib.blake2b(read.tobytes(), digest_size=16).digest() + bytes(
            str(read.shape), 'ascii'
        )
        moves = self._plans.get(key)
        if moves is None:
            moves = self.policy.cell_logits(read, self.horizon).argmax(axis=-1).astype(np.int8)
            self.computed += 1
            if len(self._plans) >= self.keep:
                self._plans.pop(next(iter(self._plans)))
            self._plans[key] = moves
        self._last = (static, moves)
        return moves


@dataclasses.dataclass(frozen=True)
class Episode:
    name: str
    outcome: int  # reward.EpisodeOutcome: 0 success, 1 detected, 2 timeout
    episode_return: float
    steps: int
    optimal_return: float
    optimal_steps: int


def rollout(policy: GeneralistPolicy, scenario) -> Episode:
    """One greedy episode of ``policy`` on ``scenario`` in the JAX environment, and value
    iteration's return and path length on the same scenario (a scenario the network cannot
    play refused: ``GeneralistPolicy.check_scenario``)."""
    arrays = TaskArrays(scenario)
    model = arrays.model
    policy.check_scenario(model.task.scenario, model)
    env, params = build([scenario], track='full', layout='grid')
    one = env.scenario(params, 0)
    obs, state = env.reset(jax.random.PRNGKey(0), one)
    phased = policy.model.phased
    grid = data.phased_grid(arrays) if phased else np.asarray(obs.grid)
    logits = policy.cell_logits(grid)
    # per place of the padded grid (phased: layer * cells + cell, the env's place)
    actions = jnp.asarray(logits.argmax(-1).reshape(-1))
    cells = actions.shape[0]

    def body(carry, _):
        state, done, info = carry
        action = actions[state.place % cells]
        _, after, _, step_done, step_info = env.step_env(None, state, action, one)
        keep = lambda new, old: jax.tree_util.tree_map(  # noqa: E731
            lambda a, b: jnp.where(done, b, a), new, old
        )
        return (keep(after, state), done | step_done, keep(step_info, info)), None

    _, _, _, _, info0 = env.step_env(None, state, 0, one)
    limit = int(one.step_limit)
    carry, _ = jax.lax.scan(body, (state, jnp.asarray(False), info0), None, length=limit)
    info = carry[2]
    optimum = value_iteration(model)
    path = follow(model, lambda i: int(optimum.policy[i]))
    return Episode(
        getattr(scenario, 'name', str(scenario)),
        int(info['outcome']),
        float(info['episode_return']),
        int(info['steps']),
        optimum.optimal_return,
        len(path) - 1,
    )


def unseen_scenarios(count: int, options: Options, directory: Path, offset: int = 0):
    """``count`` generated scenarios of the test seed range (a seed not proven is skipped)."""
    out = []
    for seed in data.seeds_of('test', count, offset):
        try:
            out.append(data.scenario_of(seed, options, directory))
        except GenerationError:
            continue
    return out
