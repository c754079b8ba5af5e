"""System tests of stealth_env's env_node: the real simulator and environment as processes on
a private domain, driven over DDS by a scripted agent living in the test process."""

import dataclasses
import math
import os
import re
import signal
import time

from nav_msgs.msg import OccupancyGrid
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from ros_support import REPO_ROOT, SpinningNode
from stealth_core import exposure
from stealth_core.gym_env import lattice_model
from stealth_core.move_lattice import ACTIONS
from stealth_core.planners import dark_path
from stealth_core.scenario import find_scenario, load_scenario
from stealth_core.task import StealthTask
from stealth_core.visibility import visibility_field
from stealth_env.markers import visibility_levels
from stealth_interfaces.msg import (
    EpisodeSummary,
    RLAction,
    RLEnvDescription,
    RLExperimentInfo,
    RLStateReward,
    SearchlightArray,
    StepInfo,
)
from stealth_interfaces.srv import RestartEpisode
from visualization_msgs.msg import Marker, MarkerArray
import yaml

SIM_NODE = REPO_ROOT / 'ros2_ws/install/stealth_sim/lib/stealth_sim/sim_node'
ENV_NODE = REPO_ROOT / 'ros2_ws/install/stealth_env/lib/stealth_env/env_node'
RL_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
UP, DOWN, LEFT, RIGHT, WAIT = range(5)
SCENARIO = 'simple-maze'  # start (1.5, 1.5); easy goal up the west side, round a light
# The cheapest simulator that still closes the loop: big physics steps, fast robot, a tiny
# filter (what the lossless and speed runs need; localisation is poor, which they ignore).
FAST_SIM = {
    'physics_dt': 0.1,
    'particles': 10,
    'laser_beams': 8,
    'max_linear_speed': 5.0,
    'max_angular_speed': 10.0,
    'max_linear_accel': 20.0,
    'max_angular_accel': 50.0,
}
LOSSLESS_STEPS = 10_000


def covert_actions(scenario, goal: str) -> list[int]:
    """The dark path's moves from the start to the goal point itself (no node it visits is
    lit). Its last but one node lies on the goal's radius: the real robot may end there."""
    model = lattice_model(scenario, goal)
    model = dataclasses.replace(model, goal=model.distance < 1e-9)
    assert model.goal.any(), 'the goal point is not a lattice node'
    deltas = {delta: index for index, (_, delta) in enumerate(ACTIONS)}
    nodes = [model.nodes[i] for i in dark_path(model)]
    return [deltas[(b[0] - a[0], b[1] - a[1])] for a, b in zip(nodes, nodes[1:], strict=False)]


def copy_scenario(directory, name: str, **changes):
    """A copy of a shipped scenario in ``directory`` with some fields changed; its path."""
    source = find_scenario(name)
    values = yaml.safe_load(source.read_text())
    values['map'] = str((source.parent / values['map']).resolve())
    values.update(changes)
    path = directory / f'{name}-changed.yaml'
    path.write_text(yaml.safe_dump(values))
    return path


class ScriptedAgent(SpinningNode):
    """The agent's side of rl_msgs, plus monitors of everything else the environment sends."""

    def __init__(self, context):
        super().__init__('scripted_agent', context)
        self.received = {key: [] for key in ('description', 'lights', 'markers', 'grid')}
        self.states: list[RLStateReward] = []
        self.steps: list[StepInfo] = []
        self.summaries: list[EpisodeSummary] = []
        self.actions_sent = 0
        for message_type, topic, key in (
            (RLEnvDescription, 'rl_env/rl_env_description', 'description'),
            (SearchlightArray, 'searchlights', 'lights'),
            (MarkerArray, 'searchlight_markers', 'markers'),
            (OccupancyGrid, 'visibility_grid', 'grid'),
        ):
            self.node.create_subscription(message_type, topic, self.received[key].append, LATCHED)
        self.node.create_subscription(StepInfo, 'rl_env/step_info', self.steps.append, RL_QOS)
        self.node.create_subscription(
            EpisodeSummary, 'rl_env/episode_summary', self.summaries.append, RL_QOS
        )
        self.info_pub = self.node.create_publisher(
            RLExperimentInfo, 'rl_agent/rl_experiment_info', RL_QOS
        )
        self.state_sub = None
        self.action_pub = None
        self.connect()
        self.parameters = AsyncParameterClient(self.node, 'environment')

    def connect(self, on_state=None):
        """(Re)appear as an agent: a state reader and an action writer."""
        self.state_sub = self.node.create_subscription(
            RLStateReward, 'rl_env/rl_state_reward', on_state or self.states.append, RL_QOS
        )
        self.action_pub = self.node.create_publisher(RLAction, 'rl_agent/rl_action', RL_QOS)

    def disconnect(self):
        self.node.destroy_subscription(self.state_sub)
        self.node.destroy_publisher(self.action_pub)

    def next_state(self, timeout: float = 20.0) -> RLStateReward:
        count = len(self.states)
        assert self.spin_until(lambda: len(self.states) > count, timeout), 'no state came'
        return self.states[count]

    def act(self, action: int, timeout: float = 20.0) -> tuple[RLStateReward, StepInfo]:
        """Send an action; the state and the StepInfo it leads to."""
        states, steps = len(self.states), len(self.steps)
        self.action_pub.publish(RLAction(action=action))
        self.actions_sent += 1
        arrived = self.spin_until(
            lambda: len(self.states) > states and len(self.steps) > steps, timeout
        )
        assert arrived, f'no answer to action {action}'
        return self.states[states], self.steps[steps]

    def no_state_for(self, seconds: float) -> bool:
        count = len(self.states)
        self.spin_for(seconds)
        return len(self.states) == count

    def set_parameter(self, name, value):
        assert self.parameters.wait_for_services(timeout_sec=10.0)
        future = self.parameters.set_parameters([Parameter(name, value=value)])
        assert self.spin_until(future.done, 10.0)
        return future.result().results[0]


