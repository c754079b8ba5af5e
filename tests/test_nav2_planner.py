"""System test of the covert planner server behind Nav2's planner interface: a real
planner_server (started with `stealth run`) on a private domain, called by plain rclpy action
clients the way nav2_simple_commander's getPath / getPathThroughPoses call Nav2's."""

import math
import os
import random
import signal
import sys
import time

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, TransformStamped
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
from nav_msgs.msg import OccupancyGrid, Path
import numpy as np
import pytest
from rclpy.action import ActionClient
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_support import REPO_ROOT, SpinningNode, wait_for_output
from stealth_core.lattice_model import LatticeModel
from stealth_core.occupancy_map import to_occupancy_grid_data
from stealth_core.planners import optimal_path
from stealth_core.scenario import load_scenario
from stealth_core.task import StealthTask
from stealth_env.env_messages import searchlight_array_msg
from stealth_interfaces.msg import SearchlightArray
from stealth_nav2.covert_planning import CovertPlanner, Pose
from stealth_nav2.plan_errors import PlanError
from stealth_nav2.scene_source import scene_from_scenario
from stealth_node_kit.conversions import quaternion_yaw, seconds, yaw_quaternion
from tf2_msgs.msg import TFMessage

STEALTH = str(
    REPO_ROOT / 'ros2_ws' / 'install' / 'stealth_tools' / 'lib' / 'stealth_tools' / 'stealth'
)
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
TO_POSE, THROUGH = ComputePathToPose.Result, ComputePathThroughPoses.Result


def stamped(x, y, yaw=0.0, frame='map') -> PoseStamped:
    pose = PoseStamped()
    pose.header.frame_id = frame
    pose.pose.position.x, pose.pose.position.y = float(x), float(y)
    pose.pose.orientation = yaw_quaternion(yaw)
    return pose


class PlannerClient(SpinningNode):
    """nav2_simple_commander's side: the two action clients, called as getPath calls them."""

    def __init__(self, context):
        super().__init__('planner_test_client', context)
        self.to_pose = ActionClient(self.node, ComputePathToPose, 'compute_path_to_pose')
        self.through = ActionClient(
            self.node, ComputePathThroughPoses, 'compute_path_through_poses'
        )
        self.plans: list[Path] = []
        self.node.create_subscription(Path, 'plan', self.plans.append, 10)
        self.parameters = AsyncParameterClient(self.node, 'planner_server')

    def wait_for_server(self, process) -> None:
        ready = self.spin_until(
            lambda: self.to_pose.server_is_ready() and self.through.server_is_ready(), 60.0
        )
        assert ready, f'no planner server; its log:\n{process.log_path.read_text()}'

    def _call(self, client, goal_msg):
        """_getPathImpl: send_goal_async, spin until accepted, get_result_async, spin."""
        sent = client.send_goal_async(goal_msg)
        assert self.spin_until(sent.done, 30.0)
        handle = sent.result()
        assert handle.accepted
        result = handle.get_result_async()
        assert self.spin_until(result.done, 60.0)
        return result.result().status, result.result().result

    def get_path(self, start, goal, planner_id='', use_start=True):
        goal_msg = ComputePathToPose.Goal(
            start=start, goal=goal, planner_id=planner_id, use_start=use_start
        )
        return self._call(self.to_pose, goal_msg)

    def get_path_through_poses(self, start, goals, planner_id='', use_start=True):
        goal_msg = ComputePathThroughPoses.Goal(
            start=start, goals=goals, planner_id=planner_id, use_start=use_start
        )
        return self._call(self.through, goal_msg)

    def set_parameter(self, name, value) -> None:
        future = self.parameters.set_parameters([Parameter(name, value=value)])
        assert self.spin_until(future.done, 10.0)
        assert future.result().results[0].successful


@pytest.fixture
def client(node_processes, ros_context):
    planner_client = PlannerClient(ros_context)
    yield planner_client
    planner_client.close()


def start_planner(node_processes, **params):
    args = [STEALTH, 'run', 'stealth_nav2', 'planner_server', '--ros-args']
    for key, value in params.items():
        args += ['-p', f'{key}:={value}']
    return node_processes.start(
        args, 'planner_server', extra_env={'RCUTILS_LOGGING_BUFFERED_STREAM': '0'}
    )


