"""The generalist's network: a value-iteration network (Tamar et al., NeurIPS 2016) over the
grid observation of ``jax_env`` (layout 'grid', ``obs_layout.CHANNELS``), lights known.

    model = Vin(iterations=200)
    params = model.init(key, grid[None])             # grid: (rows, cols, 7), any size
    logits = model.apply(params, grid[None])          # (1, actions): the robot's cell's
    q = model.apply(params, grid[None], method=Vin.q_map)   # (1, rows, cols, actions)

Why this shape: a building the policy has never seen is a new grid, so the network is fully
convolutional (any rows x cols) and plans instead of memorising: a learned reward map from the
light field feeds ``iterations`` Bellman backups over the lattice's four moves, and the
decision is the attention on the robot's cell (its Q values are the logits).

- **Reward** (learned): per cell and move, a small MLP of the move's features (the light on
  the move, whether that reaches the detection threshold, the light of the node entered,
  whether it is the goal, its distance to the goal's centre: the reward's distance term) and
  the cell's
  3x3 neighbourhood (a 3x3 convolution over free, goal and node light) gives R_a.
- **Transition**: the lattice's moves as shifts of the value map (0 up: row + 1, 1 down, 2 left:
  col - 1, 3 right, ``planners.PERPENDICULAR``'s numbering); a move that does not exist (light
  -2 on it: a wall) is masked out. The four shifts are VIN's transition kernels, fixed to the
  lattice rather than learned, so the recurrence stays exact over hundreds of iterations.
- **Value**: V_0 = 0; V_{k+1} = G on goal cells (G learned), max_a (R_a + V_k(after a)) on
  free cells, ``iterations`` times in training (the weights are tied, so the count is free);
  at decision time (``q_and_backups``) at least as many and then on to the fixed point (no
  more than a horizon, where one is given), so a covert path longer than training's horizon
  is still found.
- **Decision**: logits = scale * Q(robot's cell) (scale learned), masked moves at -1e9.

**Moving lights** (``layers`` > 1): the same network over the lattice model's time
expansion (``stealth_core.lattice_model``): the value map is (phase layer, row, col), a step
from layer t (a move or the wait, blocked or not) arrives at layer (t + ``advance``) mod
``layers`` (``advance``: the timing's ``bins_per_step``), and the fifth action waits in place.
Its input is the phased grid, (B, layers, R, C, 12): at each layer the grid of that layer's
lights (``CHANNELS``; the robot channel 1 only at the robot's layer and cell: the phase is read
there) and the step channels (``stealth_core.grid_observation.STEP_CHANNELS``), the light each
step from there is judged on (the lattice model's ``step_visibility``, exactly, -2 where the
step does not exist: a wall or a blocked move, which only waits). The reward MLP reads, per
layer and action, that step light, whether it is lit, the node light of the layer it arrives
at, the goal and distance entered and the layer's context, with the same weights as above:
one layer (so no wait) is exactly the static network (its step light the grid's move
channels), so the static weights are these weights.

**Lights sensed** (``uncertain``): the reward MLP reads one more input per step, last, after
the context: whether the light of the node it enters, at the layer it arrives at, was never
sensed (the grid's age channel, 1 there: ``belief.believed_phased`` marks it; on a lights-known
grid it is 0 everywhere). With that input's weights at 0 it is the network above, so the
hand-set twin is unchanged; a trained network can price what it has not seen.

**Distance cap** (``distance_cap`` C > 0, tens of lattice steps): the distance input is read as
at most C. A reward learned on 20-30 m buildings makes a dark step's cost grow with its goal
distance while a lit step's stays put, so far from the goal on larger buildings a lit step
became cheap (docs/generalist.md); capped, no cell is farther than training showed. 0: as is
(the hand-set twin reads it uncapped: the environment's distance term is exact only so).
"""

from __future__ import annotations

from stealth_learn.jax_deps import jax, jnp, nn
from stealth_learn.obs_layout import CHANNELS, PHASED_CHANNELS

NUM_MOVES = 4  # up, down, left, right: static lights without exposure have no wait or turns
WAIT = 4  # the fifth action where lights move (``stealth_core.task.WAIT``)
NO_MOVE = -2.0  # obs_layout: the light where no node or move is
MASKED = -1e9
FREE, ROBOT, GOAL, LIGHT, MOVE_UP, MOVE_RIGHT, AGE = range(7)