@pytest.fixture
def agent(node_processes, ros_context):
    """Set up after (so torn down before) node_processes, which checks for leftovers."""
    scripted = ScriptedAgent(ros_context)
    yield scripted
    scripted.close()


def ros_args(params: dict) -> list[str]:
    args = ['--ros-args']
    for key, value in params.items():
        if value is not None:
            args += ['-p', f'{key}:={str(value).lower() if isinstance(value, bool) else value}']
    return args


def start_sim(node_processes, scenario, name='sim_node', **params):
    assert SIM_NODE.exists(), f'{SIM_NODE} is missing: colcon build --packages-select stealth_sim'
    x, y, yaw = scenario.start
    defaults = {'map': scenario.map_path, 'initial_pose': [x, y, yaw], 'seed': 3}
    return node_processes.start(
        [str(SIM_NODE), *ros_args({**defaults, **params})],
        name,
        extra_env={'RCUTILS_LOGGING_BUFFERED_STREAM': '0'},
    )


def start_env(node_processes, name='env_node', extra_args=(), **params):
    assert ENV_NODE.exists(), f'{ENV_NODE} is missing: colcon build --packages-select stealth_env'
    return node_processes.start(
        [str(ENV_NODE), *ros_args(params), *extra_args],
        name,
        extra_env={'RCUTILS_LOGGING_BUFFERED_STREAM': '0'},
    )


def wait_for_log(process, text, timeout=20.0, count=1) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        log = process.log_path.read_text()
        if log.count(text) >= count or process.poll() is not None:
            break
        time.sleep(0.05)
    log = process.log_path.read_text()
    assert log.count(text) >= count, f'{text!r} not {count} times in the log:\n{log}'
    return log


def stop(process) -> str:
    os.killpg(process.pid, signal.SIGINT)
    assert process.wait(15) == 0, process.log_path.read_text()
    return process.log_path.read_text()


def totals(log: str) -> dict:
    """The environment's shutdown totals."""
    match = re.search(
        r'totals: (\d+) actions received \((\d+) dropped, (\d+) executed\), (\d+) states sent, '
        r'(\d+) episodes started',
        log,
    )
    assert match, f'no totals in the log:\n{log}'
    keys = ('received', 'dropped', 'executed', 'states', 'episodes')
    return dict(zip(keys, map(int, match.groups()), strict=True))


_JUDGED: dict[int, tuple[float, ...]] = {}  # per task: the last judged x, y, t, yaw