def lit_goal(scenario):
    """A point every lattice node within the goal radius of which is in the light."""
    model = LatticeModel.build(StealthTask(scenario))
    for x, y in model.points[model.seen]:
        near = np.hypot(model.points[:, 0] - x, model.points[:, 1] - y) <= scenario.goal_radius
        if model.seen[near].all():
            return float(x), float(y)
    raise AssertionError('no lit goal')


def failure(outcome, code):
    status, result = outcome
    assert status == GoalStatus.STATUS_ABORTED, result
    assert result.error_code == code, result.error_msg
    assert result.error_msg and '\n' not in result.error_msg
    assert not result.path.poses
    return result.error_msg


def test_lgfloor_hard_goal_is_the_optimum_and_every_error_is_named(client, node_processes):
    scenario = load_scenario('lgfloor')
    process = start_planner(node_processes, scenario='lgfloor')
    client.wait_for_server(process)
    start = stamped(*scenario.start)
    hard, medium = scenario.goals['hard'], scenario.goals['medium']

    status, result = client.get_path(start, stamped(hard.x, hard.y, 1.0))
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    assert result.error_code == TO_POSE.NONE
    points, optimum = optimal_path(scenario, 'hard')
    path = np.array([(p.pose.position.x, p.pose.position.y) for p in result.path.poses])
    assert np.array_equal(path, points)  # value iteration's node sequence, exactly
    assert result.path.header.frame_id == 'map'
    assert all(p.header.frame_id == 'map' for p in result.path.poses)
    assert math.isclose(quaternion_yaw(result.path.poses[-1].pose.orientation), 1.0)
    dx, dy = points[1] - points[0]
    assert math.isclose(quaternion_yaw(result.path.poses[0].pose.orientation), math.atan2(dy, dx))
    stamps = [p.header.stamp.sec + p.header.stamp.nanosec * 1e-9 for p in result.path.poses]
    assert np.allclose(np.diff(stamps), 1.0)  # one step a second (static lights)
    assert result.planning_time.sec > 0 or result.planning_time.nanosec > 0
    assert client.spin_until(lambda: client.plans, 5.0)
    assert len(client.plans[-1].poses) == len(points)

    status, result = client.get_path(start, stamped(hard.x, hard.y), 'GridBased')  # Nav2's id
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    assert np.array_equal(
        [(p.pose.position.x, p.pose.position.y) for p in result.path.poses], points
    )

    status, result = client.get_path_through_poses(
        start, [stamped(medium.x, medium.y), stamped(hard.x, hard.y)]
    )
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    first = optimal_path(scenario, 'medium')[0]
    through = np.array([(p.pose.position.x, p.pose.position.y) for p in result.path.poses])
    assert np.array_equal(through[: len(first)], first)

    # The errors, each with its Nav2 code and reason.
    goal = stamped(hard.x, hard.y)
    message = failure(client.get_path(start, stamped(500.0, 0.0)), TO_POSE.GOAL_OUTSIDE_MAP)
    assert 'goal (500.00, 0.00) is outside the map' in message
    message = failure(client.get_path(stamped(0.0, -500.0), goal), TO_POSE.START_OUTSIDE_MAP)
    assert 'start (0.00, -500.00) is outside the map' in message
    rows, cols = np.nonzero(scenario.map.occupied)
    wall = stamped(*scenario.map.cell_to_world(cols[0], rows[0]))
    assert 'occupied cell' in failure(client.get_path(start, wall), TO_POSE.GOAL_OCCUPIED)
    assert 'occupied cell' in failure(client.get_path(wall, goal), TO_POSE.START_OCCUPIED)
    lit = stamped(*lit_goal(scenario))
    assert 'no covert route' in failure(client.get_path(start, lit), TO_POSE.NO_VALID_PATH)
    message = failure(client.get_path(start, goal, 'astar'), TO_POSE.NO_VALID_PATH)
    assert 'is seen at' in message
    message = failure(client.get_path(start, goal, 'warp'), TO_POSE.INVALID_PLANNER)
    assert message.startswith(
        "planner id 'warp' is invalid; planner ids are: covert dark_path astar policy"
    )
    message = failure(client.get_path(start, goal, 'policy'), TO_POSE.INVALID_PLANNER)
    assert 'policy_file' in message
    message = failure(client.get_path_through_poses(start, []), THROUGH.NO_VIAPOINTS_GIVEN)
    assert 'no goals given' in message
    message = failure(
        client.get_path(start, stamped(hard.x, hard.y, frame='odom')), TO_POSE.TF_ERROR
    )
    assert "goal in frame 'odom'" in message and "to 'map'" in message
    message = failure(client.get_path(start, goal, use_start=False), TO_POSE.TF_ERROR)
    assert 'amcl_pose' in message

    # The robot's pose from amcl_pose, a goal in odom carried over /tf's map -> odom.
    amcl = client.node.create_publisher(PoseWithCovarianceStamped, 'amcl_pose', LATCHED)
    robot = PoseWithCovarianceStamped()
    robot.header.frame_id = 'map'
    robot.pose.pose = stamped(*scenario.start).pose
    amcl.publish(robot)
    tf = client.node.create_publisher(TFMessage, '/tf', 100)
    offset = TransformStamped()
    offset.header.frame_id, offset.child_frame_id = 'map', 'odom'
    offset.transform.translation.x, offset.transform.translation.y = 1.0, -2.0
    offset.transform.rotation = yaw_quaternion(0.0)

    def robot_path():
        tf.publish(TFMessage(transforms=[offset]))
        return client.get_path(start, stamped(hard.x - 1.0, hard.y + 2.0, frame='odom'), '', False)

    assert client.spin_until(lambda: client.parameters.wait_for_services(0.1), 10.0)
    for _ in range(20):  # until the transform and the pose have arrived
        status, result = robot_path()
        if status == GoalStatus.STATUS_SUCCEEDED:
            break
        client.spin_for(0.2)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    path = np.array([(p.pose.position.x, p.pose.position.y) for p in result.path.poses])
    assert np.array_equal(path, points)

    # Planning longer than max_planning_time: a new goal (nothing cached) answers TIMEOUT.
    client.set_parameter('max_planning_time', 1e-6)
    message = failure(client.get_path(start, stamped(medium.x + 0.5, medium.y)), TO_POSE.TIMEOUT)
    assert 'more than max_planning_time' in message


