"""The environment's side of the RL loop with its agent: the topics of
``stealth_node_kit.rl_contract`` it publishes (the description, states, step info, episode
summaries) and hears (actions, experiment info), and whether an agent is there to be sent a
first state (:func:`stealth_env.episode_flow.agent_connected` over the ROS graph). On the sensed
track (a ``sensed_track.SensedTrack``) the description and every RLStateReward carry what the
robot sensed (its layout: ``stealth_env.sensed_track``); StepInfo keeps the full track's state.
With a ``grid_observation.FullTrackGrid`` (parameter observation_layout grid) the grid goes out
on ``rl_env/observation``, latched as the description is. Track 'full': with the description,
once: every channel but the robot's is fixed, so once is enough and a recording stays small
(the robot's cell is each state's x, y); sent per step it would be ~100 KB a step. With moving
lights it is the phased grid (``FullTrackGrid.phased``: every bin's lights and each step's
light; the robot's layer is each state's phase). Track 'sensed': the belief grid, with the
description (nothing sensed yet: the agent plans on it, compiling, before it takes states)
and whenever what was sensed changes (each episode's first state, then a step that sensed
something new), just before that state, numbered with its episode and step; the state carries
the same sensed light, which is how the agent matches them. Track 'sensed' with moving lights:
the phased grid of what was sensed at each layer (``FullTrackGrid.phased_sensed``), with the
description (nothing sensed) and then before every state but a terminal one, the robot channel
marking that state's (layer, cell) (``FullTrackGrid.with_robot``): it changes at nearly every
step and the state cannot tell when it did not, so it is sent each time and matched by the mark.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy
from stealth_interfaces.msg import (
    EpisodeSummary,
    GridObservation,
    RLAction,
    RLEnvDescription,
    RLExperimentInfo,
    RLStateReward,
    StepInfo,
)
from stealth_node_kit import rl_contract
from stealth_node_kit.endpoints import (
    QUIET_PUBLISHER,
    QUIET_SUBSCRIPTION,
    warn_publisher,
    warn_subscription,
)

from stealth_env.env_messages import (
    description_msg,
    float32,
    grid_observation_msg,
    state_reward_msg,
    step_info_msg,
    summary_msg,
)
from stealth_env.episode_flow import Endpoint, agent_connected

TOPICS = {
    'description': rl_contract.ENV_DESCRIPTION,
    'state': rl_contract.STATE,
    'step_info': rl_contract.STEP_INFO,
    'summary': rl_contract.EPISODE_SUMMARY,
    'observation': rl_contract.OBSERVATION,
    'action': rl_contract.ACTION,
    'experiment_info': rl_contract.EXPERIMENT_INFO,
}


class AgentLink:
    """The RL topics on `node`; `on_action` and `on_experiment_info` get the agent's messages;
    `sensed`: the SensedTrack of track sensed (None: the full track); `grid`: the
    FullTrackGrid to send on rl_env/observation (None: none)."""

    def __init__(self, node, on_action, on_experiment_info, sensed=None, grid=None):
        self.node = node
        self.sensed = sensed
        self.grid = grid
        self._observation_pub = None
        if grid is not None:
            streamed = grid.track == 'sensed' and grid.timed  # a grid before every state
            qos = rl_contract.OBSERVATION_STREAM_QOS if streamed else rl_contract.DESCRIPTION_QOS
            self._observation_pub = node.create_publisher(
                GridObservation, TOPICS['observation'], qos
            )
        self._last_state: list | None = None  # the last sensed state sent (an abort repeats it)
        self._description_pub = node.create_publisher(
            RLEnvDescription, TOPICS['description'], rl_contract.DESCRIPTION_QOS
        )
        self._state_pub = node.create_publisher(
            RLStateReward,
            TOPICS['state'],
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=warn_publisher(
                node.get_logger,
                f'a subscription to {TOPICS["state"]} requests QoS this environment cannot '
                'offer ({policy}): it gets no states; the RL topics are reliable and volatile',
            ),
        )
        self._step_pub = node.create_publisher(
            StepInfo, TOPICS['step_info'], rl_contract.STEP_INFO_QOS,
            event_callbacks=QUIET_PUBLISHER,
        )  # fmt: skip
        self._summary_pub = node.create_publisher(
            EpisodeSummary, TOPICS['summary'], rl_contract.SUMMARY_QOS,
            event_callbacks=QUIET_PUBLISHER,
        )  # fmt: skip
        self._action_sub = node.create_subscription(
            RLAction,
            TOPICS['action'],
            on_action,
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=warn_subscription(
                node.get_logger,
                f'a publisher of {TOPICS["action"]} offers QoS this environment cannot accept '
                '({policy}): its actions never arrive; the RL topics are reliable and volatile',
            ),
        )
        node.create_subscription(
            RLExperimentInfo,
            TOPICS['experiment_info'],
            on_experiment_info,
            rl_contract.LOCKSTEP_QOS,
            event_callbacks=QUIET_SUBSCRIPTION,
        )

    # --- who is there ---------------------------------------------------------------------------

    def action_writers(self) -> int:
        """Publishers of actions (0: the agent went away)."""
        return self._action_sub.get_publisher_count()

    def step_readers(self) -> int:
        return self._step_pub.get_subscription_count()

    def agent_connected(self) -> bool:
        """An agent publishes actions and its state reader is matched (a volatile first state
        published before that would be lost)."""
        if self.action_writers() == 0:
            return False
        graph = self.node
        writers = [
            Endpoint(_node_of(info))
            for info in graph.get_publishers_info_by_topic(self._action_sub.topic_name)
        ]
        readers = [
            Endpoint(
                _node_of(info),
                info.qos_profile.durability != DurabilityPolicy.TRANSIENT_LOCAL,
            )
            for info in graph.get_subscriptions_info_by_topic(self._state_pub.topic_name)
        ]
        return agent_connected(writers, readers, self._state_pub.get_subscription_count())

    # --- publishing -----------------------------------------------------------------------------

    def publish_description(self, fields: dict) -> None:
        if self.sensed is not None:
            fields = self.sensed.description(fields)
        self._description_pub.publish(description_msg(fields))
        if self.grid is None:
            return
        if self.grid.track == 'full':
            self._publish_grid(self.grid.full())
        elif self.grid.timed:  # sensed: nothing sensed yet (the agent plans on it, ready)
            self._publish_grid(self.grid.phased_sensed(self.sensed.sensor.phased))
        else:
            self._publish_grid(self.grid.belief(self.sensed.light, self.sensed.moves))

    def _publish_grid(self, grid, episode: int = 0, step: int = 0) -> None:
        t = self.node.get_clock().now().nanoseconds * 1e-9
        layout, geometry, names = self.grid.layout(), self.grid.geometry, self.grid.channels
        self._observation_pub.publish(
            grid_observation_msg(grid, layout, geometry, t, episode, step, names)
        )

    def _publish_sensed_grid(self, state, episode: int, terminal: bool = False) -> None:
        """The sensed track's grid, before the state it goes with: the belief when it changed;
        the phased grid of what was sensed (moving lights) before every state decided on, the
        robot marked at the state's (layer, cell)."""
        sensed, grid = self.sensed, self.grid
        if grid is None or grid.track != 'sensed':
            return
        if grid.timed:
            if not terminal:
                phased = grid.with_robot(grid.phased_sensed(sensed.sensor.phased), state)
                self._publish_grid(phased, episode, sensed.step)
        elif sensed.changed:
            self._publish_grid(grid.belief(sensed.light, sensed.moves), episode, sensed.step)

    def publish_state(
        self, state, reward: float = 0.0, terminal: bool = False, start=None, episode: int = 0
    ):
        """A first state (reward 0; `start`: the start pose (x, y, yaw); `episode`: its
        number), or an abort's terminal state (reward 0: the last state again)."""
        if self.sensed is not None:
            if start is not None:
                self._last_state = self.sensed.first_state(state, start)
                self._publish_sensed_grid(self._last_state, episode, terminal)
            state = self._last_state
        self._state_pub.publish(state_reward_msg(state, reward, terminal))

    def publish_step(self, report, stamp, truth_known: bool = True, t: float = 0.0) -> None:
        """A step's RLStateReward (`t`: the episode's time of its judgement), and its StepInfo
        while someone subscribes (as the simulator does with its periodic topics: built only
        when wanted)."""
        state = list(report.state)
        reward = float32(report.reward)
        sent = state
        if self.sensed is not None:
            visibility = report.judgement.visibility
            sent = self._last_state = self.sensed.step_state(
                state, report.judged, t, report.step, visibility
            )
            self._publish_sensed_grid(sent, report.episode, report.terminal)
        self._state_pub.publish(state_reward_msg(sent, reward, report.terminal))
        if self._step_pub.get_subscription_count():
            self._step_pub.publish(step_info_msg(report, state, reward, stamp, truth_known))

    def publish_summary(self, summary, stamp) -> None:
        self._summary_pub.publish(summary_msg(summary, stamp))


def _node_of(info) -> str:
    namespace = info.node_namespace.rstrip('/')
    return f'{namespace}/{info.node_name}'
