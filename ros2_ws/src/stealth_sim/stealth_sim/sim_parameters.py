"""The simulator node's parameters (sim_node declares them), importable without rclpy: an
orchestrator checks parameter names against them before it starts the node."""

import math

from stealth_core.kinematics import Limits
from stealth_node_kit.param_table import Param, Unset

from stealth_sim.laser import LaserConfig
from stealth_sim.localisation import FilterConfig
from stealth_sim.odometry_noise import MotionNoise
from stealth_sim.simulator import SimConfig

IDLE_PERIOD = 0.02  # s of wall time between idle ticks (50 Hz: teleop is smooth, idling cheap)
_DEFAULTS = SimConfig()
_NOISE = _DEFAULTS.odometry_noise
_LIMITS = _DEFAULTS.limits
_FILTER = _DEFAULTS.filter


UNIT = (0.0, 1.0)
START_UP = ('map', 'initial_pose')  # used once to build the simulator
PARAMETERS = {
    'map': Param('', 'Path to a nav2 map YAML (required).', read_only=True),
    'initial_pose': Param(
        Unset('DOUBLE_ARRAY'),
        'Start pose [x (m), y (m), yaw (rad)], map frame; unset: the most open point.',
        read_only=True,
    ),
    'physics_dt': Param(_DEFAULTS.physics_dt, 'Physics step (s).', (0.001, 0.1), True),
    'max_linear_speed': Param(_LIMITS.max_linear_speed, 'Speed limit (m/s).', (0.01, 5.0)),
    'max_angular_speed': Param(
        _LIMITS.max_angular_speed, 'Turn rate limit (rad/s).', (0.01, 10.0)
    ),
    'max_linear_accel': Param(_LIMITS.max_linear_accel, 'Accel. limit (m/s^2).', (0.01, 20.0)),
    'max_angular_accel': Param(_LIMITS.max_angular_accel, 'Accel. limit (rad/s^2).', (0.01, 50.0)),
    'robot_radius': Param(_DEFAULTS.robot_radius, 'Robot disc radius (m).', (0.0, 1.0), True),
    'odom_alpha1': Param(_NOISE.alpha1, 'Odometry rotation noise from rotation.', UNIT),
    'odom_alpha2': Param(_NOISE.alpha2, 'Odometry rotation noise from translation.', UNIT),
    'odom_alpha3': Param(_NOISE.alpha3, 'Odometry translation noise from translation.', UNIT),
    'odom_alpha4': Param(_NOISE.alpha4, 'Odometry translation noise from rotation.', UNIT),
    'laser_beams': Param(_DEFAULTS.laser.beams, 'Beams of the 360-degree scan.', (3, 3600), True),
    'laser_range': Param(_DEFAULTS.laser.range_max, 'Laser range (m).', (0.5, 100.0), True),
    'laser_noise': Param(_DEFAULTS.laser.noise_std, 'Laser range noise, std. dev. (m).', UNIT),
    'particles': Param(_DEFAULTS.filter.particles, 'Filter particles.', (10, 100_000), True),
    'update_min_d': Param(_FILTER.update_min_d, 'AMCL update distance (m).', (0.0, 5.0), True),
    'update_min_a': Param(_FILTER.update_min_a, 'AMCL update turn (rad).', (0.0, math.pi), True),
    'seed': Param(_DEFAULTS.seed, 'Seed of every random stream.', (0, 2**31 - 1), True),
    'real_time_factor': Param(
        0.0,
        'Simulated s per wall s; 0: as fast as possible (service moves) or as the cmd_vel '
        'publisher answers each odometry (lockstep, 1x once nobody answers; see sim_node Time).',
        (0.0, 1000.0),
    ),
    'cmd_vel_timeout': Param(0.5, 'Drop a cmd_vel older than this (s, simulated).', (0.01, 60.0)),
    'publish_rate': Param(
        10.0,
        'Rate of odom, ground_truth, scan, clock, tf (Hz of simulated time; at '
        'real_time_factor 0 under cmd_vel, one control period per answer).',
        (0.1, 1000.0),
    ),
    'idle_period': Param(
        IDLE_PERIOD,
        'Wall s between ticks of time between moves (with real_time_factor > 0 under cmd_vel, '
        'the control period of a robot driven over topics is this times the factor).',
        (0.001, 1.0),
        True,
    ),
}


def sim_config(values: dict) -> SimConfig:
    """The simulator configuration the parameter values describe (ValueError when invalid)."""
    return SimConfig(
        physics_dt=values['physics_dt'],
        limits=Limits(
            values['max_linear_speed'],
            values['max_angular_speed'],
            values['max_linear_accel'],
            values['max_angular_accel'],
        ),
        robot_radius=values['robot_radius'],
        odometry_noise=MotionNoise(*(values[f'odom_alpha{i}'] for i in range(1, 5))),
        laser=LaserConfig(
            beams=values['laser_beams'],
            range_max=values['laser_range'],
            noise_std=values['laser_noise'],
        ),
        filter=FilterConfig(
            particles=values['particles'],
            update_min_d=values['update_min_d'],
            update_min_a=values['update_min_a'],
        ),
        seed=values['seed'],
    )
