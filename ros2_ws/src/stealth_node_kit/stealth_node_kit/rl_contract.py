"""The RL contract: every topic and service of the loop between the environment, the agent and
the simulator, with the QoS each end uses, written once.

The environment, the agent, the simulator, the orchestrator's monitor, the recorder's
comparison and the bridge import their names and profiles from here, so a writer and its
readers cannot drift apart (an incompatible QoS pair matches nothing and the loop stalls
silently). Names are relative: a namespace or a remap applies to them as to any other name;
``absolute`` gives the name a recording or the graph shows in the root namespace.

Decisions:

- **Lockstep topics** (states, actions, experiment info): reliable and volatile, with a history
  of LOCKSTEP_DEPTH on both ends. The loop has at most one message in flight (the environment
  publishes a state only after the agent's action for the last one arrived), so the depth never
  fills; it is bounded on purpose, KEEP_LAST and not KEEP_ALL, so that a stalled reader can
  neither block the writer nor grow its memory without end. Both ends used to differ (the
  environment KEEP_ALL, the agent KEEP_LAST 1000); history is not part of QoS matching, and
  the same runs give the same messages either way (the determinism test).
- **The description** is latched (transient local, depth 1): a late agent still gets it; so is
  the grid observation (``OBSERVATION``, sent once: with static lights it never changes). The
  phased grid of what was sensed (moving lights, track sensed) goes out before every state,
  0.35-1.5 MB each: its writer keeps OBSERVATION_STREAM_HISTORY of them (still latched), so a
  recorder that falls a few grids behind gets every one instead of only the latest (with depth 1
  it lost 31 grids of a floorplan-moving run); the agent reads the one marked at its state.
- **Reports** (step info, episode summaries, the agent's episode info) are transient local and
  keep their latest messages, so a reader that (re)joins late, as a respawned recorder,
  monitor or agent does, gets what was published while it was away. Their readers keep all
  that the writer kept (REPORT_READER_QOS).
"""

from __future__ import annotations

import functools

# --- names (every message and service type is stealth_interfaces') --------------------------
ENV_DESCRIPTION = 'rl_env/rl_env_description'  # RLEnvDescription: once per environment
STATE = 'rl_env/rl_state_reward'  # RLStateReward: each state, and the reward leading to it
STEP_INFO = 'rl_env/step_info'  # StepInfo: what happened in each step
EPISODE_SUMMARY = 'rl_env/episode_summary'  # EpisodeSummary: how each episode ended
OBSERVATION = 'rl_env/observation'  # GridObservation: the grid (observation_layout grid)
ACTION = 'rl_agent/rl_action'  # RLAction: the agent's answer to a non-terminal state
EXPERIMENT_INFO = 'rl_agent/rl_experiment_info'  # RLExperimentInfo: one per episode
AGENT_EPISODE_INFO = 'rl_agent/episode_info'  # AgentEpisodeInfo: one per episode
RESTART_EPISODE = 'rl_env/restart_episode'  # RestartEpisode, served by the environment
EXECUTE_MOVE = 'sim/execute_move'  # ExecuteMove, served by the simulator
RESET_ROBOT = 'sim/reset'  # ResetRobot, served by the simulator
# The topics of the loop, in the order it produces them within a step.
RL_TOPICS = (STATE, ACTION, STEP_INFO, EPISODE_SUMMARY, EXPERIMENT_INFO, AGENT_EPISODE_INFO)
SIMULATOR_SERVICES = (EXECUTE_MOVE, RESET_ROBOT)

# --- history depths ------------------------------------------------------------------------
LOCKSTEP_DEPTH = 1000  # one message is in flight at a time; the rest is headroom
# Episode summaries: hours of episodes.
SUMMARY_HISTORY = 2000
# Steps: the 20 s a respawned recorder may take to start and be matched, at 1000 steps/s (a
# run without its recorder goes faster). 2000 held 5 s of a chaos run, and its recorder took 6.
STEP_HISTORY = 20_000
AGENT_REPORT_HISTORY = 1000  # the agent's episode info
# The sensed phased grids (<= 1.5 MB each on the shipped scenarios): a recorder's lag of a few
# steps, bounded so the writer holds at most ~25 MB.
OBSERVATION_STREAM_HISTORY = 16

# --- profiles ------------------------------------------------------------------------------
# (history depth or None for KEEP_ALL, transient local): every profile is reliable.
PROFILES = {
    'LOCKSTEP_QOS': (LOCKSTEP_DEPTH, False),
    'DESCRIPTION_QOS': (1, True),
    'OBSERVATION_STREAM_QOS': (OBSERVATION_STREAM_HISTORY, True),
    'SUMMARY_QOS': (SUMMARY_HISTORY, True),
    'STEP_INFO_QOS': (STEP_HISTORY, True),
    'AGENT_EPISODE_INFO_QOS': (AGENT_REPORT_HISTORY, True),
    # Every reader of a report: all the writer kept, delivered to a reader that joins late.
    'REPORT_READER_QOS': (None, True),
}


@functools.cache
def __getattr__(name: str):
    """The rclpy QoSProfile of PROFILES[name], built on first use: the names above stay
    importable without rclpy (by the parameter tables and the recording comparison)."""
    if name not in PROFILES:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    depth, kept = PROFILES[name]
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if depth is None else HistoryPolicy.KEEP_LAST,
        depth=depth or 0,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if kept else DurabilityPolicy.VOLATILE,
    )


def absolute(name: str) -> str:
    """The name as the graph and a recording show it in the root namespace."""
    return name if name.startswith('/') else '/' + name
