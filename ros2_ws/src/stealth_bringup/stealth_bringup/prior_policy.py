"""`stealth train --prior floor_plan`: the agent node starts from the floor plan's values. No
rclpy.

The agent node knows states only as the vectors the environment sends; it has no floor plan.
The run has one: before the nodes start, this writes the run's policy file with a row for every
place of the scenario's lattice (its state vector, as the environment sends it) holding
stealth_core.floor_plan_prior's action values (value iteration with every light dark, at the
agent's gamma), and the agent loads it as a resumed run loads its table (load_policy). Its model
is empty, so prioritized sweeping takes every pair as untried and worth that much: the
optimism of the in-process harness (docs/evaluation-and-sweeps.md, the learners), through ROS.
"""

from __future__ import annotations

from pathlib import Path

from stealth_agent.learners import LearnerConfig, canonical_learner_name, make_learner
from stealth_agent.policy_store import save_policy
from stealth_agent.protocol import parse_description
from stealth_agent.state_index import StateIndex
from stealth_core.floor_plan_prior import floor_plan_values
from stealth_core.lattice_model import LatticeModel
from stealth_core.scenario import content_identity
from stealth_core.task import StealthTask


def write_prior_policy(path: Path, scenario, goal: str, agent: dict) -> int:
    """The policy file at ``path``: a table of the floor plan's values for ``agent``'s learner
    (the agent node's parameter values); returns its number of states. ValueError for a
    learner that keeps no table (a policy plugin)."""
    name = canonical_learner_name(agent['agent'])  # ValueError for a plugin or an unknown one
    task = StealthTask(scenario, goal)
    model = LatticeModel.build(task)
    values = floor_plan_values(model, gamma=float(agent['gamma']))
    learner = make_learner(name, model.num_actions, LearnerConfig())
    index = StateIndex()
    for place, state in enumerate(model.states):
        learner.set_initial_row(index.row(state), values[place])
    identity = {
        **parse_description(**task.description(False)).identity(),
        **content_identity(scenario),
    }
    save_policy(path, learner, index, scenario=identity, extra={'prior': 'floor_plan'})
    return len(index)