def check_step(task, state: RLStateReward, info: StepInfo, judged: str = 'true'):
    """The state is the estimate's cell (and phase, and heading); reward and visibility the
    core's for the step from the pose judged before (the start at the first step) to the judged
    pose (turning from its yaw to the judged one where lights are weighed by exposure), the goal
    and the reward's distances at the lattice node the judged pose stands at."""
    assert list(info.state) == list(state.state)
    estimate = info.estimated_pose
    t = info.header.stamp.sec + info.header.stamp.nanosec * 1e-9
    expected_state = task.state_of(estimate.x, estimate.y, t, estimate.theta)
    assert tuple(state.state) == pytest.approx(expected_state, abs=1e-6)
    pose = info.true_pose if judged == 'true' else estimate
    x0, y0, t0, yaw0 = _JUDGED.get(id(task), (*task.scenario.start[:2], 0.0, 0.0))
    if info.step == 1:  # from the start, at the reset: the previous episode's end
        x0, y0, yaw0 = task.scenario.start
    _JUDGED[id(task)] = (pose.x, pose.y, t, pose.theta)
    visibility = task.step_visibility(x0, y0, min(t0, t), pose.x, pose.y, t, yaw0, pose.theta)
    judgement = task.judge(*task.move_start(pose.x, pose.y), t, info.step, visibility=visibility)
    assert info.distance_to_goal == pytest.approx(task.distance_to_goal(pose.x, pose.y), rel=1e-5)
    assert info.visibility == pytest.approx(judgement.visibility, rel=1e-6, abs=1e-7)
    assert state.reward == pytest.approx(judgement.reward, rel=1e-6)
    assert state.terminal == info.terminal == judgement.terminal
    assert info.detected == judgement.detected
    assert info.header.frame_id == 'map'


def test_covert_path_reaches_the_goal_and_experiment_info_starts_the_next_episode(
    agent, node_processes
):
    scenario = load_scenario(SCENARIO)
    task = StealthTask(scenario, 'easy')
    sim = start_sim(node_processes, scenario)
    env = start_env(node_processes, scenario=SCENARIO, goal='easy', marker_period=0.2)

    # Before the agent speaks: the description (latched), the lights and the scene.
    assert agent.spin_until(lambda: all(agent.received.values()), 20.0), env.log_path.read_text()
    description = agent.received['description'][0]
    expected = task.description(stochastic=True)
    assert description.title == 'stealth-nav: simple-maze (easy)'
    assert (description.num_actions, description.num_states) == (4, expected['num_states'])
    assert list(description.min_state_range) == expected['min_state_range']
    assert list(description.max_state_range) == expected['max_state_range']
    assert description.max_reward == pytest.approx(expected['max_reward'])
    assert description.stochastic and description.episodic
    lights = agent.received['lights'][0]
    assert [light.name for light in lights.lights] == ['shortcut', 'west-column']
    assert lights.header.frame_id == 'map' and lights.lights[0].range == 25.0
    markers = agent.received['markers'][0].markers
    assert markers[0].action == Marker.DELETEALL
    assert all(m.header.frame_id == 'map' for m in markers)
    cones = [m for m in markers if m.ns == 'cones']
    assert len(cones) == 2 and all(m.type == Marker.TRIANGLE_LIST for m in cones)
    assert all(len(m.colors) == len(m.points) > 0 for m in cones)
    texts = {m.text for m in markers if m.type == Marker.TEXT_VIEW_FACING}
    assert {'shortcut', 'west-column', 'start', 'goal: easy'} <= texts

    first = agent.next_state()
    assert (list(first.state), first.reward, first.terminal) == ([1.5, 1.5], 0.0, False)
    actions = covert_actions(find_scenario(SCENARIO), 'easy')
    rewards = []
    for number, action in enumerate(actions, start=1):
        state, info = agent.act(action)
        check_step(task, state, info)
        assert (info.episode, info.step, info.action) == (0, number, action)
        rewards.append(state.reward)
        if state.terminal:
            break
    assert state.terminal and number >= len(actions) - 1, f'step {number}: {info}'
    assert agent.spin_until(lambda: agent.summaries, 5.0)
    summary = agent.summaries[0]
    assert (summary.episode, summary.outcome, summary.steps, summary.goal) == (
        0,
        EpisodeSummary.SUCCESS,
        number,
        'easy',
    )
    assert summary.total_reward == pytest.approx(sum(rewards), rel=1e-5)
    assert summary.peak_visibility < scenario.detection_threshold
    assert summary.path_length == pytest.approx(0.5 * number, rel=0.1)

    # After the terminal state, an action is dropped, not queued; RLExperimentInfo resets.
    agent.action_pub.publish(RLAction(action=UP))
    assert agent.no_state_for(0.5)
    wait_for_log(env, 'action 0 dropped: the environment is between episodes')
    agent.info_pub.publish(
        RLExperimentInfo(episode_number=0, episode_reward=sum(rewards), number_actions=number)
    )
    again = agent.next_state()
    assert (list(again.state), again.reward, again.terminal) == ([1.5, 1.5], 0.0, False)
    state, info = agent.act(RIGHT)
    assert (info.episode, info.step) == (1, 1)
    check_step(task, state, info)
    log = stop(env)
    assert totals(log) == {
        'received': number + 2,
        'dropped': 1,
        'executed': number + 1,
        'states': number + 3,
        'episodes': 2,
    }
    assert sim.poll() is None


