"""The agent's messages, to and from the plain-Python core (no rclpy).

What the agent reads (RLEnvDescription; GridObservation for a policy plugin; EpisodeSummary's
outcome codes; the DDS sequence numbers of the states) and what it publishes at the end of an
episode (RLExperimentInfo, AgentEpisodeInfo) and the light model's belief (OccupancyGrid), so
that the node only moves messages.
"""

import dataclasses

from nav_msgs.msg import OccupancyGrid
import numpy as np
from stealth_core.light_belief_map import BeliefGrid
from stealth_interfaces.msg import (
    AgentEpisodeInfo,
    EpisodeSummary,
    RLEnvDescription,
    RLExperimentInfo,
)
from stealth_node_kit.conversions import grid_msg

from .grid_agent import ObservedGrid
from .learners import TabularLearner
from .protocol import BadInputError, Ending, EnvDescription, EpisodeResult, parse_description

# A table keyed on longer states would hold a long key per visited state (the environment's
# sensed track sends thousands of features, nearly all new at each step).
MAX_KEYED_FEATURES = 256
FLOAT32_MAX = float(np.finfo(np.float32).max)
OUTCOME_NAMES = {
    EpisodeSummary.SUCCESS: 'success',
    EpisodeSummary.DETECTED: 'detected',
    EpisodeSummary.TIMEOUT: 'timeout',
    EpisodeSummary.ABORTED: 'aborted',
}
# How the environment's outcome is learned (an unknown outcome: as rl_msgs says, terminal).
OUTCOME_ENDINGS = {
    EpisodeSummary.SUCCESS: Ending.TERMINATED,
    EpisodeSummary.DETECTED: Ending.TERMINATED,
    EpisodeSummary.TIMEOUT: Ending.TRUNCATED,
    EpisodeSummary.ABORTED: Ending.ABORTED,
}
ENDING_FIELDS = {
    Ending.TERMINATED: AgentEpisodeInfo.END_TERMINAL,
    Ending.TRUNCATED: AgentEpisodeInfo.END_TRUNCATED,
    Ending.ABORTED: AgentEpisodeInfo.END_ABORTED,
}


def description_from_msg(msg: RLEnvDescription) -> EnvDescription:
    """The checked description; BadInputError when unusable."""
    return parse_description(
        msg.num_actions,
        msg.num_states,
        msg.min_state_range,
        msg.max_state_range,
        msg.max_reward,
        msg.reward_range,
        msg.stochastic,
        msg.episodic,
        msg.title,
    )


def keyed_description(description: EnvDescription, features: int) -> EnvDescription:
    """The description as the table sees it: the ranges of the state's first `features`
    features (0: all; agent parameter state_features). BadInputError for a state too long to
    key a table on."""
    if features:
        return dataclasses.replace(
            description,
            min_state_range=description.min_state_range[:features],
            max_state_range=description.max_state_range[:features],
        )
    length = len(description.min_state_range)
    if length > MAX_KEYED_FEATURES:
        raise BadInputError(
            f'environment description: the state has {length} features (the sensed track?), '
            f'more than a table can key on ({MAX_KEYED_FEATURES}); set the agent parameter '
            'state_features to the leading features to key on (stealth train does for '
            'environment.track sensed)'
        )
    return description


def grid_from_msg(msg) -> ObservedGrid:
    """A GridObservation as numpy: (rows, cols, channels), or (layers, rows, cols, channels)
    for a phased grid (layers > 1); BadInputError naming the field that does not fit."""
    layers = int(msg.layers)
    shape = (int(msg.rows), int(msg.cols), int(msg.channels))
    if layers < 1:
        raise BadInputError(f'GridObservation: layers {layers}, expected >= 1 (1: no phases)')
    data = np.frombuffer(msg.data, dtype=np.float32) if len(msg.data) else np.zeros(0, np.float32)
    if 0 in shape or data.size != layers * shape[0] * shape[1] * shape[2]:
        raise BadInputError(
            f'GridObservation: data has {data.size} values, layers x rows x cols x channels = '
            f'{layers} x {shape[0]} x {shape[1]} x {shape[2]} expected'
        )
    geometry = (float(msg.resolution), float(msg.origin.x), float(msg.origin.y))
    if not (geometry[0] > 0 and all(np.isfinite(geometry))):
        raise BadInputError(f'GridObservation: resolution {geometry[0]} must be > 0 (m)')
    if layers > 1:
        shape = (layers, *shape)
    return ObservedGrid(str(msg.layout), data.reshape(shape).copy(), geometry, int(msg.step))


def keyed_state(state, features: int):
    """The part of a state the table keys on (state_features; 0: all of it)."""
    return state[:features] if features else state


def outcome_name(outcome: int) -> str:
    """The progress log's name of an EpisodeSummary outcome."""
    return OUTCOME_NAMES.get(outcome, f'outcome {outcome}')


def outcome_ending(outcome: int) -> Ending:
    """How an episode with this EpisodeSummary outcome is learned."""
    return OUTCOME_ENDINGS.get(outcome, Ending.TERMINATED)


def ending_of(result: EpisodeResult) -> Ending:
    if result.aborted:
        return Ending.ABORTED
    return Ending.TRUNCATED if result.truncated else Ending.TERMINATED


def reported_reward(result: EpisodeResult) -> float:
    """The episode's return as the messages carry it (float32: clipped to its range)."""
    return float(np.clip(result.reward, -FLOAT32_MAX, FLOAT32_MAX))


def experiment_info(result: EpisodeResult) -> RLExperimentInfo:
    """rl_msgs' report of a finished episode."""
    return RLExperimentInfo(
        episode_number=result.episode,
        episode_reward=reported_reward(result),
        number_actions=result.actions,
    )


def episode_info(
    result: EpisodeResult, learner: TabularLearner, table_rows: int
) -> AgentEpisodeInfo:
    """The agent's own report of a finished episode (the caller stamps its header)."""
    return AgentEpisodeInfo(
        episode=result.episode,
        greedy=not result.learning,
        epsilon=float(result.epsilon),
        alpha=float(learner.alpha) if result.learning else 0.0,
        total_reward=reported_reward(result),
        steps=result.actions,
        learner_episodes=learner.episodes,
        learner_updates=learner.updates,
        table_states=table_rows,
        ending=ENDING_FIELDS[ending_of(result)],
    )


class StateWriters:
    """Tells a restarted environment by the DDS sequence numbers of its states: a writer
    numbers its messages from 1, so a number that does not grow is a new writer, whose states
    must not continue the old one's episode."""

    def __init__(self):
        self.last: int | None = None  # of the last state (None: the middleware gives none)

    def new_writer(self, sequence: int | None) -> bool:
        """Whether this state comes from another writer than the last one."""
        if sequence is None:
            return False
        last, self.last = self.last, sequence
        return last is not None and sequence <= last


def belief_msgs(grid: BeliefGrid, t: float) -> tuple[OccupancyGrid, OccupancyGrid]:
    """The light model's belief as (most likely field, uncertain places), stamped t (s), on the
    map frame's grid of ``grid`` (``stealth_core.light_belief_map``)."""
    return tuple(
        grid_msg(levels, grid.resolution, grid.origin, t)
        for levels in (grid.likely, grid.uncertain)
    )
