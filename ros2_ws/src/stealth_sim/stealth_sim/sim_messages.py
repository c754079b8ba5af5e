"""The simulator's messages, built from its core values (and the initial pose's covariance
read back): plain functions, so the node only decides when to send them."""

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Pose as PoseMsg
from geometry_msgs.msg import PoseWithCovariance, PoseWithCovarianceStamped, TransformStamped
from nav_msgs.msg import OccupancyGrid, Odometry
import numpy as np
from sensor_msgs.msg import LaserScan
from stealth_node_kit.conversions import time_msg, yaw_quaternion

from stealth_sim.frames import BASE_FRAME, MAP_FRAME, FrameTransform
from stealth_sim.kinematics import Pose
from stealth_sim.occupancy_map import OccupancyMap, to_occupancy_grid_data
from stealth_sim.simulator import Simulator

# Indices of x, y and yaw in a row-major 6x6 pose covariance (x, y, z, roll, pitch, yaw).
POSE_COVARIANCE_AXES = (0, 1, 5)


def pose_msg(pose: Pose) -> PoseMsg:
    result = PoseMsg(orientation=yaw_quaternion(pose.yaw))
    result.position.x, result.position.y = pose.x, pose.y
    return result


def pose_with_covariance(pose: Pose, covariance: np.ndarray) -> PoseWithCovariance:
    full = np.zeros((6, 6))
    full[np.ix_(POSE_COVARIANCE_AXES, POSE_COVARIANCE_AXES)] = covariance
    # An ndarray is taken as is; a list is checked element by element (measured: 5x slower).
    return PoseWithCovariance(pose=pose_msg(pose), covariance=full.ravel())


def planar_covariance(covariance_6x6) -> np.ndarray:
    return np.asarray(covariance_6x6, dtype=float).reshape(6, 6)[
        np.ix_(POSE_COVARIANCE_AXES, POSE_COVARIANCE_AXES)
    ]


def transform_msg(transform: FrameTransform, stamp: Time) -> TransformStamped:
    result = TransformStamped(child_frame_id=transform.child)
    result.header.stamp, result.header.frame_id = stamp, transform.parent
    pose = transform.pose
    result.transform.translation.x, result.transform.translation.y = pose.x, pose.y
    result.transform.rotation = yaw_quaternion(pose.yaw)
    return result


def occupancy_grid(occupancy_map: OccupancyMap) -> OccupancyGrid:
    grid = OccupancyGrid()
    grid.header.frame_id = MAP_FRAME
    grid.info.resolution = occupancy_map.resolution
    grid.info.width, grid.info.height = occupancy_map.width, occupancy_map.height
    x, y, yaw = occupancy_map.origin
    grid.info.origin = pose_msg(Pose(x, y, yaw))
    grid.data = to_occupancy_grid_data(occupancy_map)
    return grid


def odometry_message(sim: Simulator, frame: str, pose: Pose, stamp: Time) -> Odometry:
    """``pose`` of base_link in ``frame`` (odom: the noisy odometry; map: the ground truth),
    with the true body velocities."""
    message = Odometry(child_frame_id=BASE_FRAME)
    message.header.stamp, message.header.frame_id = stamp, frame
    message.pose.pose = pose_msg(pose)
    message.twist.twist.linear.x = sim.state.linear
    message.twist.twist.angular.z = sim.state.angular
    return message


def scan_message(sim: Simulator, stamp: Time, scan_time: float) -> LaserScan:
    """A scan of the laser at the robot's centre (base_link), drawn now."""
    laser = sim.config.laser
    scan = LaserScan(
        angle_min=laser.angle_min,
        angle_max=laser.angle_max,
        angle_increment=laser.angle_increment,
        scan_time=scan_time,
        range_min=laser.range_min,
        range_max=laser.range_max,
    )
    scan.header.stamp, scan.header.frame_id = stamp, BASE_FRAME
    scan.ranges = sim.scan().astype(np.float32).tolist()
    return scan


def estimate_message(sim: Simulator) -> PoseWithCovarianceStamped:
    """amcl_pose: the localisation's estimate in the map frame, at the simulated time."""
    message = PoseWithCovarianceStamped()
    message.header.stamp, message.header.frame_id = time_msg(sim.time), MAP_FRAME
    message.pose = pose_with_covariance(sim.estimate, sim.estimate_covariance)
    return message