def test_walking_into_a_light_is_detected_and_bad_actions_are_dropped(agent, node_processes):
    scenario = load_scenario(SCENARIO)
    task = StealthTask(scenario, 'easy')
    # At 20x real time a move takes ~0.15 s of wall time, so the second of two actions published
    # back to back surely arrives while the first is moving (as fast as possible it could not).
    start_sim(node_processes, scenario, real_time_factor=20.0)
    env = start_env(node_processes, scenario=SCENARIO, goal='easy', seed=5)
    agent.next_state()

    agent.action_pub.publish(RLAction(action=7))
    agent.action_pub.publish(RLAction(action=-1))
    assert agent.no_state_for(0.5)
    log = wait_for_log(env, 'action -1 dropped: expected one of 0 up, 1 down, 2 left, 3 right')
    assert 'action 7 dropped' in log
    # Two at once: the second arrives during the first's move and is dropped.
    agent.action_pub.publish(RLAction(action=UP))
    agent.action_pub.publish(RLAction(action=UP))
    assert agent.spin_until(lambda: len(agent.states) == 2, 20.0)
    assert agent.no_state_for(0.5) and len(agent.states) == 2
    wait_for_log(env, 'action 0 dropped: the environment is executing a move (action 0, step 1)')

    # Straight up the west column into the light that cuts across it.
    for _ in range(30):
        state, info = agent.act(UP)
        check_step(task, state, info)
        if state.terminal:
            break
    assert info.detected and info.visibility >= scenario.detection_threshold
    assert agent.spin_until(lambda: agent.summaries, 5.0)
    assert agent.summaries[0].outcome == EpisodeSummary.DETECTED
    assert agent.summaries[0].steps == info.step

    # Parameters are checked at runtime too.
    assert 'read-only' in agent.set_parameter('scenario', 'map1').reason
    assert 'judge_on must be one of true, estimate' in agent.set_parameter('judge_on', 'x').reason
    assert not agent.set_parameter('move_timeout', 0.0).successful
    assert agent.set_parameter('judge_on', 'estimate').successful
    wait_for_log(env, 'parameters changed: judge_on=estimate')
    assert env.poll() is None


def test_step_limit_times_out_judged_on_the_estimate(agent, node_processes, tmp_path):
    path = copy_scenario(tmp_path, SCENARIO, step_limit=4)
    scenario = load_scenario(path)
    task = StealthTask(scenario)
    start_sim(node_processes, scenario)
    env = start_env(node_processes, scenario=path, judge_on='estimate')
    wait_for_log(env, 'judged on the estimate')
    agent.next_state()
    for number, action in enumerate((UP, DOWN, RIGHT, LEFT), start=1):
        state, info = agent.act(action)
        check_step(task, state, info, judged='estimate')
        assert state.terminal == (number == 4)
    assert agent.spin_until(lambda: agent.summaries, 5.0)
    summary = agent.summaries[0]
    assert (summary.outcome, summary.steps, summary.goal) == (EpisodeSummary.TIMEOUT, 4, 'hard')


def test_moving_lights_are_judged_at_the_end_of_each_move_and_redrawn(
    agent, node_processes, tmp_path
):
    values = yaml.safe_load(find_scenario(SCENARIO).read_text())
    lights = values['lights']
    lights[0]['motion'] = {
        'type': 'sweep',
        'min_direction': 240,
        'max_direction': 300,
        'angular_speed': 30,
    }
    path = copy_scenario(tmp_path, SCENARIO, lights=lights)
    scenario = load_scenario(path)
    task = StealthTask(scenario)
    start_sim(node_processes, scenario)
    start_env(node_processes, scenario=path, marker_period=0.1)
    assert agent.spin_until(lambda: all(agent.received.values()), 20.0)
    agent.next_state()
    for action in (RIGHT, RIGHT, UP):
        state, info = agent.act(action)
        check_step(task, state, info)  # visibility at the stamp: the lights as they were then
    t = info.header.stamp.sec + info.header.stamp.nanosec * 1e-9
    assert t > 1.0

    def drawn_at(message) -> float:
        return message.header.stamp.sec + message.header.stamp.nanosec * 1e-9

    assert agent.spin_until(lambda: drawn_at(agent.received['lights'][-1]) == t, 5.0)
    assert agent.spin_until(lambda: drawn_at(agent.received['markers'][-1].markers[0]) == t, 5.0)
    sweeping = agent.received['lights'][-1].lights[0]
    assert sweeping.motion == sweeping.MOTION_SWEEP
    assert sweeping.direction == pytest.approx(scenario.lights[0].at(t).direction)
    first_cone = next(m for m in agent.received['markers'][0].markers if m.ns == 'cones')
    last_cone = next(m for m in agent.received['markers'][-1].markers if m.ns == 'cones')
    assert first_cone.points != last_cone.points
    # The visibility grid moves with the lights: the field at t, as 0-100 of the threshold.
    assert agent.spin_until(lambda: drawn_at(agent.received['grid'][-1]) == t, 5.0)
    grid = agent.received['grid'][-1]
    occupancy = scenario.map
    assert (grid.info.width, grid.info.height) == (occupancy.width, occupancy.height)
    total, _ = visibility_field(
        occupancy.blocked, occupancy.resolution, occupancy.origin, scenario.lights, t
    )
    levels = visibility_levels(total, scenario.detection_threshold).ravel().tolist()
    assert list(grid.data) == levels
    assert list(agent.received['grid'][0].data) != levels


