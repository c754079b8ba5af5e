"""System tests of the navigator (``stealth_nav2 navigator``, node ``bt_navigator``): the
simulator standing in for the robot and AMCL, the covert planner server, and plain rclpy action
clients called the way nav2_simple_commander's BasicNavigator calls them (wait for the server,
send_goal_async with a feedback callback, get_result_async, cancel_goal_async; GetState on
``bt_navigator/get_state`` and ``amcl/get_state`` as waitUntilNav2Active does)."""

import math
import re
import time

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import FollowWaypoints, NavigateThroughPoses, NavigateToPose
from nav_msgs.msg import Odometry, Path
import pytest
from rclpy.action import ActionClient
from rclpy.qos import qos_profile_sensor_data
from ros_support import REPO_ROOT, SpinningNode
from stealth_core.planners import optimal_path
from stealth_core.scenario import find_scenario, load_scenario
from stealth_core.task import StealthTask
from stealth_node_kit.conversions import quaternion_yaw, seconds, yaw_quaternion
from stealth_node_kit.qos import kept_qos
from test_env_node import ros_args, start_sim, wait_for_log
from test_nav2_planner import stamped

INSTALL = REPO_ROOT / 'ros2_ws/install/stealth_nav2/lib/stealth_nav2'
NAVIGATOR, PLANNER = INSTALL / 'navigator', INSTALL / 'planner_server'
SCENARIO = 'lgfloor'
# Simulated time at 2x (slack for a loaded machine), odometry (and so the control period) every
# 0.1 s simulated (50 ms wall); the simulator's default odometry noise.
SIM = {'real_time_factor': 2.0, 'idle_period': 0.025, 'publish_rate': 10.0}
SIM_TIME = {'use_sim_time': True}


def start_planner(node_processes, scenario=SCENARIO, **params):
    assert PLANNER.exists(), f'{PLANNER} is missing: make setup'
    process = node_processes.start(
        [str(PLANNER), *ros_args({'scenario': scenario, **SIM_TIME, **params})],
        'planner_server',
        extra_env={'RCUTILS_LOGGING_BUFFERED_STREAM': '0'},
    )
    return process


def start_navigator(node_processes, name='navigator', extra_args=(), **params):
    assert NAVIGATOR.exists(), f'{NAVIGATOR} is missing: make setup'
    return node_processes.start(
        [str(NAVIGATOR), *ros_args({**SIM_TIME, **params}), *extra_args],
        name,
        extra_env={'RCUTILS_LOGGING_BUFFERED_STREAM': '0'},
    )


class Commander(SpinningNode):
    """What BasicNavigator does, with the test's own spinning; plus the robot's ground truth
    and the commands it is sent."""

    def __init__(self, context, namespace=''):
        super().__init__('commander', context)
        prefix = f'{namespace}/' if namespace else ''
        node = self.node
        self.clients = {
            'to_pose': ActionClient(node, NavigateToPose, f'{prefix}navigate_to_pose'),
            'through': ActionClient(node, NavigateThroughPoses, f'{prefix}navigate_through_poses'),
            'waypoints': ActionClient(node, FollowWaypoints, f'{prefix}follow_waypoints'),
        }
        self.feedback = []
        self.truths = []  # (sim t, x, y, yaw, speed)
        self.commands = []  # (wall t, linear, angular)
        node.create_subscription(Odometry, 'ground_truth', self._on_truth, qos_profile_sensor_data)
        node.create_subscription(Twist, 'cmd_vel', self._on_cmd, 10)

    def _on_truth(self, message: Odometry):
        p = message.pose.pose
        yaw, speed = quaternion_yaw(p.orientation), message.twist.twist.linear.x
        self.truths.append((seconds(message.header.stamp), p.position.x, p.position.y, yaw, speed))

    def _on_cmd(self, message: Twist):
        self.commands.append((time.monotonic(), message.linear.x, message.angular.z))

    def wait_until_active(self, names=('amcl', 'bt_navigator'), timeout=60.0) -> None:
        """waitUntilNav2Active's GetState loop on each node."""
        for name in names:
            client = self.node.create_client(GetState, f'{name}/get_state')
            assert self.spin_until(lambda c=client: c.service_is_ready(), timeout), name
            deadline = time.monotonic() + timeout
            state = 'unknown'
            while state != 'active' and time.monotonic() < deadline:
                future = client.call_async(GetState.Request())
                self.spin_until(future.done, 5.0)
                state = future.result().current_state.label if future.done() else 'unknown'
                if state != 'active':
                    self.spin_for(0.2)
            assert state == 'active', f'{name}/get_state: {state}'

    def send(self, kind: str, goal, timeout=30.0):
        client = self.clients[kind]
        assert self.spin_until(lambda: client.server_is_ready(), timeout), f'no {kind} server'
        self.feedback = []
        future = client.send_goal_async(goal, lambda message: self.feedback.append(
            (time.monotonic(), message.feedback)))  # fmt: skip
        assert self.spin_until(future.done, timeout)
        handle = future.result()
        assert handle.accepted, f'{kind} goal rejected'
        return handle

    def result(self, handle, timeout: float):
        future = handle.get_result_async()
        assert self.spin_until(future.done, timeout), 'no result in time'
        return future.result()


