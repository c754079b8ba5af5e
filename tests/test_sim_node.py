"""System tests of stealth_sim's sim_node: a real process on a private domain, driven over DDS
from the test process (topics, frames, the motion services, /initialpose, /cmd_vel,
parameters)."""

import math

from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
from nav_msgs.msg import OccupancyGrid, Odometry
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_support import REPO_ROOT, SpinningNode
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from stealth_core.occupancy_map import OCCUPIED, OccupancyMap, save_map
from stealth_interfaces.srv import ExecuteMove, ResetRobot

SIM_NODE = REPO_ROOT / 'ros2_ws/install/stealth_sim/lib/stealth_sim/sim_node'
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
START = (2.0, 2.0, 0.0)
BEAMS = 90


@pytest.fixture
def map_yaml(tmp_path):
    """An 8 x 6 m room (walls one cell thick) split by a wall at y = 3 with a door at x 4-5."""
    cells = np.zeros((120, 160), np.int8)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = OCCUPIED
    cells[60, :] = OCCUPIED
    cells[60, 80:100] = 0
    cells[20:30, 120:140] = OCCUPIED  # a cupboard to localise against
    return save_map(OccupancyMap(cells, 0.05, (0.0, 0.0, 0.0)), tmp_path / 'room')


def yaw_of(orientation) -> float:
    return 2.0 * math.atan2(orientation.z, orientation.w)


class SimClient(SpinningNode):
    """The test's side of the simulator: topic buffers, service calls, a parameter client."""

    def __init__(self, context):
        super().__init__('sim_test_client', context)
        self.received = {name: [] for name in ('map', 'odom', 'truth', 'scan', 'clock', 'pose')}
        for message_type, topic, key, qos in (
            (OccupancyGrid, 'map', 'map', LATCHED),
            (Odometry, 'odom', 'odom', 10),
            (Odometry, 'ground_truth', 'truth', 10),
            (LaserScan, 'scan', 'scan', 10),
            (Clock, 'clock', 'clock', 10),
            (PoseWithCovarianceStamped, 'amcl_pose', 'pose', LATCHED),
        ):
            self.node.create_subscription(message_type, topic, self.received[key].append, qos)
        self.move_client = self.node.create_client(ExecuteMove, 'sim/execute_move')
        self.reset_client = self.node.create_client(ResetRobot, 'sim/reset')
        self.cmd_vel = self.node.create_publisher(Twist, 'cmd_vel', 10)
        self.initial_pose = self.node.create_publisher(
            PoseWithCovarianceStamped, 'initialpose', 10
        )
        self.parameters = AsyncParameterClient(self.node, 'simulator')

    def wait_for_simulator(self, process) -> None:
        """Until both services answer: a move of no distance and a reset to no number are
        rejected and change nothing (see SpinningNode.handshake for why readiness is not
        enough)."""
        answers = self.handshake(
            {
                'move': (self.move_client, ExecuteMove.Request(kind=ExecuteMove.Request.UP)),
                'reset': (self.reset_client, ResetRobot.Request(x=math.nan, y=math.nan)),
            },
            30.0,
        )
        assert len(answers) == 2, f'the services never came up:\n{process.log_path.read_text()}'

    def call(self, client, request, timeout: float = 30.0):
        future = client.call_async(request)
        assert self.spin_until(future.done, timeout), 'no answer from the simulator'
        return future.result()

    def move(self, kind: int, distance: float = 0.0, heading: float = 0.0, seconds: float = 0.0):
        request = ExecuteMove.Request(
            kind=kind, distance=distance, heading=heading, seconds=seconds
        )
        return self.call(self.move_client, request)

    def reset(self, x: float, y: float, yaw: float, covariance=(0.0,) * 9):
        request = ResetRobot.Request(x=x, y=y, yaw=yaw, covariance=list(covariance))
        return self.call(self.reset_client, request)

    def set_parameter(self, name, value):
        future = self.parameters.set_parameters([Parameter(name, value=value)])
        assert self.spin_until(future.done, 10.0)
        return future.result().results[0]

    def latest_truth(self) -> tuple[float, float]:
        position = self.received['truth'][-1].pose.pose.position
        return position.x, position.y


