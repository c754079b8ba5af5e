"""What the floor plan alone says a state-action is worth: the prior that prioritized sweeping's
optimism starts from in-process. No rclpy.

The robot crosses a *known* floor plan; only the lights are unknown to a learner. Value
iteration on the scenario's lattice model with every light dark (no detection, no exposure)
gives each place and action the best return the walls allow. No light can add to a return (a
detection ends the episode with a penalty, exposure costs), so this is an upper bound on the
true action value everywhere: optimism that is still *admissible*, as an A* heuristic is. A
learner whose untried pairs start there (instead of at one constant, the goal reward) still
tries every pair that could lie on a cheaper route than the best it knows, and so still
settles on the optimum, but no longer tries the pairs the floor plan already rules out: those
leading away from the goal. Starting Q at a potential is potential-based shaping (Wiewiora,
"Potential-based shaping and Q-value initialization are equivalent", JAIR 19, 2003), so the
optimal policy is unchanged.

Measured with bench/bench_learners.py (docs/evaluation-and-sweeps.md, the learners): on map1
the first goal came at episodes 51-55 with the constant, after trying about 45 lit moves once
each; with the floor plan the greedy policy met the criterion from episode 40.
"""

from __future__ import annotations

from collections.abc import Callable
import dataclasses

import numpy as np

from stealth_core.lattice_model import LatticeModel
from stealth_core.path_scores import OPTIMUM_GAMMA
from stealth_core.planners import value_iteration

# The priors a harness run may start its table from (RunSpec.params 'prior').
PRIORS = ('floor_plan', 'none')


def dark_model(model: LatticeModel) -> LatticeModel:
    """The same lattice, walls, goal and rewards with every light dark."""
    return dataclasses.replace(
        model,
        step_visibility=np.zeros_like(model.step_visibility),
        visibility=np.zeros_like(model.visibility),
    )


def floor_plan_values(model: LatticeModel, gamma: float = OPTIMUM_GAMMA) -> np.ndarray:
    """(places, actions): value iteration's action values with the lights dark."""
    return value_iteration(dark_model(model), gamma=gamma).q


def floor_plan_prior(
    model: LatticeModel, gamma: float = OPTIMUM_GAMMA
) -> Callable[[np.ndarray], np.ndarray | None]:
    """The prior of a state vector (the environment's, as the model's ``states`` hold them):
    its place's action values with the lights dark, or None for a state not in the model."""
    values = floor_plan_values(model, gamma)
    place_of = {tuple(state.tolist()): place for place, state in enumerate(model.states)}

    def prior(state: np.ndarray) -> np.ndarray | None:
        place = place_of.get(tuple(np.asarray(state, dtype=np.float32).tolist()))
        return None if place is None else values[place].copy()

    return prior
