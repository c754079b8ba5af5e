"""The learned policy as a planner: a tabular policy saved by ``stealth train``, followed by its
greedy actions on the move lattice (no rclpy).

A policy is learned on one scenario's map and lights; it is used only on the same content (the
grid and lights SHA-256s it carries, ``stealth_core.scenario.content_identity``), with the same
actions and state features. Its states are the task's (``StealthTask.state_of`` at each place
of the lattice model); ties between maximal actions go to the first, as value iteration's
greedy policy (the harness's greedy rollouts break them at random with a seed).
"""

from __future__ import annotations

import numpy as np
from stealth_agent.policy_store import PolicyFileError, SavedPolicy, load_policy
from stealth_core.scenario import content_identity

from stealth_nav2.plan_errors import PlanError

CONTENT = {'grid_sha256': 'map', 'lights_sha256': 'lights'}


def read_policy(path: str) -> SavedPolicy:
    """The policy file, or PlanError INVALID_PLANNER naming the file and the problem."""
    try:
        return load_policy(path)
    except PolicyFileError as error:
        raise PlanError('INVALID_PLANNER', f'planner policy: {error}') from None


def check_policy_fits(policy: SavedPolicy | None, scenario, model) -> None:
    """PlanError INVALID_PLANNER unless the policy was learned on this scene's content, with
    this task's actions and state length."""
    if policy is None:
        raise PlanError(
            'INVALID_PLANNER',
            'planner policy: no policy file; start the planner server with '
            '-p policy_file:=<policy.npz> (saved by stealth train)',
        )
    if scenario.name == 'scene':
        raise PlanError(
            'INVALID_PLANNER',
            f'planner policy: {policy.path} needs the scenario it was trained on (its states '
            'count from the scenario start); start the planner server with -p scenario:=<file>',
        )
    saved, now = policy.scenario, content_identity(scenario)
    if not all(saved.get(key) for key in CONTENT):
        raise PlanError(
            'INVALID_PLANNER',
            f'planner policy: {policy.path} records no map or lights SHA-256 (saved before '
            'policies did): cannot tell whether it was learned on this scene; train it again',
        )
    differ = [what for key, what in CONTENT.items() if saved[key] != now[key]]
    if differ:
        raise PlanError(
            'INVALID_PLANNER',
            f'planner policy: {policy.path} was learned on {" and ".join(differ)} other than '
            f'scenario {scenario.name!r} has ({saved.get("title", "no title")}); give the '
            'scenario it was trained on, or train a policy on this one',
        )
    actions, dim = model.num_actions, model.states.shape[1]
    problems = []
    if policy.learner.num_actions != actions:
        problems.append(f'{policy.learner.num_actions} actions, the task has {actions}')
    if policy.index.dim is not None and policy.index.dim != dim:
        problems.append(f'states of {policy.index.dim} features, the task has {dim}')
    if problems:
        raise PlanError(
            'INVALID_PLANNER', f'planner policy: {policy.path} does not fit: {"; ".join(problems)}'
        )


def greedy_actions(policy: SavedPolicy | None, scenario, model) -> np.ndarray:
    """(places,) the policy's greedy action at each place of the model, -1 where it never saw
    the state (the path stops there, short of the goal)."""
    check_policy_fits(policy, scenario, model)
    learner = policy.learner
    actions = np.full(model.size, -1, dtype=np.int64)
    for place, state in enumerate(model.states):
        row = policy.index.lookup(state)
        if row is not None and row < learner.num_rows:
            actions[place] = learner.greedy_action(row)  # ties: the first, every time
    return actions