def _shift(array, action: int, fill):
    """``array`` (..., rows, cols) seen from each cell's neighbour after ``action``: out[r, c] =
    array[r + 1, c] for up, [r - 1, c] down, [r, c - 1] left, [r, c + 1] right; ``fill``
    beyond the edge."""
    pad = [(0, 0)] * (array.ndim - 2)
    if action == 0:
        return jnp.pad(array[..., 1:, :], pad + [(0, 1), (0, 0)], constant_values=fill)
    if action == 1:
        return jnp.pad(array[..., :-1, :], pad + [(1, 0), (0, 0)], constant_values=fill)
    if action == 2:
        return jnp.pad(array[..., :, :-1], pad + [(0, 0), (1, 0)], constant_values=fill)
    return jnp.pad(array[..., :, 1:], pad + [(0, 0), (0, 1)], constant_values=fill)


def move_features(grid):
    """(light on each move (B, R, C, 4), the move exists (B, R, C, 4)) from the grid's node and
    move channels: up and right are the grid's own, down and left the neighbour's up / right."""
    up, right = grid[..., MOVE_UP], grid[..., MOVE_RIGHT]
    lights = jnp.stack([up, _shift(up, 1, NO_MOVE), _shift(right, 2, NO_MOVE), right], axis=-1)
    return lights, lights > NO_MOVE + 0.5


def goal_distance(goal):
    """(B, R, C) each cell's distance to the goal cells' centre (tens of lattice steps): the
    reward's distance term (``reward.step_reward``) that no local feature gives."""
    rows = jnp.arange(goal.shape[-2], dtype=jnp.float32)[:, None]
    cols = jnp.arange(goal.shape[-1], dtype=jnp.float32)[None, :]
    total = jnp.maximum(goal.sum(axis=(-2, -1)), 1.0)[..., None, None]
    centre_row = (goal * rows).sum(axis=(-2, -1))[..., None, None] / total
    centre_col = (goal * cols).sum(axis=(-2, -1))[..., None, None] / total
    return jnp.hypot(rows - centre_row, cols - centre_col) / 10.0