def test_a_bounce_variant_is_judged_and_drawn_with_its_bounce(agent, node_processes):
    """map1-bounce: the node judges steps with direct + bounce light (the task's model) and
    its visibility grid is the field with the bounce, not the direct light alone."""
    scenario = load_scenario('map1-bounce')
    task = StealthTask(scenario)
    start_sim(node_processes, scenario)
    start_env(node_processes, scenario='map1-bounce', marker_period=0.2)
    assert agent.spin_until(lambda: all(agent.received.values()), 60.0)
    agent.next_state()
    for action in (RIGHT, RIGHT, UP):
        state, info = agent.act(action)
        check_step(task, state, info)
    grid = agent.received['grid'][-1]
    occupancy, threshold = scenario.map, scenario.detection_threshold
    grid_args = (occupancy.blocked, occupancy.resolution, occupancy.origin, scenario.lights)
    total, _ = visibility_field(*grid_args, bounce=scenario.bounce)
    direct, _ = visibility_field(*grid_args)
    assert list(grid.data) == visibility_levels(total, threshold).ravel().tolist()
    assert list(grid.data) != visibility_levels(direct, threshold).ravel().tolist()


def start_variant(agent, node_processes, name: str):
    """Simulator and environment on scenario `name`: (scenario, task, RLEnvDescription), the
    description's state ranges checked against the task's."""
    scenario = load_scenario(name)
    task = StealthTask(scenario)
    start_sim(node_processes, scenario)
    start_env(node_processes, scenario=name)
    assert agent.spin_until(lambda: agent.received['description'], 20.0)
    description = agent.received['description'][-1]
    assert description.num_actions == task.num_actions
    assert list(description.min_state_range) == pytest.approx(task.state_bounds()[0])
    assert list(description.max_state_range) == pytest.approx(task.state_bounds()[1])
    return scenario, task, description


def test_a_moving_variant_has_the_phase_in_the_state_and_a_wait(agent, node_processes):
    """simple-maze-moving: RLEnvDescription grows by the phase and the wait action; a wait
    keeps the robot at its node while simulated time passes; states carry the phase of the
    move's end time and steps are judged along the way."""
    scenario, task, description = start_variant(agent, node_processes, 'simple-maze-moving')
    assert description.num_actions == 5
    assert description.max_state_range[2] == scenario.timing.cycle_bins - 1
    first = agent.next_state()
    assert list(first.state) == [*scenario.start[:2], 0.0]
    state, info = agent.act(WAIT)
    check_step(task, state, info)
    assert list(state.state[:2]) == list(first.state[:2]) and not state.terminal
    waited = info.header.stamp.sec + info.header.stamp.nanosec * 1e-9
    slot = task.step_seconds
    assert waited == pytest.approx(slot, abs=1e-6)  # a wait holds still for a step's slot
    assert state.state[2] == scenario.timing.bin_of(slot)
    state, info = agent.act(RIGHT)
    check_step(task, state, info)
    assert state.state[0] == pytest.approx(first.state[0] + scenario.step_distance)
    # A move that ends early is padded to its slot's end, a slower one ends a little late.
    moved = info.header.stamp.sec + info.header.stamp.nanosec * 1e-9
    assert 2 * slot - 1e-6 <= moved < 2 * slot + scenario.timing.bin_seconds
    assert state.state[2] == scenario.timing.bin_of(2 * slot)


