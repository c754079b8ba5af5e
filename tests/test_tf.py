"""System test of the simulator's /tf: a real sim_node on a private domain, its transforms
received over DDS as RViz or Foxglove would (tf2_ros's TransformListener QoS), checked against
the estimate and the simulated time the motion service answers with."""

import math

from nav_msgs.msg import Odometry
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from stealth_core.frames import multiply
from stealth_core.kinematics import Pose, wrap_angle
from stealth_interfaces.srv import ExecuteMove
from stealth_sim.simulator import SimConfig
import test_sim_node
from test_sim_node import START, SimClient, start_sim
from tf2_msgs.msg import TFMessage

map_yaml = test_sim_node.map_yaml  # the fixture: test_sim_node's room with a door

PHYSICS_DT = SimConfig().physics_dt  # start_sim leaves it at its default
# tf2_ros's TransformListener: /tf reliable, volatile, depth 100.
TF_QOS = QoSProfile(
    depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE
)


class TfClient(SimClient):
    """The simulator's test client, also listening to /tf (and /tf_static, which stays empty)."""

    def __init__(self, context):
        super().__init__(context)
        self.tf: list[TFMessage] = []
        self.tf_static: list[TFMessage] = []
        self.node.create_subscription(TFMessage, '/tf', self.tf.append, TF_QOS)
        latched = QoSProfile(
            depth=1,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
        )
        self.node.create_subscription(TFMessage, '/tf_static', self.tf_static.append, latched)

    def transforms(self, parent: str, child: str) -> list:
        return [
            t
            for message in self.tf
            for t in message.transforms
            if (t.header.frame_id, t.child_frame_id) == (parent, child)
        ]


@pytest.fixture
def tf_client(node_processes, ros_context):
    """Set up after (so torn down before) node_processes, which checks for leftovers."""
    client = TfClient(ros_context)
    yield client
    client.close()


def seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def planar(transform) -> Pose:
    translation, rotation = transform.translation, transform.rotation
    assert translation.z == 0.0 and rotation.x == 0.0 and rotation.y == 0.0
    assert math.hypot(rotation.z, rotation.w) == pytest.approx(1.0, abs=1e-12)
    return Pose(translation.x, translation.y, 2.0 * math.atan2(rotation.z, rotation.w))


def test_tf_carries_map_odom_base_link_at_sim_time_composing_to_the_estimate(
    tf_client, node_processes, map_yaml
):
    client = tf_client
    process = start_sim(node_processes, map_yaml)
    client.wait_for_simulator(process)

    for kind in (ExecuteMove.Request.RIGHT, ExecuteMove.Request.UP):
        result = client.move(kind, 0.5)
        assert result.outcome == ExecuteMove.Response.DONE
        estimate = result.estimate.pose
        expected = Pose(
            estimate.position.x,
            estimate.position.y,
            2.0 * math.atan2(estimate.orientation.z, estimate.orientation.w),
        )

        # The move ends with a /tf stamped with the simulated time the service answers with,
        # and map -> odom * odom -> base_link is the estimate it answered. (A periodic /tf may
        # have the same stamp from before the final filter update: the last one counts.)
        def final_tf(stamp=result.stamp, expected=expected):
            at_end = [m for m in client.tf if m.transforms[0].header.stamp == stamp]
            if not at_end:
                return None
            composed = multiply(*(planar(t.transform) for t in at_end[-1].transforms))
            close = math.hypot(composed.x - expected.x, composed.y - expected.y) < 1e-6
            return at_end[-1] if close else None

        assert client.spin_until(final_tf, 5.0), (
            f'no /tf composing to the estimate at the end of the move: {client.tf[-3:]}'
        )
        final = final_tf()
        frames = [(t.header.frame_id, t.child_frame_id) for t in final.transforms]
        assert frames == [('map', 'odom'), ('odom', 'base_link')]
        map_odom, odom_base = (planar(t.transform) for t in final.transforms)
        composed = multiply(map_odom, odom_base)
        assert seconds(final.transforms[0].header.stamp) > 0.0
        assert composed.x == pytest.approx(expected.x, abs=1e-6)
        assert composed.y == pytest.approx(expected.y, abs=1e-6)
        assert abs(wrap_angle(composed.yaw - expected.yaw)) < 1e-6

    # Periodic /tf during the moves too: both transforms every time, stamps never going back,
    # each a whole number of physics steps of simulated time (not wall time).
    assert len(client.tf) >= 3
    stamps = []
    for message in client.tf:
        steps = seconds(message.transforms[0].header.stamp) / PHYSICS_DT
        assert steps == pytest.approx(round(steps), abs=1e-6)
        assert len({seconds(t.header.stamp) for t in message.transforms}) == 1
        assert {t.child_frame_id for t in message.transforms} == {'odom', 'base_link'}
        stamps.append(seconds(message.transforms[0].header.stamp))
    assert stamps == sorted(stamps) and stamps[-1] == seconds(result.stamp)
    # odom -> base_link is the odometry: it started at the start pose and stayed close to truth.
    first = planar(client.transforms('odom', 'base_link')[0].transform)
    assert (first.x, first.y) == pytest.approx(START[:2], abs=0.1)
    last = planar(client.transforms('odom', 'base_link')[-1].transform)
    assert (last.x, last.y) == pytest.approx((2.5, 2.5), abs=0.15)
    client.spin_for(0.5)
    assert not client.tf_static, 'no fixed frame: the laser sits at base_link'
    assert process.poll() is None


def test_tf_matches_odom_and_follows_a_reset(tf_client, node_processes, map_yaml):
    client = tf_client
    odometry: list[Odometry] = client.received['odom']
    process = start_sim(node_processes, map_yaml)
    client.wait_for_simulator(process)
    assert client.move(ExecuteMove.Request.RIGHT, 0.5).outcome == ExecuteMove.Response.DONE
    assert client.reset(5.0, 4.5, -math.pi / 2).success
    result = client.move(ExecuteMove.Request.DOWN, 1.0)  # through the door
    assert result.outcome == ExecuteMove.Response.DONE
    stamp = seconds(result.stamp)
    assert client.spin_until(
        lambda: (
            any(seconds(m.header.stamp) == stamp for m in odometry)
            and client.transforms('odom', 'base_link')
            and seconds(client.transforms('odom', 'base_link')[-1].header.stamp) == stamp
        ),
        5.0,
    )
    # odom -> base_link is exactly the pose the odom topic carries at the same stamp.
    odom = [m for m in odometry if seconds(m.header.stamp) == stamp][-1]
    tf = client.transforms('odom', 'base_link')[-1].transform
    assert (tf.translation.x, tf.translation.y) == (
        odom.pose.pose.position.x,
        odom.pose.pose.position.y,
    )
    assert tf.rotation == odom.pose.pose.orientation
    map_odom = planar(client.transforms('map', 'odom')[-1].transform)
    robot = multiply(map_odom, planar(tf))
    truth = result.true_pose.position
    assert math.hypot(robot.x - truth.x, robot.y - truth.y) < 0.1
    assert process.poll() is None
