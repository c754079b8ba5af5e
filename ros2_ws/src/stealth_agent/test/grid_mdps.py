"""Hand-made grid MDPs with known optimal values, for the learner tests (not a test module).

A layout is a list of rows, top row first: 'S' start, 'G' goal (terminal), 'L' lit by a
searchlight (terminal, detected), '#' wall (moving into it, or off the grid, stays put),
'.' free. Actions as stealth_env: 0 up (+y), 1 down (-y), 2 left (-x), 3 right (+x).
Observations are float32 [x, y] on a grid of the cell size in metres, like stealth_env's states
(the lattice nodes, each the centre of its state cell), so the learners see what they would see
from the real environment.
"""

from dataclasses import dataclass, field

import numpy as np

MOVES = ((0, 1), (0, -1), (-1, 0), (1, 0))


@dataclass
class GridMDP:
    layout: list[str]
    step_reward: float = -1.0
    goal_reward: float = 10.0
    lit_reward: float = -10.0
    max_steps: int = 200  # the episode ends (terminal, as stealth_env's timeout) after this
    cell: float = 0.5
    cells: dict = field(init=False)
    start: tuple[int, int] = field(init=False)

    def __post_init__(self):
        height = len(self.layout)
        self.cells = {}
        for row, line in enumerate(self.layout):
            for x, char in enumerate(line):
                y = height - 1 - row
                self.cells[(x, y)] = char
                if char == 'S':
                    self.start = (x, y)

    def free(self, cell) -> bool:
        return self.cells.get(cell, '#') != '#'

    def terminal(self, cell) -> bool:
        return self.cells[cell] in 'GL'

    def transition(self, cell, action):
        """(next cell, reward, terminal) of a deterministic move."""
        dx, dy = MOVES[action]
        nxt = (cell[0] + dx, cell[1] + dy)
        if not self.free(nxt):
            nxt = cell
        char = self.cells[nxt]
        if char == 'G':
            return nxt, self.goal_reward, True
        if char == 'L':
            return nxt, self.lit_reward, True
        return nxt, self.step_reward, False

    def observation(self, cell) -> np.ndarray:
        return np.array([cell[0] * self.cell, cell[1] * self.cell], dtype=np.float32)

    def states(self):
        return [c for c in self.cells if self.free(c)]

    def value_iteration(self, gamma: float, tol: float = 1e-13) -> dict:
        """V*(cell) for every free cell (0 at terminal cells)."""
        values = dict.fromkeys(self.states(), 0.0)
        while True:
            delta = 0.0
            for c in values:
                if self.terminal(c):
                    continue
                best = max(self._backup(values, c, a, gamma) for a in range(len(MOVES)))
                delta = max(delta, abs(best - values[c]))
                values[c] = best
            if delta < tol:
                return values

    def _backup(self, values, cell, action, gamma):
        nxt, reward, terminal = self.transition(cell, action)
        return reward + (0.0 if terminal else gamma * values[nxt])

    def optimal_return(self, gamma: float) -> float:
        return self.value_iteration(gamma)[self.start]


def run_episode(agent, mdp: GridMDP, first_reward: float = 0.0):
    """One episode of a ProtocolAgent on the MDP through the rl_msgs protocol."""
    cell = mdp.start
    step = agent.handle(mdp.observation(cell), first_reward, False)
    for t in range(1, mdp.max_steps + 1):
        cell, reward, terminal = mdp.transition(cell, step.action)
        step = agent.handle(mdp.observation(cell), reward, terminal or t == mdp.max_steps)
        if step.result is not None:
            return step.result
    raise AssertionError('episode did not end')


def greedy_return(learner, index, mdp: GridMDP, gamma: float) -> float | None:
    """Discounted return of the greedy policy from the start (lowest-index tie-breaking).

    None when it reaches a state the table has never seen or does not end in max_steps.
    """
    cell, total, discount = mdp.start, 0.0, 1.0
    for _ in range(mdp.max_steps):
        row = index.lookup(mdp.observation(cell))
        if row is None or row >= learner.num_rows:
            return None
        action = int(np.argmax(learner.q[row]))
        cell, reward, terminal = mdp.transition(cell, action)
        total += discount * reward
        discount *= gamma
        if terminal:
            return total
    return None


# Searchlight-flavoured: the short way passes between two lit cells.
STEALTH_GRID = GridMDP(
    [
        '....G',
        '.L#..',
        '...L.',
        '.#...',
        'S....',
    ],
    max_steps=100,
)

# Sutton & Barto's Dyna maze (figure 8.2): reward only at the goal, so values spread slowly.
DYNA_MAZE = GridMDP(
    [
        '.......#G',
        '..#....#.',
        'S.#....#.',
        '..#......',
        '.....#...',
        '.........',
    ],
    step_reward=0.0,
    goal_reward=1.0,
    max_steps=3000,
)
