"""The default episode budget of `stealth train`: it follows the scenario's state count. No rclpy.

A tabular learner has to try each (state, action) it may need, so the episodes a run takes grow
with their number: the places (lattice nodes x the phase bins of moving lights x the headings of
exposure) times the actions. A fixed budget sized for the default scenario was 8 times too small
where lights move (simple-maze-moving has 8 times simple-maze's places; Dyna-Q needed 1,125
episodes there against its budget of 400). The budget is an upper bound: a run stops earlier
once its greedy policy reaches the goal --success-streak times in a row.
"""

from __future__ import annotations

from stealth_bringup.run_arguments import DEFAULT_EPISODES

# One episode per this many state-actions: simple-maze (603 nodes, 4 actions) gets its 400.
STATE_ACTIONS_PER_EPISODE = 6


def state_actions(scenario, goal: str) -> int:
    """(state, action) pairs of a scenario's table: reachable-or-not lattice nodes x phase bins
    x headings x actions, as the environment's state grid keys them."""
    from stealth_core.move_lattice import MoveLattice
    from stealth_core.task import StealthTask

    task = StealthTask(scenario, goal)
    nodes = sum(1 for _ in MoveLattice.from_scenario(scenario).valid_nodes())
    return nodes * task.cycle_bins * task.headings * task.num_actions


def budget_for(pairs: int) -> int:
    """The budget for a table of `pairs` state-actions: one episode per
    STATE_ACTIONS_PER_EPISODE, rounded to hundreds, never below DEFAULT_EPISODES."""
    return max(DEFAULT_EPISODES, 100 * round(pairs / STATE_ACTIONS_PER_EPISODE / 100))


def default_episode_budget(scenario, goal: str) -> tuple[int, int]:
    """(episode budget, state-actions) of a scenario and goal."""
    pairs = state_actions(scenario, goal)
    return budget_for(pairs), pairs
