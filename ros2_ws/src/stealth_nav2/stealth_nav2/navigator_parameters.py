"""The navigator node's parameters (navigator_node declares them), importable without rclpy."""

from stealth_env.env_parameters import PARAMETERS as ENV_PARAMETERS
from stealth_node_kit.param_table import Param

from stealth_nav2.back_off import BackOffSettings
from stealth_nav2.navigation_goals import PLANNER_IDS
from stealth_nav2.path_following import FollowSettings

# The defaults of the settings the parameters make (navigator_node), written once, there.
_FOLLOW = FollowSettings()
_BACK_OFF = BackOffSettings()


def _moves(name: str, description: str) -> Param:
    """A parameter of the moves over topics: the navigator drives the robot with the
    environment's code (``env_parameters.topic_config``, ``TopicRobot``), so the environment's
    entry (default, range, read-only) under the navigator's own description."""
    return ENV_PARAMETERS[name]._replace(description=description)


PARAMETERS = {
    'planner_id': Param(
        'covert', "The planner server's planner id for a goal whose behavior_tree is '': "
        "covert (the covert optimum, time-aware where lights move), dark_path, astar or policy "
        '(the learned policy).',
    ),
    'planner_ids': Param(
        list(PLANNER_IDS), "The planner ids a goal's behavior_tree field may name instead.",
        read_only=True,
    ),
    'map_frame': Param('map', 'The global frame: plans, amcl_pose and feedback.', read_only=True),
    'odom_frame': Param('odom', "odom's frame: goals in it are transformed through the "
                        'localisation.', read_only=True),
    'robot_frame': Param('base_link', "The robot's frame: goals in it are relative to the robot.",
                         read_only=True),
    'feedback_rate': Param(5.0, 'Feedback messages per second of wall time.', (0.5, 100.0),
                           read_only=True),
    'sensor_timeout': Param(
        2.0, 'Wall-clock s without odom (or without amcl_pose while the robot drove '
        'localisation_travel on odom) that abort a navigation.', (0.1, 600.0),
    ),
    'localisation_travel': Param(
        1.0, 'm the robot may move on odom (from where it was at the last amcl_pose) without an '
        'amcl_pose before the localisation counts as silent (AMCL publishes only after moving '
        'update_min_d away).', (0.0, 100.0),
    ),
    'server_timeout': Param(
        5.0, 'Wall-clock s to wait for the planner server to be there.', (0.1, 600.0)
    ),
    'planner_timeout': Param(
        30.0, "Wall-clock s to wait for a plan (the planner server's answer).", (0.1, 3600.0)
    ),
    'max_recoveries': Param(
        5, 'Recoveries (blocked: back off and replan; strayed or timed out: replan) a goal '
        'may take before it is aborted.', (0, 1000)
    ),
    'max_lateness': Param(
        _FOLLOW.max_lateness,
        "s of the robot's clock a timed path's pose may be reached after its stamp (beyond "
        'the time the plan took) before the robot replans (not a recovery); half a step of the '
        'shipped moving-light scenarios.', (0.0, 3600.0),
    ),
    'back_off_distance': Param(
        _BACK_OFF.distance,
        "m a blocked robot drives straight backwards (Nav2's BackUp) before it replans, as "
        'the same recovery; 0: replan at once.', (0.0, 2.0),
    ),
    'back_off_speed': Param(_BACK_OFF.speed, 'm/s of the back-off.', (0.01, 1.0)),
    'back_off_from_nearest': Param(
        _BACK_OFF.turn_to_nearest,
        'Turn in place until the nearest return of the scan is dead ahead before backing '
        'off, so the back-off moves straight away from it (sideways off a wall met at an angle); '
        "false: straight back, as Nav2's BackUp.",
    ),
    'clearance_margin': Param(
        0.25, 'm the navigator keeps between the robot and walls beyond robot_radius, as far as '
        'moving each drive of the path sideways by up to clearance_shift gives it (the map from '
        'the map topic; the localisation may be this far off the truth); 0: drive the path as '
        'planned.', (0.0, 1.0),
    ),
    'clearance_shift': Param(
        0.2, 'm a drive of the path may be moved sideways off a wall: keep it under half the '
        "planner's lattice step, so each corner stays in its lattice node's cell (the light "
        'the planner judged); 0: drive the path as planned.', (0.0, 1.0),
    ),
    'lookahead_distance': Param(
        0.6, 'm ahead along a drive of the path the robot steers for when its estimate is off the '
        "drive's line (pure pursuit, as Nav2's Regulated Pure Pursuit lookahead_dist), rather "
        "than at the drive's far end.", (0.05, 5.0), read_only=True,
    ),
    'stray_distance': Param(
        _FOLLOW.stray_distance, 'm off the path that make the robot replan.', (0.05, 100.0)
    ),
    'goal_tolerance': Param(
        0.25, "m from the path's last pose that count as arrived (as Nav2's "
        "xy_goal_tolerance; the covert planner's path ends where its task counts the goal "
        'reached, within the scenario goal_radius).', (0.01, 10.0),
    ),
    'via_radius': Param(
        0.7, 'm from a NavigateThroughPoses pose that count as passing it (the covert '
        "planner's legs end within the scenario's goal_radius of each, 0.5 m in the shipped "
        'ones, plus localisation error).', (0.01, 10.0),
    ),
    'stop_on_failure': Param(
        True, 'FollowWaypoints: end at the first waypoint not reached (else go on to the next).'
    ),
    'localizer_state': Param(
        'amcl', "Also answer <this>/get_state (lifecycle_msgs/GetState: active once amcl_pose "
        "came) for nav2_simple_commander's waitUntilNav2Active; '' when a real lifecycle "
        'localiser runs.', read_only=True,
    ),
    'unresponsive_moves': _moves(
        'unresponsive_moves', 'Moves in a row that time out without the robot moving before it '
        'counts as not responding to cmd_vel.'
    ),
    'robot_radius': Param(
        0.2, 'm: the disc the scan check sweeps ahead (an obstacle it would touch before the '
        "leg's end stops the robot short of it, blocked: a recovery); the simulator's robot.",
        (0.0, 5.0), read_only=True,
    ),
    'bump_distance': _moves(
        'bump_distance', 'm to an obstacle in the scan that ends a move blocked.'
    ),
    'stall_time': _moves(
        'stall_time', "s (robot's clock) without progress while driving: blocked."
    ),
    'command_latency': _moves(
        'command_latency', 'When a command takes effect after the odom it answers, in odom '
        'periods: 1 a robot that takes it at its next control cycle, 0 a simulator in lockstep '
        "with its controller (stealth_sim's real_time_factor 0)."
    ),
    'max_linear_speed': _moves('max_linear_speed', "m/s (the robot's limit or lower)."),
    'max_angular_speed': _moves('max_angular_speed', 'rad/s.'),
    'max_linear_accel': _moves('max_linear_accel', 'm/s^2.'),
    'max_angular_accel': _moves('max_angular_accel', 'rad/s^2.'),
}  # fmt: skip