@pytest.fixture
def commander(node_processes, ros_context):
    """Set up after (so torn down before) node_processes."""
    node = Commander(ros_context)
    yield node
    node.close()


def start_all(node_processes, name=SCENARIO, **navigator_params):
    scenario = load_scenario(find_scenario(name))
    sim = start_sim(node_processes, scenario, **SIM)
    planner = start_planner(node_processes, name)
    navigator = start_navigator(node_processes, **navigator_params)
    wait_for_log(navigator, 'navigator ready', timeout=60.0)
    return scenario, sim, planner, navigator


def until_reached(truths, task, radius: float):
    """The ground truth up to reaching the goal (within its radius, where the task ends: what
    the lights do to a robot standing there afterwards is no part of the way)."""
    for index, (_, x, y, *_) in enumerate(truths):
        if math.dist((x, y), (task.goal.x, task.goal.y)) <= radius + 0.02:
            return truths[: index + 1]
    return truths


def test_navigate_to_lgfloors_hard_goal_unseen_with_feedback(commander, node_processes):
    scenario, _, _, navigator = start_all(node_processes)
    commander.wait_until_active()
    # The ground truth is heard before the robot moves, so the way is judged from its start.
    assert commander.spin_until(lambda: commander.truths, 30.0), 'no ground truth'
    task = StealthTask(scenario, 'hard')
    gx, gy = task.goal.x, task.goal.y
    started = time.monotonic()
    handle = commander.send('to_pose', NavigateToPose.Goal(pose=stamped(gx, gy)))
    answer = commander.result(handle, timeout=600.0)
    elapsed = time.monotonic() - started
    result = answer.result
    assert answer.status == GoalStatus.STATUS_SUCCEEDED, (result.error_code, result.error_msg)
    assert (result.error_code, result.error_msg) == (0, '')

    truths = commander.truths
    sim_seconds = truths[-1][0] - truths[0][0]
    print(f'\nlgfloor hard goal: {elapsed:.1f} s wall, {sim_seconds:.1f} s simulated')
    x, y = truths[-1][1:3]
    assert math.dist((x, y), (gx, gy)) <= scenario.goal_radius + 0.25  # goal_tolerance
    way = until_reached(truths, task, scenario.goal_radius)
    peak = max(task.visibility(x, y, t, yaw) for t, x, y, yaw, _ in way)
    assert peak < scenario.detection_threshold, f'seen: visibility {peak:.3f} on the way'
    moved = [(tx, ty) for _, tx, ty, _, _ in truths]
    assert math.dist(moved[0], scenario.start[:2]) < 0.2 and len(truths) > 50

    feedback = [message for _, message in commander.feedback]
    assert len(feedback) > 10
    following = [message for message in feedback if message.distance_remaining > 0]
    first, last = following[0], feedback[-1]  # distance 0 while the first plan is being made
    assert first.distance_remaining > 20.0 > last.distance_remaining
    assert seconds(last.navigation_time) > seconds(first.navigation_time)
    assert first.estimated_time_remaining.sec > 10
    assert last.current_pose.header.frame_id == 'map'
    assert math.dist((last.current_pose.pose.position.x, last.current_pose.pose.position.y),
                     (gx, gy)) < 2.0  # fmt: skip
    assert all(message.number_of_recoveries >= 0 for message in feedback)
    assert 'goal reached' in navigator.log_path.read_text()


