"""The simulator's messages from its core values, and its parameters to a configuration."""

import math

from builtin_interfaces.msg import Time
import numpy as np
import pytest
from sim_test_maps import maze_map
from stealth_core.kinematics import Pose
from stealth_node_kit.conversions import quaternion_yaw
from stealth_sim.sim_messages import (
    estimate_message,
    occupancy_grid,
    odometry_message,
    planar_covariance,
    pose_with_covariance,
    scan_message,
)
from stealth_sim.sim_parameters import PARAMETERS, sim_config
from stealth_sim.simulator import SimConfig, Simulator


@pytest.fixture
def sim():
    return Simulator(maze_map(), SimConfig(), Pose(3.0, 2.0, 0.5))


def test_a_planar_covariance_goes_out_on_x_y_and_yaw_and_comes_back():
    covariance = np.array([[0.1, 0.01, 0.02], [0.01, 0.2, 0.03], [0.02, 0.03, 0.3]])
    message = pose_with_covariance(Pose(1.0, -2.0, math.pi / 3), covariance)
    full = np.asarray(message.covariance).reshape(6, 6)
    assert full[5, 5] == 0.3 and full[0, 1] == 0.01 and full[2, 2] == 0.0
    np.testing.assert_array_equal(planar_covariance(message.covariance), covariance)
    assert math.isclose(quaternion_yaw(message.pose.orientation), math.pi / 3)


def test_the_estimate_is_in_the_map_frame_at_the_simulated_time(sim):
    message = estimate_message(sim)
    assert message.header.frame_id == 'map'
    assert message.header.stamp.sec == int(sim.time)
    assert (message.pose.pose.position.x, message.pose.pose.position.y) == (
        sim.estimate.x,
        sim.estimate.y,
    )


def test_odometry_carries_the_pose_in_its_frame_and_the_body_velocities(sim):
    sim.step(0.3, 0.1)
    message = odometry_message(sim, 'odom', sim.odometry_pose, Time(sec=4))
    assert (message.header.frame_id, message.child_frame_id) == ('odom', 'base_link')
    assert message.pose.pose.position.x == sim.odometry_pose.x
    assert (message.twist.twist.linear.x, message.twist.twist.angular.z) == (
        sim.state.linear,
        sim.state.angular,
    )


def test_a_scan_has_a_range_per_beam_in_base_link(sim):
    scan = scan_message(sim, Time(sec=1), 0.1)
    assert scan.header.frame_id == 'base_link' and scan.scan_time == pytest.approx(0.1)
    assert len(scan.ranges) == sim.config.laser.beams


def test_the_map_message_keeps_the_map_layout():
    occupancy = maze_map()
    grid = occupancy_grid(occupancy)
    assert (grid.info.width, grid.info.height) == (occupancy.width, occupancy.height)
    assert len(grid.data) == occupancy.width * occupancy.height
    assert grid.header.frame_id == 'map'


def test_the_parameter_defaults_make_the_default_configuration():
    values = {name: param.default for name, param in PARAMETERS.items()}
    assert sim_config(values) == SimConfig()
    with pytest.raises(ValueError):
        sim_config({**values, 'physics_dt': -1.0})