def test_moving_lights_stamp_each_pose_with_when_to_be_there(client, node_processes):
    """lgfloor-moving: the path from the request's time on the node's clock (less
    lights_time_offset) is the core's time-aware optimum from that time; pose k is stamped
    with the request's time plus the wait for the next bin of the lights' cycle plus k steps."""
    scene = scene_from_scenario('lgfloor-moving')
    scenario = scene.scenario
    process = start_planner(node_processes, scenario='lgfloor-moving', lights_time_offset=1000.0)
    client.wait_for_server(process)
    hard = scenario.goals['hard']
    status, result = client.get_path(stamped(*scenario.start), stamped(hard.x, hard.y))
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    asked = seconds(result.path.header.stamp)
    stamps = np.array([seconds(p.header.stamp) for p in result.path.poses])
    t = asked - 1000.0
    expected = CovertPlanner().plan(scene, Pose(*scenario.start), Pose(hard.x, hard.y), t=t)
    path = np.array([(p.pose.position.x, p.pose.position.y) for p in result.path.poses])
    assert np.array_equal(path, expected.poses[:, :2])
    assert np.allclose(stamps - asked, expected.times, atol=1e-6)
    assert np.allclose(np.diff(stamps), scenario.timing.step_seconds, atol=1e-6)


def test_scene_from_the_map_and_the_lights_topics(client, node_processes):
    scenario = load_scenario('simple-maze')
    process = start_planner(node_processes, robot_radius=scenario.robot_radius, step_limit=300)
    client.wait_for_server(process)
    start = stamped(*scenario.start)
    goal = stamped(scenario.goals['hard'].x, scenario.goals['hard'].y)
    message = failure(client.get_path(start, goal), TO_POSE.UNKNOWN)
    assert 'nothing on /map' in message and 'nothing on /searchlights' in message

    grid = OccupancyGrid()
    grid.header.frame_id = 'map'
    grid.info.width, grid.info.height = scenario.map.width, scenario.map.height
    grid.info.resolution = scenario.map.resolution
    grid.info.origin.position.x, grid.info.origin.position.y = scenario.map.origin[:2]
    grid.info.origin.orientation.w = 1.0
    grid.data = to_occupancy_grid_data(scenario.map)
    client.node.create_publisher(OccupancyGrid, 'map', LATCHED).publish(grid)
    lights = client.node.create_publisher(SearchlightArray, 'searchlights', LATCHED)
    lights.publish(searchlight_array_msg(scenario.lights, 0.0))
    for _ in range(50):
        status, result = client.get_path(start, goal)
        if status == GoalStatus.STATUS_SUCCEEDED:
            break
        client.spin_for(0.2)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    path = np.array([(p.pose.position.x, p.pose.position.y) for p in result.path.poses])
    model = LatticeModel.build(StealthTask(scenario, 'hard'))
    index = {tuple(p): i for i, p in enumerate(model.points)}
    places = [index[tuple(p)] for p in path]  # the scenario's lattice: same grid
    for i, j in zip(places, places[1:], strict=False):
        assert not model.step_seen[i, model.direction(i, j)]
    assert model.goal[places[-1]]