def test_an_exposure_variant_has_the_heading_in_the_state_and_turns(agent, node_processes):
    """simple-maze-exposure: RLEnvDescription grows by the heading and the two turn actions; a
    turn turns the robot in place (TURN_TO_HEADING), a move leaves it facing the move's
    direction, a move the map blocks keeps its heading; steps are judged with the true pose's
    yaw, the turn at the departure included."""
    scenario, task, description = start_variant(agent, node_processes, 'simple-maze-exposure')
    assert description.num_actions == 6
    assert (description.min_state_range[2], description.max_state_range[2]) == (0.0, 3.0)
    first = agent.next_state()
    assert list(first.state) == [*scenario.start[:2], 2.0]  # yaw 180: west
    turn_left = task.action_names.index('turn_left')
    expected = [
        (turn_left, (3.0, 1.5, 3.0)),  # a quarter left in place: south
        (DOWN, (3.0, 1.0, 3.0)),
        (RIGHT, (3.5, 1.0, 0.0)),  # a move faces its direction
        (DOWN, (3.5, 1.0, 0.0)),  # the outer wall blocks it: nothing turns
    ]
    for action, state_wanted in expected:
        state, info = agent.act(action)
        check_step(task, state, info)
        assert tuple(state.state) == pytest.approx(state_wanted)
        assert not state.terminal
        yaw = exposure.heading_angle(int(state_wanted[2]))
        # the true yaw: the estimate's aim at the node, off by the localisation error
        assert abs(exposure.wrap(info.true_pose.theta - yaw)) < 0.3


def test_a_simulator_on_another_map_is_reported(agent, node_processes):
    scenario = load_scenario(SCENARIO)
    other = load_scenario('map1')
    start_sim(node_processes, scenario, map=other.map_path)
    env = start_env(node_processes, scenario=SCENARIO)
    log = wait_for_log(env, "the simulator's map is not the map of scenario 'simple-maze'")
    assert '400 x 400 cells of 0.05 m from (0, 0), expected 300 x 300 cells' in log, log


def test_simulator_failure_and_agent_loss_abort_and_recover(agent, node_processes):
    scenario = load_scenario(SCENARIO)
    sim = start_sim(node_processes, scenario)
    env = start_env(node_processes, scenario=SCENARIO, move_timeout=1.0)
    agent.next_state()
    agent.act(UP)

    stop(sim)
    started = time.monotonic()
    state, info_count = agent.states[-1], len(agent.steps)
    agent.action_pub.publish(RLAction(action=UP))
    aborted = agent.next_state(timeout=10.0)
    assert time.monotonic() - started < 5.0
    assert aborted.terminal and aborted.reward == 0.0 and list(aborted.state) == list(state.state)
    assert len(agent.steps) == info_count  # no StepInfo: no step happened
    assert agent.spin_until(lambda: agent.summaries, 5.0)
    assert (agent.summaries[0].outcome, agent.summaries[0].steps) == (EpisodeSummary.ABORTED, 1)
    wait_for_log(env, 'episode 0 ABORTED after 1 steps')

    # The agent closes the episode; the reset waits for a simulator, then the next one starts.
    agent.info_pub.publish(RLExperimentInfo(episode_number=0, number_actions=2))
    assert agent.no_state_for(1.5)
    start_sim(node_processes, scenario, name='sim_node_again')
    first = agent.next_state(timeout=30.0)
    assert (list(first.state), first.terminal) == ([1.5, 1.5], False)
    state, info = agent.act(RIGHT)
    assert (info.episode, info.step) == (1, 1)

    # An agent that goes away ends the running episode; the next agent gets a fresh one.
    agent.disconnect()
    wait_for_log(env, 'the agent went away')
    assert agent.spin_until(lambda: len(agent.summaries) == 2, 5.0)
    assert (agent.summaries[1].episode, agent.summaries[1].outcome) == (1, EpisodeSummary.ABORTED)
    count = len(agent.states)
    agent.connect()
    assert agent.spin_until(lambda: len(agent.states) > count, 20.0)
    assert list(agent.states[count].state) == [1.5, 1.5]
    # Gone again before acting: the episode is withdrawn (no summary) and starts over.
    agent.disconnect()
    wait_for_log(env, 'before its first action in episode 2: withdrawn')
    agent.connect()
    assert agent.spin_until(lambda: len(agent.states) > count + 1, 20.0)
    state, info = agent.act(UP)
    assert (info.episode, info.step) == (2, 1)
    assert len(agent.summaries) == 2
    counts = totals(stop(env))
    assert (counts['states'], counts['episodes']) == (len(agent.states), 3)


