"""The simulator's messages, built from its core values (and the initial pose's covariance
read back): plain functions, and the messages of every control period kept for reuse
(:class:`StateMessages`), so the node only decides when to send them."""

import array

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Pose as PoseMsg
from geometry_msgs.msg import PoseWithCovariance, PoseWithCovarianceStamped, TransformStamped
from nav_msgs.msg import OccupancyGrid, Odometry
import numpy as np
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import LaserScan
from stealth_core.frames import BASE_FRAME, MAP_FRAME, ODOM_FRAME, FrameTransform
from stealth_core.kinematics import Pose
from stealth_core.occupancy_map import OccupancyMap, to_occupancy_grid_data
from stealth_node_kit.conversions import set_yaw, time_msg, yaw_quaternion
from tf2_msgs.msg import TFMessage

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


def occupancy_grid(occupancy_map: OccupancyMap) -> OccupancyGrid:
    grid = OccupancyGrid()
    grid.header.frame_id = MAP_FRAME
    grid.info.resolution = occupancy_map.resolution
    grid.info.width, grid.info.height = occupancy_map.width, occupancy_map.height
    x, y, yaw = occupancy_map.origin
    grid.info.origin = pose_msg(Pose(x, y, yaw))
    grid.data = to_occupancy_grid_data(occupancy_map)
    return grid


class StateMessages:
    """The messages the simulator publishes every control period (odom, ground_truth, scan,
    /tf, clock) and its amcl_pose, each built once and refilled in place: rclpy converts a
    message when it is published, so one object serves them all, and building them afresh
    (nested message objects, the scan's ranges checked value by value) was a tenth of the
    simulator's time per period when driven over cmd_vel (measured)."""

    def __init__(self, laser):
        self.odometry = {frame: _odometry(frame) for frame in (ODOM_FRAME, MAP_FRAME)}
        self.scan = _scan(laser)
        self.transforms = TFMessage(transforms=[TransformStamped(), TransformStamped()])
        self.clock = ClockMsg()
        self.estimate = PoseWithCovarianceStamped()
        self.estimate.header.frame_id = MAP_FRAME

    def odometry_of(self, sim: Simulator, frame: str, pose: Pose, stamp: Time) -> Odometry:
        """:func:`odometry_message`, in the one message kept for ``frame``."""
        return _fill_odometry(self.odometry[frame], sim, pose, stamp)

    def scan_of(self, sim: Simulator, stamp: Time, scan_time: float) -> LaserScan:
        """:func:`scan_message`, in the one scan kept."""
        return _fill_scan(self.scan, sim, stamp, scan_time)

    def transforms_of(self, tree, stamp: Time) -> TFMessage:
        """The /tf message of ``tree`` (``frames.robot_transforms``: its two transforms)."""
        for message, transform in zip(self.transforms.transforms, tree, strict=True):
            _fill_transform(message, transform, stamp)
        return self.transforms

    def clock_at(self, seconds: float) -> ClockMsg:
        self.clock.clock = time_msg(seconds)
        return self.clock

    def estimate_of(self, sim: Simulator) -> PoseWithCovarianceStamped:
        """:func:`estimate_message`, in the one message kept."""
        return _fill_estimate(self.estimate, sim)


def _set_pose(message: PoseMsg, pose: Pose) -> None:
    message.position.x, message.position.y = pose.x, pose.y
    set_yaw(message.orientation, pose.yaw)


def _odometry(frame: str) -> Odometry:
    message = Odometry(child_frame_id=BASE_FRAME)
    message.header.frame_id = frame
    return message


def _fill_odometry(message: Odometry, sim: Simulator, pose: Pose, stamp: Time) -> Odometry:
    message.header.stamp = stamp
    _set_pose(message.pose.pose, pose)
    twist = message.twist.twist
    twist.linear.x, twist.angular.z = sim.state.linear, sim.state.angular
    return message


def odometry_message(sim: Simulator, frame: str, pose: Pose, stamp: Time) -> Odometry:
    """``pose`` of base_link in ``frame`` (odom: the noisy odometry; map: the ground truth),
    with the true body velocities."""
    return _fill_odometry(_odometry(frame), sim, pose, stamp)


def _scan(laser) -> LaserScan:
    scan = LaserScan(
        angle_min=laser.angle_min,
        angle_max=laser.angle_max,
        angle_increment=laser.angle_increment,
        range_min=laser.range_min,
        range_max=laser.range_max,
    )
    scan.header.frame_id = BASE_FRAME
    return scan


def _fill_scan(scan: LaserScan, sim: Simulator, stamp: Time, scan_time: float) -> LaserScan:
    scan.header.stamp, scan.scan_time = stamp, scan_time
    # An array('f') is taken as is; a list is checked value by value.
    scan.ranges = array.array('f', sim.scan().astype(np.float32).tobytes())
    return scan


def scan_message(sim: Simulator, stamp: Time, scan_time: float) -> LaserScan:
    """A scan of the laser at the robot's centre (base_link), drawn now."""
    return _fill_scan(_scan(sim.config.laser), sim, stamp, scan_time)


def _fill_transform(
    message: TransformStamped, transform: FrameTransform, stamp: Time
) -> TransformStamped:
    message.header.stamp, message.header.frame_id = stamp, transform.parent
    message.child_frame_id = transform.child
    translation = message.transform.translation
    translation.x, translation.y = transform.pose.x, transform.pose.y
    set_yaw(message.transform.rotation, transform.pose.yaw)
    return message


def transform_msg(transform: FrameTransform, stamp: Time) -> TransformStamped:
    return _fill_transform(TransformStamped(), transform, stamp)


# Where a planar (x, y, yaw) covariance sits in the flat row-major 6x6 one.
_PLANAR_IN_FULL = np.array([6 * r + c for r in POSE_COVARIANCE_AXES for c in POSE_COVARIANCE_AXES])


def _fill_estimate(
    message: PoseWithCovarianceStamped, sim: Simulator
) -> PoseWithCovarianceStamped:
    message.header.stamp = time_msg(sim.time)
    _set_pose(message.pose.pose, sim.estimate)
    message.pose.covariance[_PLANAR_IN_FULL] = np.asarray(sim.estimate_covariance).ravel()
    return message


def estimate_message(sim: Simulator) -> PoseWithCovarianceStamped:
    """amcl_pose: the localisation's estimate in the map frame, at the simulated time."""
    message = PoseWithCovarianceStamped()
    message.header.frame_id = MAP_FRAME
    return _fill_estimate(message, sim)