def test_a_timed_path_through_the_sweeping_light_keeps_its_stamps_unseen(
    commander, node_processes
):
    """lgfloor-moving: every way to the hard goal is lit at some time, so the covert plan times
    its passages (each pose stamped with when to be there). The robot is never early at a pose
    (it paces its drives and holds to the stamps) and is never seen by the lights as they move,
    judged on the ground truth at its own time."""
    scenario, _, _, navigator = start_all(node_processes, 'lgfloor-moving')
    commander.wait_until_active()
    assert commander.spin_until(lambda: commander.truths, 30.0), 'no ground truth'
    plans = []
    # The plan is latched: a reader matched only after it was published (a loaded machine's
    # discovery) still gets it.
    commander.node.create_subscription(Path, 'plan', plans.append, kept_qos(1))
    task = StealthTask(scenario, 'hard')
    started = time.monotonic()
    handle = commander.send('to_pose', NavigateToPose.Goal(pose=stamped(task.goal.x, task.goal.y)))
    answer = commander.result(handle, timeout=900.0)
    elapsed = time.monotonic() - started
    assert answer.status == GoalStatus.STATUS_SUCCEEDED, answer.result.error_msg
    truths = commander.truths
    print(f'\nlgfloor-moving hard goal: {elapsed:.1f} s wall, '
          f'{truths[-1][0] - truths[0][0]:.1f} s simulated, {len(plans)} plan(s)')  # fmt: skip
    x, y = truths[-1][1:3]
    # The covert way ends within the goal radius (the goal itself may be lit then).
    assert math.dist((x, y), (task.goal.x, task.goal.y)) <= scenario.goal_radius + 0.25
    way = until_reached(truths, task, scenario.goal_radius)
    peak = max(task.visibility(x, y, t, yaw) for t, x, y, yaw, _ in way)
    assert peak < scenario.detection_threshold, f'seen: visibility {peak:.3f} on the way'

    # Never early at a pose of the first plan (up to a replan, if the loaded machine made the
    # robot fall behind): when it comes closest to each (within 0.25 m: localisation error),
    # not before its stamp (but for half a step: a paced run's speed ramps are estimated).
    assert plans, 'no plan published'
    until = seconds(plans[1].header.stamp) if len(plans) > 1 else math.inf
    poses = plans[0].poses[1:]  # (the robot stands at the first from the start)
    checked = 0
    for pose in poses:
        stamp, point = seconds(pose.header.stamp), (pose.pose.position.x, pose.pose.position.y)
        near = [(math.dist((x, y), point), t) for t, x, y, *_ in truths if t <= until]
        closest = min(near)[0] if near else math.inf
        if closest < 0.25:
            reached = next(t for d, t in near if d <= closest + 0.02)
            assert reached >= stamp - scenario.timing.step_seconds / 2, (point, reached, stamp)
            checked += 1
    assert checked >= len(poses) / 2 if until == math.inf else checked > 10


def test_preempt_reject_and_cancel_which_stops_the_robot_within_one_control_period(
    commander, node_processes
):
    """A second goal of the same action preempts the first (ABORTED), a goal of another action
    is rejected while one runs, and a cancel stops the robot at once."""
    start_all(node_processes)
    commander.wait_until_active()
    task = StealthTask(load_scenario(find_scenario(SCENARIO)), 'hard')
    goal = NavigateToPose.Goal(pose=stamped(task.goal.x, task.goal.y))
    first = commander.send('to_pose', goal)
    assert commander.spin_until(lambda: commander.truths and commander.truths[-1][4] > 0.3, 120.0)
    handle = commander.send('to_pose', goal)
    answer = commander.result(first, timeout=30.0)
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert answer.result.error_msg == 'preempted by a newer goal'
    other = commander.clients['through'].send_goal_async(
        NavigateThroughPoses.Goal(poses=[stamped(task.goal.x, task.goal.y)])
    )
    assert commander.spin_until(other.done, 30.0)
    assert not other.result().accepted  # one goal at a time, as Nav2's navigator muxer

    assert commander.spin_until(
        lambda: commander.truths and commander.truths[-1][4] > 0.3, 120.0
    ), 'the robot never got under way'
    sent = time.monotonic()
    truths_before = len(commander.truths)
    cancel = handle.cancel_goal_async()
    assert commander.spin_until(cancel.done, 10.0)
    assert cancel.result().goals_canceling, 'the cancel was refused'
    answer = commander.result(handle, timeout=30.0)
    assert answer.status == GoalStatus.STATUS_CANCELED
    commander.spin_for(1.0)

    after = [c for c in commander.commands if c[0] >= sent]
    stops = [c for c in after if c[1] == 0.0 and c[2] == 0.0]
    assert stops, 'no zero Twist after the cancel'
    first_stop = stops[0][0]
    # At most a command already in flight between the cancel and the zero Twist, and nothing
    # but zeros once it came.
    assert len([c for c in after if c[0] < first_stop]) <= 1
    assert all(c[1] == 0.0 and c[2] == 0.0 for c in after if c[0] >= first_stop)
    period_wall = 1.0 / SIM['publish_rate'] / SIM['real_time_factor']
    latency = first_stop - sent
    truths = commander.truths[truths_before:]
    stopped = next(t for t, *_, speed in truths if abs(speed) < 0.01)
    print(f'\ncancel: zero Twist {latency * 1000:.0f} ms (wall) after the cancel was sent '
          f'(control period {period_wall * 1000:.0f} ms wall); ground truth at rest '
          f'{stopped - truths[0][0]:.2f} s simulated after')  # fmt: skip


