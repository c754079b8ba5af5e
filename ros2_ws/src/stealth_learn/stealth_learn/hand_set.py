"""The generalist's hand-set twin: the same network (``vin.Vin``) with the environment's reward
written into its weights instead of learned, the baseline a trained network must beat.

    params, architecture = hand_set_params(architecture, ScenarioReward.of(scenario, goal))
    policy = GeneralistPolicy.hand_set(architecture, ScenarioReward.of(scenario, goal))

Why it is exact: the network's reward head reads, per move, the light on it, whether that
reaches the threshold ("lit"), the node it enters (light, goal, distance to the goal's centre
in tens of lattice steps) and a 3x3 context; its Bellman backups are value iteration's over
the lattice's four moves, V fixed at ``goal_value`` on goal cells. Value iteration's step
(``planners.step_terms``, ``reward.step_outcome``) pays, entering a node d m from the goal
point over a move of light v:

- lit (v >= threshold): detection, terminal, ``-(detection_penalty + detection_distance_weight
  * d)``;
- else on a goal node: success, terminal, ``goal_reward + goal_distance_weight * (radius -
  d)``;
- else ``-(visibility_weight * v + distance_weight * d + time_cost)``.

The hidden layer writes these with ReLUs: the light and the distance as they are, and each
again gated by a flag (``relu(x + GATE * flag - GATE)`` is x where the flag is 1, 0 where it
is 0, for 0 <= x < GATE), so the output is exactly that reward (to float32), ``goal_value`` is
``goal_reward`` and a success is value iteration's. A backup cannot end an episode, so a lit
move also pays the most any place can be worth (``goal_reward + goal_distance_weight *
radius``): it is worth at most the detection's reward, never more than a way that is not seen,
as in value iteration. The distance is the grid's, to the goal cells' centre, not to the goal
point (within a fraction of a step). The convolution is zero: the context adds nothing; so is
the never-sensed input of a network that reads one (``uncertain``): the belief read as known.

``REWARDS``: 'env' (the above; it needs 8 hidden units), and 'dark-steps', the review's second
variant (issue 42): -1 a move, -1e4 a lit one, goal value 0: the shortest way that is not seen.
Written for threshold detection (a probabilistic scenario's reward is an expectation the lit
flag cannot give: refused). Plain numpy: no JAX here.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from stealth_core.reward import RewardWeights

REWARDS = ('env', 'dark-steps')
GATE = 100.0  # > any input it gates: 1000 lattice steps of distance (feature 100), light < 100
DARK_STEP, LIT_STEP = -1.0, -1e4  # the 'dark-steps' variant's rewards
# The reward head's inputs per move (vin.Vin.rewards), before the context's channels.
MOVE_LIGHT, LIT, NODE_LIGHT, GOAL, DISTANCE = range(5)
INPUTS = 5
UNITS = {'env': 8, 'dark-steps': 1}  # hidden units each reward needs


@dataclasses.dataclass(frozen=True)
class ScenarioReward:
    """What the written reward depends on: the scenario's reward weights, its detection
    threshold and mode, the metres of one lattice step and the goal's radius."""

    weights: RewardWeights
    threshold: float
    detection_mode: str
    step_distance: float
    goal_radius: float
    scenario: str = ''  # its name, for the messages

    @classmethod
    def of(cls, scenario, goal: str | None = None) -> ScenarioReward:
        """The reward of ``scenario`` (a ``stealth_core.scenario.Scenario``) at ``goal``
        (default: its default goal)."""
        target = scenario.goals[goal or scenario.default_goal]
        return cls(
            scenario.rewards,
            float(scenario.detection_threshold),
            scenario.detection_mode,
            float(scenario.step_distance),
            float(target.radius),
            scenario.name,
        )