class Vin(nn.Module):
    """See the module docstring. ``iterations``: Bellman backups; ``hidden``: the reward MLP's
    width; ``features``: the 3x3 convolution's channels; ``threshold``: the detection threshold
    of the scenarios it is for (the generator's ``THRESHOLD``), a fixed input feature;
    ``layers``, ``advance``: the phase layers of moving lights and the layers a step advances
    (1, 0: static lights, the static grid as input; more layers add the wait action);
    ``uncertain``: 1 to read the never-sensed input of the sensed track; ``distance_cap``:
    the most distance the reward reads, tens of lattice steps (0: uncapped);
    ``gradient_backups``: in training, only the last N backups are differentiated (the values
    before them held fixed: truncated backpropagation through the recurrence, as for an RNN;
    the reward still gets every cell's gradient through them), for reinforcement learning's
    many forward-and-backward passes (``ppo``); 0 differentiates all. Decisions and values are
    the same either way; it is not stored in a weights file."""

    iterations: int = 200
    hidden: int = 32
    features: int = 8
    threshold: float = 0.3
    layers: int = 1
    advance: int = 0
    uncertain: int = 0  # 1: the never-sensed input (module docstring)
    distance_cap: float = 0.0  # tens of lattice steps; 0: uncapped (module docstring)
    gradient_backups: int = 0  # training only: differentiate the last N backups (0: all)

    @property
    def num_actions(self) -> int:
        return NUM_MOVES + int(self.phased)

    @property
    def phased(self) -> bool:
        """Whether the input is the phased grid (moving lights) rather than the static grid."""
        return self.layers > 1

    def grid_shape(self, rows: int, cols: int) -> tuple[int, ...]:
        """The shape of one grid this network reads (no batch axis): (R, C, 7), or the phased
        grid's (L, R, C, 12)."""
        if self.phased:
            return (self.layers, rows, cols, len(PHASED_CHANNELS))
        return (rows, cols, len(CHANNELS))

    def setup(self):
        self.context = nn.Conv(self.features, (3, 3), padding='SAME', name='context')
        self.reward_hidden = nn.Dense(self.hidden, name='reward_hidden')
        self.reward_out = nn.Dense(1, name='reward_out')
        self.goal_value = self.param('goal_value', nn.initializers.normal(1.0), ())
        self.scale = self.param('scale', nn.initializers.ones, ())

    def inputs(self, x):
        """(grid (B, L, R, C, 7), step light (B, L, R, C, A), the step exists (same)) of the
        static grid (B, R, C, 7) or the phased grid (B, L, R, C, 12); ValueError for a shape
        this network does not read."""
        x = jnp.asarray(x, jnp.float32)
        if not self.phased:
            if x.ndim != 4 or x.shape[-1] != len(CHANNELS):
                raise ValueError(f'static network: expected a grid (B, R, C, 7), got {x.shape}')
            lights, exists = move_features(x)
            return x[:, None], lights[:, None], exists[:, None]
        channels = len(CHANNELS) + self.num_actions
        if x.ndim != 5 or x.shape[1] != self.layers or x.shape[-1] != channels:
            raise ValueError(
                f'time-aware network ({self.layers} phase layers): expected a phased grid '
                f'(B, {self.layers}, R, C, {channels}), got {x.shape}'
            )
        lights = x[..., len(CHANNELS) :]
        return x[..., : len(CHANNELS)], lights, lights > NO_MOVE + 0.5

    def _after(self, array, action: int, fill):
        """``array`` (B, L, R, C) as each step arrives in it: the layer ``advance`` on, the
        neighbour the move goes to (the wait: the cell itself)."""
        arrived = jnp.roll(array, -self.advance, axis=1) if self.advance else array
        return arrived if action == WAIT else _shift(arrived, action, fill)

    def rewards(self, x):
        """The learned reward of each move from each cell, (B, R, C, 4) of a static grid, or
        of each step from each cell and layer, (B, L, R, C, A), of a phased one."""
        rewards = self._rewards(*self.inputs(x))
        return rewards if self.phased else rewards[:, 0]

    def _rewards(self, grid, lights, exists):
        """(B, L, R, C, A) the learned reward of each step from each cell at each layer."""
        free, goal, light = grid[..., FREE], grid[..., GOAL], grid[..., LIGHT]
        node_light = jnp.where(free > 0.5, light, 0.0)
        context = nn.relu(self.context(jnp.stack([free, goal, node_light], axis=-1)))
        distance = goal_distance(goal)
        if self.distance_cap > 0:
            distance = jnp.minimum(distance, self.distance_cap)
        per_action = []
        for action in range(self.num_actions):
            entered = jnp.stack(
                [
                    jnp.where(exists[..., action], lights[..., action], 0.0),
                    (lights[..., action] >= self.threshold).astype(jnp.float32),
                    self._after(node_light, action, 0.0),
                    self._after(goal, action, 0.0),
                    self._after(distance, action, 0.0),
                ],
                axis=-1,
            )
            parts = [entered, context]
            if self.uncertain:
                unknown = (grid[..., AGE] > 0.5).astype(jnp.float32)
                parts.append(self._after(unknown, action, 0.0)[..., None])
            per_action.append(jnp.concatenate(parts, axis=-1))
        stacked = jnp.stack(per_action, axis=-2)  # (B, L, R, C, A, 5 + features [+ 1])
        hidden = nn.relu(self.reward_hidden(stacked))
        return self.reward_out(hidden)[..., 0]

    def q_map(self, x, until_fixed: bool = False):
        """The action values after ``iterations`` backups, masked steps MASKED: (B, R, C, 4)
        of a static grid, (B, L, R, C, A) of a phased one. ``until_fixed`` (decision time):
        then on until the values are a fixed point (``fixed_point``)."""
        return self.q_and_backups(x, until_fixed)[0]

    def q_and_backups(self, x, until_fixed: bool = False, horizon=None):
        """(``q_map``'s values, the backups made: () int32). Value iteration's own stopping
        rule at decision time: after the ``iterations`` backups (the floor: the horizon the
        weights were evaluated with), go on while any value of a node the goal can be reached
        from still changes (a closed room's falls by its step cost forever and decides
        nothing), at most as many more as the time-expanded lattice has free nodes (layers x
        free cells: Bellman-Ford's bound, reached only if the learned reward pays for a
        cycle). A building whose covert path is longer than ``iterations`` gets the backups it
        needs; more backups cannot change a fixed point. ``horizon`` (() int; None: no cap)
        caps the backups at max(``iterations``, ``horizon``): k backups give the best k-step
        return, so with the episode's step limit a reward that pays for a cycle (an untrained
        network's) stops there instead of at Bellman-Ford's bound. Not a free cut for others:
        where the belief leaves no dark way to the goal, the values fall on towards the fixed
        point long after, and near-tied moves there can order otherwise. Training keeps the
        fixed count (``lax.scan``: differentiable)."""
        grid, lights, exists = self.inputs(x)
        rewards = self._rewards(grid, lights, exists)
        free, goal = grid[..., FREE] > 0.5, grid[..., GOAL] > 0.5
        goal_value = self.goal_value

        def backup(values):
            after = [self._after(values, a, 0.0) for a in range(self.num_actions)]
            return jnp.where(exists, rewards + jnp.stack(after, axis=-1), MASKED)

        def iterate(values, _=None):
            best = backup(values).max(axis=-1)
            return jnp.where(goal, goal_value, jnp.where(free, best, 0.0)), None

        values = jnp.where(goal, goal_value, 0.0)
        tail = self.gradient_backups
        if 0 < tail < self.iterations:  # truncated backpropagation (the class docstring)
            values, _ = jax.lax.scan(iterate, values, None, length=self.iterations - tail)
            values, _ = jax.lax.scan(iterate, jax.lax.stop_gradient(values), None, length=tail)
        else:
            values, _ = jax.lax.scan(iterate, values, None, length=self.iterations)
        backups = jnp.asarray(self.iterations, jnp.int32)
        if until_fixed:

            def leads_on(mask):
                after = [self._after(mask, a, False) for a in range(self.num_actions)]
                return (jnp.stack(after, axis=-1) & exists).any(axis=-1)

            compared = reachable(goal, free, leads_on)
            bound = backups + free.sum().astype(jnp.int32)
            if horizon is not None:
                bound = jnp.minimum(bound, jnp.maximum(backups, jnp.asarray(horizon, jnp.int32)))
            values, backups = fixed_point(
                lambda v: iterate(v)[0], values, backups, compared, bound
            )
        q = backup(values)
        return (q if self.phased else q[:, 0]), backups

    def __call__(self, x):
        """(B, A) logits at the robot's cell (and layer: the robot channel)."""
        q = self.q_map(x)
        robot = jnp.asarray(x, jnp.float32)[..., ROBOT]
        # phased: the robot channel is 1 at its layer and cell only, so the sum reads both
        at_robot = jnp.einsum('blrc,blrca->ba' if self.phased else 'brc,brca->ba', robot, q)
        return jnp.where(at_robot <= MASKED / 2, MASKED, self.scale * at_robot)