def test_a_first_state_left_unanswered_ends_the_episode_aborted(agent, node_processes):
    """After an agent restarts, DDS may deliver the volatile first state to the dead agent's
    reader alone: without an answer in first_action_timeout the episode ends ABORTED before its
    first step (terminal state and summary), so both sides are in step again."""
    scenario = load_scenario(SCENARIO)
    start_sim(node_processes, scenario)
    env = start_env(node_processes, scenario=SCENARIO, first_action_timeout=1.0)
    first = agent.next_state()
    aborted = agent.next_state(timeout=10.0)
    assert aborted.terminal and aborted.reward == 0.0 and list(aborted.state) == list(first.state)
    assert agent.spin_until(lambda: agent.summaries, 5.0)
    summary = agent.summaries[0]
    assert (summary.episode, summary.outcome, summary.steps) == (0, EpisodeSummary.ABORTED, 0)
    wait_for_log(env, 'no action for the first state within first_action_timeout 1 s')
    agent.action_pub.publish(RLAction(action=UP))  # a late answer is dropped, not executed
    wait_for_log(env, 'dropped')
    agent.info_pub.publish(RLExperimentInfo(episode_number=0, number_actions=0))
    assert not agent.next_state().terminal
    state, info = agent.act(UP)  # answered in time: the episode runs as usual
    assert (info.episode, info.step) == (1, 1) and not state.terminal
    assert len(agent.summaries) == 1
    stop(env)


def test_episodes_wait_for_the_step_readers_a_respawn_is_given(agent, node_processes):
    """StepInfo is built only while someone reads it: a respawned environment (step_readers
    set by stealth train) starts no episode before that many readers are matched, so none of
    its steps is missing from the recording."""
    scenario = load_scenario(SCENARIO)
    start_sim(node_processes, scenario)
    env = start_env(node_processes, scenario=SCENARIO, step_readers=2)
    wait_for_log(env, 'still waiting for 2 readers of rl_env/step_info')
    assert agent.no_state_for(2.0)  # the agent is there, and one step reader (its own)
    recorded: list[StepInfo] = []
    agent.node.create_subscription(StepInfo, 'rl_env/step_info', recorded.append, RL_QOS)
    agent.next_state()
    agent.act(UP)
    assert agent.spin_until(lambda: recorded, 5.0) and recorded[0].step == 1
    stop(env)


def test_a_restarted_simulator_or_agent_ends_the_episode_it_left(agent, node_processes):
    scenario = load_scenario(SCENARIO)
    start_sim(node_processes, scenario)
    env = start_env(node_processes, scenario=SCENARIO, first_episode=7)
    client = agent.node.create_client(RestartEpisode, 'rl_env/restart_episode')

    def restart(which: int) -> RestartEpisode.Response:
        assert agent.spin_until(client.service_is_ready, 10.0)
        future = client.call_async(RestartEpisode.Request(restarted=which, reason='a test'))
        assert agent.spin_until(future.done, 10.0)
        return future.result()

    agent.next_state()
    state, info = agent.act(UP)
    assert (info.episode, info.step) == (7, 1)  # a continued run's numbering
    # The simulator restarted while the environment waited for an action: ABORTED all the same.
    count = len(agent.states)
    response = restart(RestartEpisode.Request.SIMULATOR)
    assert (response.aborted, response.episode) == (True, 7), response.message
    assert agent.spin_until(lambda: len(agent.states) > count, 10.0)
    aborted = agent.states[count]
    assert aborted.terminal and aborted.reward == 0.0 and list(aborted.state) == list(state.state)
    assert agent.spin_until(lambda: agent.summaries, 5.0)
    summary = agent.summaries[0]
    assert (summary.episode, summary.outcome, summary.steps) == (7, EpisodeSummary.ABORTED, 1)
    wait_for_log(env, 'episode 7 ABORTED after 1 steps: the simulator was restarted (a test)')

    # The agent closes it as usual; the next episode takes the next number.
    agent.info_pub.publish(RLExperimentInfo(episode_number=7, number_actions=2))
    first = agent.next_state()
    assert (list(first.state), first.terminal) == ([1.5, 1.5], False)
    _, info = agent.act(RIGHT)
    assert (info.episode, info.step) == (8, 1)
    # The agent restarted: its episode ends ABORTED with nothing sent to it, and the next one
    # starts for whoever is connected now.
    count = len(agent.states)
    response = restart(RestartEpisode.Request.AGENT)
    assert (response.aborted, response.episode) == (True, 8), response.message
    assert agent.spin_until(lambda: len(agent.summaries) == 2, 5.0)
    assert (agent.summaries[1].episode, agent.summaries[1].outcome) == (8, EpisodeSummary.ABORTED)
    assert agent.spin_until(lambda: len(agent.states) > count, 20.0)
    fresh = agent.states[count]
    assert not fresh.terminal and list(fresh.state) == [1.5, 1.5]  # no terminal state was sent
    _, info = agent.act(UP)
    assert (info.episode, info.step) == (9, 1)
    # Nothing running (the reset in flight goes back to waiting): nothing aborted.
    count = len(agent.states)
    assert restart(RestartEpisode.Request.SIMULATOR).episode == 9
    assert agent.spin_until(lambda: len(agent.states) > count, 10.0)  # its terminal state
    agent.info_pub.publish(RLExperimentInfo(episode_number=9, number_actions=2))
    assert agent.spin_until(lambda: len(agent.states) > count + 1, 20.0)
    counts = totals(stop(env))
    assert counts['episodes'] == 4


