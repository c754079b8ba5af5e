"""The environment node's parameters (env_node declares them), importable without rclpy: an
orchestrator checks parameter names against them before it starts the node."""

from stealth_node_kit import rl_contract
from stealth_node_kit.param_table import Param

from stealth_env.episode_flow import JUDGE_ON
from stealth_env.topic_moves import Limits, TopicConfig

ROBOT_INTERFACES = ('service', 'topics')
TRACKS = ('full', 'sensed')  # as gym_env.TRACKS (not imported: that pulls in gymnasium)
RESET_MODES = ('teleport', 'drive')
OBSERVATION_LAYOUTS = ('off', 'grid')  # grid_observation.observed_grid
# The string parameters with a fixed set of values (the node refuses any other).
CHOICES = {
    'judge_on': JUDGE_ON,
    'robot_interface': ROBOT_INTERFACES,
    'reset_mode': RESET_MODES,
    'track': TRACKS,
    'observation_layout': OBSERVATION_LAYOUTS,
}

PARAMETERS = {
    'scenario': Param(
        '',
        'Scenario (required): a name such as lgfloor (scenarios/ or $STEALTH_NAV_SCENARIOS) '
        'or the path of a scenario YAML.',
        read_only=True,
    ),
    'goal': Param('', "Goal pursued: easy, medium or hard; '' = the scenario's default.",
                  read_only=True),
    'track': Param(
        'full', "What the agent is told: 'full' (the state; the lights known) or 'sensed' (the "
        'lights unknown: the state, then what the robot sensed so far, stealth_env.sensed_track; '
        'the sensed field also on sensed_light).', read_only=True,
    ),
    'observation_layout': Param(
        'off', "Also send the agent an observation on rl_env/observation: 'grid' "
        '(stealth_core.grid_observation as GridObservation, latched; track full: once, the '
        'phased grid where lights move; track sensed, static lights: the belief whenever what '
        "was sensed changes; what the generalist reads) or 'off' (nothing: recordings stay "
        'small).', read_only=True,
    ),
    'judge_on': Param(
        'true',
        "Pose that visibility, detection and the goal are judged on: 'true' (the lights see "
        "the real robot) or 'estimate' (the original's estimate-only way). From the next step.",
    ),
    'seed': Param(0, "Seed of the random draws of 'probabilistic' detection.", (0, 2**31 - 1),
                  read_only=True),
    'move_timeout': Param(
        60.0, 'Wall-clock seconds to wait for an answer of sim/execute_move or sim/reset; a '
        'move without one ends the episode as ABORTED. topics: also the seconds without odom '
        'that fail a move, a drive home or a teleport (simulated seconds under use_sim_time).',
        (0.1, 3600.0)
    ),
    'clock_timeout': Param(
        10.0, 'topics under use_sim_time: wall-clock seconds without an advancing /clock that '
        'fail what the robot was doing (a move ends the episode as ABORTED, a teleport is tried '
        'again), rather than wait on a stopped simulator for ever.', (0.1, 3600.0)
    ),
    'marker_period': Param(
        1.0, 'Wall-clock seconds between updates of searchlights and searchlight_markers '
        '(moving lights drawn at the latest simulated time); 0 = publish once.', (0.0, 3600.0)
    ),
    'start_delay': Param(
        0.5, 'Wall-clock seconds to wait, once the simulator and an agent are there, before '
        'the first episode starts: time for recorders and viewers to connect, and for the '
        "agent's side of the DDS match (a writer sees a reader before the reader sees the "
        'writer, and a volatile first state sent in between is lost).', (0.0, 3600.0)
    ),
    'first_action_timeout': Param(
        10.0, "Wall-clock seconds to wait for the agent's answer to an episode's first state; "
        'without one the episode ends ABORTED before its first step (a terminal state and its '
        'summary put both sides in step again): after an agent restarts, DDS may deliver that '
        "volatile first state to the dead agent's reader alone until its lease ends. 0 = wait "
        'for ever (the rl_msgs way).', (0.0, 3600.0)
    ),
    'step_readers': Param(
        0, 'Episodes start only once rl_env/step_info is matched with at least this many '
        'readers. StepInfo is built only while someone reads it, so an environment whose '
        "writer DDS matched late would leave its first steps out of the run's scores and "
        'recording: stealth train sets its own readers (its monitor, its recorder) at every '
        'start.',
        (0, 1000)
    ),
    'publish_plan': Param(
        False, 'Publish planned_path (nav_msgs/Path, latched): the optimum by value iteration '
        'on the move lattice, for viewers; it takes a few seconds at startup.', read_only=True,
    ),
    'log_every': Param(100, 'Log a progress line every this many episodes (0 = never).',
                       (0, 2**31 - 1)),
    'first_episode': Param(
        0, "Number of the first episode (a respawned or resumed run's next one).",
        (0, 2**31 - 1), read_only=True,
    ),
    'robot_interface': Param(
        'service', "How moves reach the robot: 'service' (the simulator's sim/execute_move) or "
        "'topics' (closed loop over cmd_vel, odom, amcl_pose and scan: any ROS robot).",
        read_only=True,
    ),
    'reset_mode': Param(
        'teleport', "How an episode puts the robot back at the start: 'teleport' (call "
        "reset_service) or 'drive' (topics only: drive back along a collision-free path on the "
        'move lattice, lights ignored, then publish initialpose).', read_only=True,
    ),
    'reset_service': Param(
        rl_contract.RESET_ROBOT,
        'The teleport of reset_mode teleport: a stealth_interfaces/ResetRobot '
        'service.', read_only=True,
    ),
    'unresponsive_moves': Param(
        3, 'topics: after this many moves in a row timed out without the robot moving, the '
        'robot is not responding to cmd_vel: the episode is ABORTED and the node exits (3).',
        (1, 1000), read_only=True,
    ),
    'bump_distance': Param(
        0.05, 'topics: m to an obstacle in the way (laser scan) that ends a move BUMPED.',
        (0.0, 1.0), read_only=True,
    ),
    'stall_time': Param(
        1.0, "topics: s (robot's clock) without progress while driving that end a move BUMPED.",
        (0.05, 60.0), read_only=True,
    ),
    'command_latency': Param(
        1.0, 'topics: when a command takes effect after the odom it answers, in odom periods: '
        "1 a robot that takes it at its next control cycle, 0 a simulator in lockstep with the "
        "controller (stealth_sim's real_time_factor 0; stealth train sets it for topics runs).",
        (0.0, 1.0), read_only=True,
    ),
    'max_linear_speed': Param(
        Limits.max_linear_speed, "topics: the controller's speed limit (m/s; the robot's or "
        'lower, as the following three).', (0.01, 5.0), read_only=True,
    ),
    'max_angular_speed': Param(
        Limits.max_angular_speed, 'topics: turn rate limit (rad/s).', (0.01, 10.0),
        read_only=True,
    ),
    'max_linear_accel': Param(
        Limits.max_linear_accel, 'topics: acceleration limit (m/s^2).', (0.01, 20.0),
        read_only=True,
    ),
    'max_angular_accel': Param(
        Limits.max_angular_accel, 'topics: angular acceleration limit (rad/s^2).', (0.01, 50.0),
        read_only=True,
    ),
}  # fmt: skip


def not_a_choice(changes) -> str | None:
    """Why a change of a parameter with CHOICES is refused (None: none is)."""
    for change in changes:
        choices = CHOICES.get(change.name)
        if choices is not None and change.value not in choices:
            return f'{change.name} must be one of {", ".join(choices)}, got {change.value!r}'
    return None


def topic_config(values: dict, robot_radius: float) -> TopicConfig:
    """The moves of robot_interface topics, from the parameters' values."""
    names = ('max_linear_speed', 'max_angular_speed', 'max_linear_accel', 'max_angular_accel')
    return TopicConfig(
        limits=Limits(*(values[name] for name in names)),
        robot_radius=robot_radius,
        bump_distance=values['bump_distance'],
        stall_time=values['stall_time'],
        command_latency=values['command_latency'],
    )