def hand_set_params(architecture: dict, reward: ScenarioReward, kind: str = 'env'):
    """(params tree of numpy float32 arrays, the architecture with the scenario's threshold):
    ``vin.Vin``'s parameters with ``kind``'s reward written in (module docstring). ValueError,
    one line, for an unknown kind, too few hidden units or probabilistic detection."""
    if kind not in REWARDS:
        raise ValueError(f'hand-set reward: expected one of {", ".join(REWARDS)}, got {kind!r}')
    hidden, features = int(architecture['hidden']), int(architecture['features'])
    if hidden < UNITS[kind]:
        raise ValueError(
            f'hand-set reward {kind!r}: needs a reward network of {UNITS[kind]} hidden units '
            f'or more, the architecture has {hidden}'
        )
    if reward.detection_mode != 'threshold':
        raise ValueError(
            f'hand-set reward: scenario {reward.scenario!r} has detection_mode '
            f"{reward.detection_mode!r}; the weights are written for 'threshold' only"
        )
    uncertain = int(architecture.get('uncertain', 0))  # its never-sensed input: weight 0
    hidden_kernel = np.zeros((INPUTS + features + uncertain, hidden), np.float64)
    hidden_bias = np.zeros(hidden, np.float64)
    out = np.zeros(hidden, np.float64)
    if kind == 'dark-steps':
        hidden_kernel[LIT, 0] = 1.0  # h0 = lit
        out[0] = LIT_STEP - DARK_STEP
        out_bias, goal_value = DARK_STEP, 0.0
    else:
        out_bias, goal_value = _env_reward(hidden_kernel, hidden_bias, out, reward)
    params = {
        'context': {
            'kernel': np.zeros((3, 3, 3, features), np.float32),
            'bias': np.zeros(features, np.float32),
        },
        'reward_hidden': {
            'kernel': hidden_kernel.astype(np.float32),
            'bias': hidden_bias.astype(np.float32),
        },
        'reward_out': {
            'kernel': out[:, None].astype(np.float32),
            'bias': np.array([out_bias], np.float32),
        },
        'goal_value': np.array(goal_value, np.float32),
        'scale': np.array(1.0, np.float32),
    }
    # the distance read uncapped: the environment's distance term is exact only so
    written = {k: v for k, v in architecture.items() if k != 'distance_cap'}
    return params, {**written, 'threshold': reward.threshold}


def _env_reward(kernel, bias, out, reward: ScenarioReward) -> tuple[float, float]:
    """Fill the hidden layer and the output weights of the 'env' reward; (output bias, goal
    value). Units: 0 move light, 1 distance, 2 lit, 3 distance if lit, 4 goal and not lit,
    5 distance if goal and not lit, 6 move light if goal and not lit, 7 move light if lit."""
    w = reward.weights
    metres = 10.0 * reward.step_distance  # the distance input is in tens of lattice steps
    kernel[MOVE_LIGHT, 0] = 1.0
    kernel[DISTANCE, 1] = 1.0
    kernel[LIT, 2] = 1.0
    _gate(kernel, bias, 3, DISTANCE, {LIT: 1.0})
    kernel[GOAL, 4], kernel[LIT, 4] = 1.0, -1.0
    _gate(kernel, bias, 5, DISTANCE, {GOAL: 1.0, LIT: -1.0})
    _gate(kernel, bias, 6, MOVE_LIGHT, {GOAL: 1.0, LIT: -1.0})
    _gate(kernel, bias, 7, MOVE_LIGHT, {LIT: 1.0})
    most = w.goal_reward + w.goal_distance_weight * reward.goal_radius  # the most V can be
    # an ordinary step, then what a lit move and a move onto the goal change of it
    out[0], out[1] = -w.visibility_weight, -w.distance_weight * metres
    out[2] = -(w.detection_penalty + most) + w.time_cost
    out[3] = (w.distance_weight - w.detection_distance_weight) * metres
    out[7] = w.visibility_weight
    out[4] = w.goal_distance_weight * reward.goal_radius + w.time_cost
    out[5] = (w.distance_weight - w.goal_distance_weight) * metres
    out[6] = w.visibility_weight
    return -w.time_cost, w.goal_reward


def _gate(kernel, bias, unit: int, value: int, flags: dict[int, float]) -> None:
    """Hidden ``unit`` = relu(input ``value`` + GATE * (sum of the flags' inputs) - GATE)."""
    kernel[value, unit] = 1.0
    for flag, sign in flags.items():
        kernel[flag, unit] = sign * GATE
    bias[unit] = -GATE