def test_a_robot_knocked_off_its_path_replans_as_a_recovery(commander, node_processes):
    """The localisation is told the robot stands a metre off the path (initialpose, as a
    kidnapped robot's AMCL would jump): the navigator replans, counted as a recovery."""
    _, _, _, navigator = start_all(node_processes)
    commander.wait_until_active()
    task = StealthTask(load_scenario(find_scenario(SCENARIO)), 'hard')
    handle = commander.send('to_pose', NavigateToPose.Goal(pose=stamped(task.goal.x, task.goal.y)))
    assert commander.spin_until(lambda: commander.truths and commander.truths[-1][4] > 0.3, 120.0)
    kidnap = commander.node.create_publisher(PoseWithCovarianceStamped, 'initialpose', 10)
    _, x, y, yaw, _ = commander.truths[-1]
    message = PoseWithCovarianceStamped()
    message.header.frame_id = 'map'
    message.pose.pose.position.x = x - math.sin(yaw)  # a metre to the robot's left
    message.pose.pose.position.y = y + math.cos(yaw)
    message.pose.pose.orientation = yaw_quaternion(yaw)
    kidnap.publish(message)
    assert commander.spin_until(
        lambda: any(m.number_of_recoveries >= 1 for _, m in commander.feedback), 30.0
    ), 'no recovery in the feedback'
    assert re.search(
        r'replanning \(recovery 1\) at \(.*\): strayed', navigator.log_path.read_text()
    )
    cancel = handle.cancel_goal_async()
    assert commander.spin_until(cancel.done, 10.0)
    assert commander.result(handle, timeout=30.0).status == GoalStatus.STATUS_CANCELED


def test_errors_end_the_goal_with_nav2s_codes_and_a_line(commander, node_processes):
    """A plan that fails carries the planner's code and reason; a frame that cannot be
    transformed, an unknown behaviour tree: Nav2 Kilted's navigator codes."""
    start_all(node_processes)
    commander.wait_until_active()

    def outcome(kind, goal):
        answer = commander.result(commander.send(kind, goal), timeout=60.0)
        return answer.status, answer.result.error_code, answer.result.error_msg

    status, code, message = outcome('to_pose', NavigateToPose.Goal(pose=stamped(80.0, 80.0)))
    assert (status, code) == (GoalStatus.STATUS_ABORTED, 204)  # GOAL_OUTSIDE_MAP
    assert message.startswith('planning failed (planner covert): ')
    status, code, message = outcome('to_pose', NavigateToPose.Goal(pose=stamped(-13.0, 0.0)))
    assert (status, code) == (GoalStatus.STATUS_ABORTED, 206), message  # GOAL_OCCUPIED: a wall
    status, code, message = outcome(
        'to_pose', NavigateToPose.Goal(pose=stamped(1.0, 1.0, frame='camera'))
    )
    assert (status, code) == (GoalStatus.STATUS_ABORTED, 9002)
    assert message == (
        "pose: header.frame_id 'camera': expected 'map' (or 'odom', 'base_link', transformed "
        "through the robot's pose)"
    )
    status, code, message = outcome(
        'to_pose', NavigateToPose.Goal(pose=stamped(-11.0, 0.0), behavior_tree='nav.xml')
    )
    assert (status, code) == (GoalStatus.STATUS_ABORTED, 9001)
    assert "behavior_tree 'nav.xml': this navigator runs no behaviour trees" in message
    # The learned policy is a planner id: without a policy file the planner server refuses it.
    status, code, message = outcome(
        'to_pose', NavigateToPose.Goal(pose=stamped(-11.0, 0.0), behavior_tree='policy')
    )
    assert (status, code) == (GoalStatus.STATUS_ABORTED, 201)  # INVALID_PLANNER
    assert message.startswith('planning failed (planner policy): planner policy: no policy file')
    status, code, message = outcome(
        'through', NavigateThroughPoses.Goal(poses=[stamped(-11.0, 0.0), stamped(80.0, 0.0)])
    )
    assert (status, code) == (GoalStatus.STATUS_ABORTED, 304)  # the through-poses planner's
    waypoints = FollowWaypoints.Goal(poses=[stamped(80.0, 0.0), stamped(-11.5, 0.0)])
    answer = commander.result(commander.send('waypoints', waypoints), timeout=120.0)
    assert answer.status == GoalStatus.STATUS_ABORTED  # stop_on_failure, as Nav2's default
    missed = answer.result.missed_waypoints
    assert [(m.index, m.error_code) for m in missed] == [(0, 204)]
    assert answer.result.error_msg.startswith('waypoint 0: planning failed')


