"""The topics robot wakes for odometry only: amcl_pose (like scan, ground_truth and /clock)
waits in its queue until the next odometry message or housekeeping tick takes it, and is then
taken whole, none lost (stealth_node_kit.on_demand)."""

import math
import time

from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from stealth_env.topic_moves import TopicConfig
from stealth_env.topic_robot import ESTIMATE_QOS, TopicRobot
from stealth_node_kit.conversions import time_msg, yaw_quaternion


def _odometry(t: float, x: float) -> Odometry:
    message = Odometry()
    message.header.stamp = time_msg(t)
    message.header.frame_id = 'odom'
    message.pose.pose.position.x = x
    message.pose.pose.orientation = yaw_quaternion(0.0)
    return message


def _estimate(t: float, x: float, y: float) -> PoseWithCovarianceStamped:
    message = PoseWithCovarianceStamped()
    message.header.stamp = time_msg(t)
    message.header.frame_id = 'map'
    message.pose.pose.position.x, message.pose.pose.position.y = x, y
    message.pose.pose.orientation = yaw_quaternion(0.0)
    return message


def _spin(executor, done, timeout=10.0) -> None:
    deadline = time.monotonic() + timeout
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


def test_the_estimate_is_taken_with_the_next_odometry_or_tick(ros_context):
    import rclpy

    node = rclpy.create_node('topic_robot_queues', context=ros_context)
    robot = TopicRobot(node, TopicConfig(), 'map', None, None, 3, lambda: 60.0)
    odom = node.create_publisher(Odometry, 'odom', 10)
    estimate = node.create_publisher(PoseWithCovarianceStamped, 'amcl_pose', ESTIMATE_QOS)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        matched = (odom.get_subscription_count, estimate.get_subscription_count)
        _spin(executor, lambda: all(count() for count in matched))
        odom.publish(_odometry(1.0, 0.0))
        _spin(executor, lambda: robot.tracker.latest is not None)
        assert robot.tracker.latest.t == 1.0

        estimate.publish(_estimate(1.0, 2.0, 3.0))
        _spin(executor, lambda: False, timeout=0.5)
        assert not robot.ready()  # the executor did not wake for it: it waits in its queue

        odom.publish(_odometry(1.2, 0.1))
        _spin(executor, lambda: robot.tracker.latest.t == 1.2)
        assert robot.ready()  # taken before the odometry: placed at 1.0, carried forward
        placed = robot.tracker.estimate
        assert math.isclose(placed.x, 2.1) and math.isclose(placed.y, 3.0)

        for x in (5.0, 6.0):  # two while nothing takes them: both come, in order
            estimate.publish(_estimate(1.2, x, 3.0))
        _spin(executor, lambda: False, timeout=0.5)
        assert math.isclose(robot.tracker.estimate.x, 2.1)
        robot.tick()  # housekeeping takes them too
        assert math.isclose(robot.tracker.estimate.x, 6.0)
    finally:
        executor.remove_node(node)
        node.destroy_node()