@pytest.mark.parametrize(
    ('params', 'expected'),
    [
        ({}, 'parameter scenario: required'),
        ({'scenario': 'atlantis'}, "scenario 'atlantis': not found (known scenarios:"),
        ({'scenario': 'BROKEN'}, "field 'step_limit': expected an integer >= 1"),
        ({'scenario': SCENARIO, 'goal': 'impossible'}, "parameter goal: goal 'impossible'"),
        ({'scenario': SCENARIO, 'judge_on': 'guess'}, 'judge_on must be one of true, estimate'),
        ({'scenario': SCENARIO, 'move_timeout': -1.0}, 'parameter move_timeout:'),
        ({'scenario': SCENARIO, 'seed': 'abc'}, 'parameter seed:'),
        ({'scenario': SCENARIO, '--params-file': 'MISSING'}, "Couldn't parse params file"),
    ],
)
def test_bad_startup_input_stops_the_node_with_one_clear_line(
    node_processes, tmp_path, params, expected
):
    params = dict(params)
    if params.get('scenario') == 'BROKEN':
        params['scenario'] = copy_scenario(tmp_path, SCENARIO, step_limit=0)
    extra = []
    if params.pop('--params-file', None):
        extra = ['--params-file', str(tmp_path / 'missing.yaml')]
    process = start_env(node_processes, extra_args=extra, **params)
    assert process.wait(30) == 2
    log = process.log_path.read_text()
    lines = [line for line in log.splitlines() if '[environment]' in line]
    assert len(lines) == 1 and 'not starting:' in lines[0] and 'Traceback' not in log, log
    assert expected in lines[0]


def test_ten_thousand_steps_lose_no_action_and_no_state(agent, node_processes):
    """Counted at both ends: actions the agent sent = actions the environment received, states
    the environment sent = states the agent received, and a StepInfo for every action."""
    agent.disconnect()  # it reappears below, answering from its callback
    scenario = load_scenario(SCENARIO)
    start_sim(node_processes, scenario, **FAST_SIM)
    env = start_env(node_processes, scenario=SCENARIO, log_every=0, marker_period=0.0)
    rng = np.random.default_rng(11)
    received = []

    def answer(state: RLStateReward) -> None:  # the agent: every state answered at once
        received.append(state.terminal)
        if state.terminal:
            agent.info_pub.publish(RLExperimentInfo())
        elif agent.actions_sent < LOSSLESS_STEPS:
            agent.action_pub.publish(RLAction(action=int(rng.integers(4))))
            agent.actions_sent += 1

    agent.connect(on_state=answer)
    started = time.monotonic()
    done = agent.spin_until(
        lambda: agent.actions_sent == LOSSLESS_STEPS and len(agent.steps) == LOSSLESS_STEPS,
        300.0,
    )
    elapsed = time.monotonic() - started
    agent.spin_for(0.5)  # anything still on its way
    log = stop(env)
    counts = totals(log)
    episodes = sum(received)
    print(
        f'\n{LOSSLESS_STEPS} steps in {elapsed:.1f} s ({LOSSLESS_STEPS / elapsed:.0f} steps/s), '
        f'{episodes} episodes ended; environment: {counts}'
    )
    assert done, f'{agent.actions_sent} actions sent, {len(agent.steps)} StepInfo received'
    assert counts['received'] == agent.actions_sent == LOSSLESS_STEPS
    assert counts['dropped'] == 0 and counts['executed'] == LOSSLESS_STEPS
    assert counts['states'] == len(received) == LOSSLESS_STEPS + counts['episodes']
    assert len(agent.steps) == LOSSLESS_STEPS
    assert [s.step for s in agent.steps[:3]] == [1, 2, 3]
    assert math.isfinite(sum(s.reward for s in agent.steps))