def test_through_poses_and_waypoints_on_the_covert_way(commander, node_processes):
    """Poses along the covert way to the hard goal: NavigateThroughPoses passes them in order
    (number_of_poses_remaining counts down), FollowWaypoints visits each (current_waypoint)."""
    scenario, *_ = start_all(node_processes)
    commander.wait_until_active()
    points, _ = optimal_path(scenario, 'hard')
    via = [stamped(*points[k]) for k in (4, 8)]
    handle = commander.send('through', NavigateThroughPoses.Goal(poses=via))
    answer = commander.result(handle, timeout=300.0)
    assert answer.status == GoalStatus.STATUS_SUCCEEDED, answer.result.error_msg
    remaining = [m.number_of_poses_remaining for _, m in commander.feedback]
    assert remaining[0] == 2 and remaining[-1] == 1 and remaining == sorted(remaining)[::-1]
    x, y = commander.truths[-1][1:3]
    reach = scenario.goal_radius + 0.25  # the covert legs end within the goal radius
    assert math.dist((x, y), points[8]) <= reach

    back = [stamped(*points[k]) for k in (6, 3)]
    handle = commander.send('waypoints', FollowWaypoints.Goal(poses=back))
    answer = commander.result(handle, timeout=300.0)
    assert answer.status == GoalStatus.STATUS_SUCCEEDED, answer.result.error_msg
    assert list(answer.result.missed_waypoints) == []
    assert {m.current_waypoint for _, m in commander.feedback} == {0, 1}
    x, y = commander.truths[-1][1:3]
    assert math.dist((x, y), points[3]) <= reach


def _heard_by(node, topic: str, listener: str) -> bool:
    """Whether the graph shows ``topic`` published and ``listener`` subscribed to it."""
    publishers = node.get_publishers_info_by_topic(f'/{topic}')
    listeners = node.get_subscriptions_info_by_topic(f'/{topic}')
    return bool(publishers) and any(info.node_name == listener for info in listeners)


@pytest.mark.parametrize(
    ('topic', 'silent'),
    [
        ('odom', 'no /silent for 1 s (is the robot running?)'),
        ('amcl_pose', 'no /silent for 1 s (is the localisation running?)'),
    ],
)
def test_a_robot_whose_odom_or_amcl_pose_is_silent_aborts_the_goal(
    commander, node_processes, topic, silent
):
    scenario = load_scenario(find_scenario(SCENARIO))
    start_sim(node_processes, scenario, **SIM)
    start_planner(node_processes)
    # The navigator listens where nothing is published.
    navigator = start_navigator(
        node_processes, sensor_timeout=1.0, extra_args=['-r', f'{topic}:=silent']
    )
    wait_for_log(navigator, 'navigator ready', timeout=60.0)
    if topic == 'amcl_pose':
        # Odometry must flow first (it is judged first): on a loaded machine the simulator may
        # start publishing, or be discovered, after the navigator is ready.
        assert commander.spin_until(lambda: commander.truths, 60.0), 'the sim publishes nothing'
        assert commander.spin_until(lambda: _heard_by(commander.node, 'odom', 'bt_navigator'), 30)
        commander.spin_for(0.5)
    handle = commander.send('to_pose', NavigateToPose.Goal(pose=stamped(-11.0, 0.0)))
    answer = commander.result(handle, timeout=30.0)
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert (answer.result.error_code, answer.result.error_msg) == (9003, silent)


@pytest.mark.parametrize(
    ('param', 'line'),
    [
        ('feedback_rate:=0.0', 'not starting: parameter feedback_rate: Invalid parameter value'),
        ('planner_id:=""', 'not starting: parameter planner_id: expected a planner id'),
    ],
)
def test_a_bad_parameter_is_one_line_and_exit_code_2(node_processes, param, line):
    navigator = start_navigator(node_processes, extra_args=['-p', param])
    assert navigator.wait(30) == 2
    log = navigator.log_path.read_text()
    assert line in log and 'Traceback' not in log, log