def reachable(start, free, leads_on):
    """(B, L, R, C) bool: ``start`` and every free node with a path of steps into it
    (``leads_on(mask)``: the nodes with a step into ``mask``)."""

    def grow(carry):
        mask, _ = carry
        grown = mask | (free & leads_on(mask))
        return grown, jnp.any(grown != mask)

    return jax.lax.while_loop(lambda carry: carry[1], grow, (start, jnp.asarray(True)))[0]


def fixed_point(iterate, values, backups, compared, bound):
    """(values, backups) after applying ``iterate`` until no value on ``compared`` changes, at
    most ``bound`` backups in all (``Vin.q_and_backups``)."""

    def changing(carry):
        _, count, changed = carry
        return changed & (count < bound)

    def step(carry):
        values, count, _ = carry
        after = iterate(values)
        return after, count + 1, jnp.any((after != values) & compared)

    start = (values, backups, jnp.asarray(True))
    values, backups, _ = jax.lax.while_loop(changing, step, start)
    return values, backups


def logits_of_cells(model: Vin, variables, grid):
    """Every cell's logits at once, (B, R, C, 4) or phased (B, L, R, C, A) (the attention at
    every cell and layer: what the imitation loss reads), after the fixed count of backups."""
    return logits_of_values(variables, model.apply(variables, grid, method=Vin.q_map))


def logits_of_values(variables, q):
    """The logits of action values ``q``: scale * q, masked steps MASKED (``Vin.__call__``'s
    rule at every cell)."""
    return jnp.where(q <= MASKED / 2, MASKED, variables['params']['scale'] * q)