@pytest.fixture
def client(node_processes, ros_context):
    """Set up after (so torn down before) node_processes, which checks for leftovers."""
    sim_client = SimClient(ros_context)
    yield sim_client
    sim_client.close()


def start_sim(node_processes, map_yaml, name='sim_node', **params):
    """Start sim_node on the test map; a parameter given as None is left out."""
    assert SIM_NODE.exists(), f'{SIM_NODE} is missing: colcon build --packages-select stealth_sim'
    args = [str(SIM_NODE), '--ros-args']
    defaults = {'map': map_yaml, 'initial_pose': list(START), 'laser_beams': BEAMS}
    for key, value in {**defaults, 'publish_rate': 20.0, **params}.items():
        if value is None:
            continue
        args += ['-p', f'{key}:={value}']
    return node_processes.start(args, name, extra_env={'RCUTILS_LOGGING_BUFFERED_STREAM': '0'})


def test_topics_carry_the_documented_frames_and_the_map_is_latched(
    client, node_processes, map_yaml
):
    process = start_sim(node_processes, map_yaml)
    client.wait_for_simulator(process)
    assert client.spin_until(lambda: client.received['map'] and client.received['pose'], 10.0)
    grid = client.received['map'][0]
    assert (grid.header.frame_id, grid.info.width, grid.info.height) == ('map', 160, 120)
    assert grid.info.resolution == pytest.approx(0.05)
    assert list(grid.data[:3]) == [100, 100, 100] and grid.data[161] == 0

    answer = client.move(ExecuteMove.Request.UP, 0.5)
    assert answer.outcome == ExecuteMove.Response.DONE
    end = answer.stamp.sec + answer.stamp.nanosec * 1e-9
    received = client.received

    def stamp_of(message) -> float:
        return message.header.stamp.sec + message.header.stamp.nanosec * 1e-9

    # Everything the move's end publishes has arrived (topics arrive in no fixed order).
    assert client.spin_until(
        lambda: (
            all(
                received[k] and stamp_of(received[k][-1]) == end for k in ('odom', 'truth', 'scan')
            )
            and received['clock']
            and received['clock'][-1].clock == answer.stamp
        ),
        5.0,
    )
    odom, truth, scan = received['odom'][-1], received['truth'][-1], received['scan'][-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')
    assert (truth.header.frame_id, truth.child_frame_id) == ('map', 'base_link')
    assert scan.header.frame_id == 'base_link' and len(scan.ranges) == BEAMS
    assert scan.angle_increment == pytest.approx(2 * math.pi / BEAMS)
    # Facing +y from (2, 2.5): the wall at y = 3 (cells from 3.0) is 0.5 m ahead of the robot.
    ahead = scan.ranges[
        round(
            (math.pi / 2 - yaw_of(truth.pose.pose.orientation) - scan.angle_min)
            / scan.angle_increment
        )
    ]
    assert ahead == pytest.approx(3.0 - truth.pose.pose.position.y, abs=0.1)
    pose = received['pose'][-1]
    assert pose.header.frame_id == 'map'
    covariance = np.array(pose.pose.covariance).reshape(6, 6)
    assert np.all(np.diag(covariance)[[0, 1, 5]] > 0) and np.all(np.diag(covariance)[2:5] == 0)
    stamps = [c.clock.sec + c.clock.nanosec * 1e-9 for c in received['clock']]
    assert stamps == sorted(stamps) and stamps[-1] > 1.0
    assert stamp_of(truth) == pytest.approx(stamps[-1], abs=1e-9)


def test_moves_resets_and_bad_requests(client, node_processes, map_yaml):
    process = start_sim(node_processes, map_yaml)
    client.wait_for_simulator(process)

    done = client.move(ExecuteMove.Request.RIGHT, 0.5)
    assert done.outcome == ExecuteMove.Response.DONE and done.message == '' and done.duration > 0
    assert done.true_pose.position.x == pytest.approx(2.5, abs=0.1)
    assert done.estimate.pose.position.x == pytest.approx(2.5, abs=0.1)
    assert done.stamp.sec + done.stamp.nanosec * 1e-9 >= done.duration

    turned = client.move(ExecuteMove.Request.TURN_TO_HEADING, heading=math.pi)
    assert turned.outcome == ExecuteMove.Response.DONE
    assert (
        abs(math.remainder(yaw_of(turned.estimate.pose.orientation) - math.pi, 2 * math.pi)) < 0.05
    )

    held = client.move(ExecuteMove.Request.HOLD, seconds=2.0)
    assert (held.outcome, held.duration) == (ExecuteMove.Response.DONE, pytest.approx(2.0))
    stamp = lambda answer: answer.stamp.sec + answer.stamp.nanosec * 1e-9  # noqa: E731
    assert stamp(held) == pytest.approx(stamp(turned) + 2.0)
    assert held.true_pose.position.x == pytest.approx(turned.true_pose.position.x, abs=1e-4)

    bumped = client.move(ExecuteMove.Request.DRIVE_DISTANCE, 4.0)  # the west wall is 2.45 m away
    assert bumped.outcome == ExecuteMove.Response.BUMPED and 'wall' in bumped.message
    assert bumped.true_pose.position.x == pytest.approx(0.05 + 0.2, abs=0.01)

    here = bumped.true_pose.position
    for kind, distance, heading, fragment in (
        (ExecuteMove.Request.UP, math.nan, 0.0, 'distance'),
        (ExecuteMove.Request.DOWN, -0.5, 0.0, 'distance'),
        (ExecuteMove.Request.LEFT, 1e9, 0.0, 'diagonal'),
        (ExecuteMove.Request.TURN_TO_HEADING, 0.0, math.inf, 'heading'),
        (ExecuteMove.Request.HOLD, 0.0, 0.0, 'seconds'),  # no seconds given
        (42, 0.5, 0.0, 'kind'),
    ):
        rejected = client.move(kind, distance, heading)
        assert rejected.outcome == ExecuteMove.Response.REJECTED and fragment in rejected.message
        assert (rejected.true_pose.position.x, rejected.true_pose.position.y) == (here.x, here.y)
        assert rejected.duration == 0.0

    for args, fragment in (
        ((-1.0, 2.0, 0.0), 'outside the map'),
        ((3.0, 3.0, 0.0), 'inside a wall'),
        ((6.5, 1.25, 0.0), 'inside a wall'),  # in the cupboard
        ((2.0, 2.0, math.nan), 'yaw'),
    ):
        result = client.reset(*args)
        assert not result.success and fragment in result.message
    result = client.reset(2.0, 2.0, 0.0, covariance=[0.1, 0, 0, 0, -0.1, 0, 0, 0, 0.1])
    assert not result.success and 'covariance' in result.message
    still = client.move(ExecuteMove.Request.TURN_TO_HEADING, heading=math.pi)
    assert (still.true_pose.position.x, still.true_pose.position.y) == pytest.approx(
        (here.x, here.y)
    )

    assert client.reset(5.0, 4.5, -math.pi / 2).success
    down = client.move(ExecuteMove.Request.DOWN, 1.0)  # through the door
    assert down.outcome == ExecuteMove.Response.DONE
    assert (down.true_pose.position.x, down.true_pose.position.y) == pytest.approx(
        (5.0, 3.5), abs=0.1
    )
    assert process.poll() is None


def test_initialpose_reinitialises_localisation_like_amcl(client, node_processes, map_yaml):
    process = start_sim(node_processes, map_yaml)
    client.wait_for_simulator(process)
    assert client.spin_until(lambda: client.received['pose'], 10.0)
    guess = PoseWithCovarianceStamped()
    guess.header.frame_id = 'map'
    guess.pose.pose.position.x, guess.pose.pose.position.y = 2.3, 1.8
    guess.pose.pose.orientation.w = 1.0
    covariance = np.zeros((6, 6))
    covariance[0, 0] = covariance[1, 1] = 0.3**2
    covariance[5, 5] = 0.1**2
    guess.pose.covariance = covariance.ravel().tolist()
    before, odometry = len(client.received['pose']), len(client.received['odom'])
    client.initial_pose.publish(guess)
    assert client.spin_until(lambda: len(client.received['pose']) > before, 10.0)
    position = client.received['pose'][-1].pose.pose.position
    assert math.hypot(position.x - 2.3, position.y - 1.8) < 0.1
    # Only the estimate, while time stands still (nothing commands the robot): an odometry
    # more of the same period is a period more to a controller in lockstep (it answers twice,
    # and every later command acts a period late).
    client.spin_for(0.5)
    assert len(client.received['odom']) == odometry
    for kind in (ExecuteMove.Request.RIGHT, ExecuteMove.Request.UP, ExecuteMove.Request.LEFT) * 2:
        result = client.move(kind, 0.5)
    truth, estimate = result.true_pose.position, result.estimate.pose.position
    assert math.hypot(truth.x - estimate.x, truth.y - estimate.y) < 0.1


def test_cmd_vel_drives_until_it_goes_stale_and_nan_is_refused(client, node_processes, map_yaml):
    process = start_sim(node_processes, map_yaml, real_time_factor=1.0, cmd_vel_timeout=0.3)
    client.wait_for_simulator(process)
    assert client.spin_until(lambda: client.received['truth'], 10.0)

    nan = Twist()
    nan.linear.x = math.nan
    client.cmd_vel.publish(nan)
    client.spin_for(0.5)
    assert client.latest_truth() == pytest.approx(START[:2], abs=1e-9)

    forward = Twist()
    forward.linear.x = 0.4
    for _ in range(10):  # 1 s of key repeat
        client.cmd_vel.publish(forward)
        client.spin_for(0.1)
    moving = client.latest_truth()
    assert moving[0] > START[0] + 0.15 and moving[1] == pytest.approx(START[1], abs=1e-6)
    client.spin_for(1.0)  # the last command goes stale after 0.3 s; the robot brakes
    stopped = client.latest_truth()
    client.spin_for(0.5)
    assert client.latest_truth() == stopped
    assert client.received['truth'][-1].twist.twist.linear.x == 0.0
    assert stopped[0] < moving[0] + 0.4 * 0.3 + 0.1
    assert 'cmd_vel rejected' in process.log_path.read_text()


def test_parameters_are_range_checked_at_runtime(client, node_processes, map_yaml):
    process = start_sim(node_processes, map_yaml, initial_pose=None)  # the most open point
    client.wait_for_simulator(process)
    assert client.parameters.wait_for_services(timeout_sec=10.0)
    assert not client.set_parameter('max_linear_speed', 100.0).successful
    assert not client.set_parameter('max_linear_speed', math.nan).successful
    assert not client.set_parameter('real_time_factor', -1.0).successful
    assert not client.set_parameter('odom_alpha1', 2.0).successful
    assert 'read-only' in client.set_parameter('particles', 100).reason
    assert not client.set_parameter('max_linear_speed', 'fast').successful
    assert client.set_parameter('max_linear_speed', 0.25).successful
    slow = client.move(ExecuteMove.Request.RIGHT, 1.0)
    assert slow.outcome == ExecuteMove.Response.DONE and slow.duration > 1.0 / 0.25
    assert process.poll() is None


@pytest.mark.parametrize(
    ('params', 'expected'),
    [
        ({'map': None}, 'parameter map: required'),
        ({'initial_pose': [3.0, 3.0, 0.0]}, 'inside a wall'),
        ({'initial_pose': [1.0, 2.0]}, 'expected [x, y, yaw]'),
        ({'physics_dt': 5.0}, 'physics_dt'),
    ],
)
def test_bad_startup_parameters_stop_the_node_with_a_reason(
    node_processes, map_yaml, params, expected
):
    process = start_sim(node_processes, map_yaml, **params)
    assert process.wait(20) == 2
    assert expected in process.log_path.read_text()