def test_a_missing_scenario_stops_the_server_with_one_line(node_processes):
    process = start_planner(node_processes, scenario='/nonexistent/nowhere.yaml')
    assert process.wait(30) != 0
    log = process.log_path.read_text()
    assert 'nowhere.yaml' in log and 'Traceback' not in log


def test_extreme_pose_fields_get_their_codes_never_a_traceback(client, node_processes):
    """Fields a start or goal may hold (1e308, the largest float, nan, inf, an orientation of
    length 0 or 14): each answered with its documented code and one line, or planned with the
    orientation normalised; (1e308, 1e308) gave an OverflowError traceback and code 0."""
    scenario = load_scenario('lgfloor')
    process = start_planner(node_processes, scenario='lgfloor')
    client.wait_for_server(process)
    start = stamped(*scenario.start)
    hard = scenario.goals['hard']

    def fields(x=hard.x, y=hard.y, z=0.0, q=(0.0, 0.0, 0.0, 1.0)):
        pose = stamped(x, y)
        pose.pose.position.z = z
        o = pose.pose.orientation
        o.x, o.y, o.z, o.w = q
        return pose

    big = sys.float_info.max
    for goal, words in (
        (fields(1e308, 1e308), 'goal (1e+308, 1e+308) is outside the map: expected x in'),
        (fields(-big, big), 'goal (-1.8e+308, 1.8e+308) is outside the map'),
        (fields(math.inf, 0.0), 'goal position.x is inf: expected a finite number'),
        (fields(z=math.nan), 'goal position.z is nan: expected a finite number'),
        (fields(q=(0.0, 0.0, 0.0, 0.0)), 'goal orientation is (0, 0, 0, 0): expected a rotation'),
        (fields(q=(0.0, 0.0, -math.inf, 1.0)), 'goal orientation.z is -inf'),
    ):
        assert words in failure(client.get_path(start, goal), TO_POSE.GOAL_OUTSIDE_MAP)
    message = failure(
        client.get_path(fields(-12.0, math.nan), fields()), TO_POSE.START_OUTSIDE_MAP
    )
    assert message.startswith('start position.y is nan')
    message = failure(
        client.get_path_through_poses(start, [fields(), fields(1e308, 0.0), fields()]),
        THROUGH.GOAL_OUTSIDE_MAP,
    )
    assert 'goal 2 of 3 (1e+308, 0.00) is outside the map' in message

    # A quaternion of any length but 0 is a rotation: normalised, as tf2 does (length 14, and
    # length ~1.4e308, both 90 degrees about z).
    for q in ((0.0, 0.0, 10.0, 10.0), (0.0, 0.0, 1e308, 1e308)):
        status, result = client.get_path(start, fields(q=q))
        assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
        assert math.isclose(quaternion_yaw(result.path.poses[-1].pose.orientation), math.pi / 2)

    # use_start false: the robot's pose from amcl_pose is checked the same way.
    amcl = client.node.create_publisher(PoseWithCovarianceStamped, 'amcl_pose', LATCHED)
    robot = PoseWithCovarianceStamped()
    robot.header.frame_id = 'map'
    robot.pose.pose = fields(q=(math.nan, 0.0, 0.0, 1.0)).pose
    amcl.publish(robot)
    for _ in range(50):  # until the pose has arrived
        status, result = client.get_path(start, fields(), use_start=False)
        if result.error_code != TO_POSE.TF_ERROR:
            break
        client.spin_for(0.1)
    message = failure((status, result), TO_POSE.START_OUTSIDE_MAP)
    assert message.startswith('start (amcl_pose) orientation.x is nan: expected a finite number')

    # A transform on /tf with such a field is kept out of the tree (it would carry nan into
    # every pose through it), with a warning.
    tf = client.node.create_publisher(TFMessage, '/tf', 100)
    broken = TransformStamped()
    broken.header.frame_id, broken.child_frame_id = 'map', 'odom'
    broken.transform.rotation.w = math.inf
    tf.publish(TFMessage(transforms=[broken]))
    wait_for_output(
        process, "/tf: transform 'map' -> 'odom' ignored: rotation.w is inf: expected", 10.0
    )
    goal = stamped(hard.x, hard.y, frame='odom')
    message = failure(client.get_path(start, goal), TO_POSE.TF_ERROR)
    assert "no transform from frame 'odom' to 'map'" in message
    assert process.poll() is None
    assert 'Traceback' not in process.log_path.read_text()


def covert_chain(scene, legs: int, seed: int) -> list[Pose]:
    """Unlit lattice points each reachable unseen from the last (from the scenario's start)."""
    planner = CovertPlanner()
    planner.prepare(scene)
    model = planner.model
    dark = [tuple(map(float, model.points[i])) for i in np.flatnonzero(~model.seen)]
    rng = random.Random(seed)
    chain, last = [], Pose(*scene.scenario.start)
    while len(chain) < legs:
        candidate = Pose(*rng.choice(dark))
        try:
            planner.plan(scene, last, candidate)
        except PlanError:
            continue
        chain.append(candidate)
        last = candidate
    return chain


def test_goals_wait_their_turn_while_one_is_planned(client, node_processes):
    """Goals are accepted while another is planned (Nav2's clients wait 20 ms for that) and run
    in the order they came; a waiting goal cancelled ends at once; a goal that finds
    max_queued_goals waiting is aborted at once (UNKNOWN, saying so)."""
    scene = scene_from_scenario('lgfloor')
    scenario = scene.scenario
    process = start_planner(node_processes, scenario='lgfloor', max_queued_goals=2)
    client.wait_for_server(process)
    start = stamped(*scenario.start)
    hard = scenario.goals['hard']
    long_goal = ComputePathThroughPoses.Goal(
        start=start, goals=[stamped(p.x, p.y) for p in covert_chain(scene, 150, 7)], use_start=True
    )
    ended = {}  # name -> (time, status, result)

    def send(action_client, name, goal_msg):
        handles = {}

        def on_response(future):
            handle = handles[name] = future.result()
            assert handle.accepted
            handle.get_result_async().add_done_callback(
                lambda done: ended.__setitem__(
                    name, (time.monotonic(), done.result().status, done.result().result)
                )
            )

        action_client.send_goal_async(goal_msg).add_done_callback(on_response)
        assert client.spin_until(lambda: name in handles, 5.0), f'{name}: no goal response'
        return handles[name]

    sent = time.monotonic()
    send(client.through, 'long', long_goal)
    to_hard = ComputePathToPose.Goal(start=start, goal=stamped(hard.x, hard.y), use_start=True)
    send(client.to_pose, 'first', to_hard)
    accepted_after = time.monotonic() - sent
    second = send(client.to_pose, 'second', to_hard)
    send(client.to_pose, 'third', to_hard)  # two wait already: refused
    second.cancel_goal_async()
    assert client.spin_until(lambda: len(ended) == 4, 60.0), ended
    order = sorted(ended, key=lambda name: ended[name][0])
    assert order[-2:] == ['long', 'first'], order  # the rest ended while 'long' was planned
    assert ended['long'][1] == ended['first'][1] == GoalStatus.STATUS_SUCCEEDED
    assert ended['second'][1] == GoalStatus.STATUS_CANCELED
    status, result = ended['third'][1:]
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == TO_POSE.UNKNOWN
    assert 'busy: 2 goals are waiting already (max_queued_goals 2)' in result.error_msg
    long_took = ended['long'][0] - sent
    assert accepted_after < long_took, (accepted_after, long_took)


def test_stopped_while_planning_it_exits_cleanly(client, node_processes):
    """Ctrl-C while a plan runs on the planning thread: the plan ends, the process exits 0 with
    no traceback (the job's done callback woke a destroyed executor's guard condition)."""
    scene = scene_from_scenario('lgfloor')
    process = start_planner(node_processes, scenario='lgfloor')
    client.wait_for_server(process)
    goals = [stamped(p.x, p.y) for p in covert_chain(scene, 200, 7)]
    goal_msg = ComputePathThroughPoses.Goal(
        start=stamped(*scene.scenario.start), goals=goals, use_start=True
    )
    sent = client.through.send_goal_async(goal_msg)
    assert client.spin_until(sent.done, 10.0) and sent.result().accepted
    client.spin_for(0.2)  # planning
    os.killpg(process.pid, signal.SIGINT)
    assert process.wait(30) == 0
    assert 'Traceback' not in process.log_path.read_text()
