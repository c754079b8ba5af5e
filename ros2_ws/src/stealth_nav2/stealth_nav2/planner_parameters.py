"""The planner server's parameters (planner_node declares them), importable without rclpy: an
orchestrator can check a parameter file against them before it starts the node."""

import dataclasses

from stealth_core.planners import DEFAULT_DARK_PATH_WEIGHT
from stealth_node_kit.param_table import Param

from stealth_nav2.covert_planning import TaskNumbers

_TASK = TaskNumbers()
FROM_TOPICS = ' Scene from topics only (a scenario file brings its own).'
PARAMETERS = {
    'scenario': Param(
        '',
        'Scenario file (or name) giving the map and the lights; empty: the map topic '
        '(nav_msgs/OccupancyGrid) and the searchlights topic (stealth_interfaces/'
        'SearchlightArray) give them.',
        read_only=True,
    ),
    'policy_file': Param(
        '', "Tabular policy (.npz, saved by stealth train) for planner id 'policy'.",
        read_only=True,
    ),
    'max_planning_time': Param(
        5.0, 'Planning longer than this (s of wall time) answers TIMEOUT; 0: no limit.',
        (0.0, 3600.0),
    ),
    'path_resolution': Param(
        0.0,
        'Largest gap between path poses (m): poses are added along each lattice step for '
        "controllers that want a dense path (Nav2's costmap resolution, 0.05); 0: lattice "
        'nodes only.',
        (0.0, 10.0),
    ),
    'dark_path_weight': Param(
        DEFAULT_DARK_PATH_WEIGHT,
        "Planner id 'dark_path': metres of detour one unit of visibility is worth.",
        (0.0, 1e6),
    ),
    'max_queued_goals': Param(
        100,
        'Goals that may wait behind the one being planned, served in the order they came; a '
        'goal that finds them all taken is aborted at once (UNKNOWN, saying so).',
        (0, 100_000),
    ),
    'action_server_result_timeout': Param(
        10.0,
        "Seconds a goal's result is kept after the goal ended, for a client that asks for it "
        "late (Nav2's parameter and default; rclpy's own, 900 s, keeps every result of a busy "
        "quarter of an hour in memory).",
        (0.1, 86_400.0),
        read_only=True,
    ),
    'lights_time_offset': Param(
        0.0,
        "The lights' clock is the node's clock (use_sim_time honoured) minus this (s): where "
        'their motions stand at t = 0.',
        (-1e9, 1e9),
    ),
    'robot_radius': Param(_TASK.robot_radius, 'Robot radius (m).' + FROM_TOPICS, (0.0, 5.0), True),
    'step_distance': Param(
        _TASK.step_distance, 'Lattice step (m).' + FROM_TOPICS, (0.01, 10.0), True
    ),
    'goal_radius': Param(
        _TASK.goal_radius, 'Distance within which a goal is reached (m).' + FROM_TOPICS,
        (0.001, 10.0), True,
    ),
    'detection_threshold': Param(
        _TASK.detection_threshold, 'Visibility at which the robot is seen.' + FROM_TOPICS,
        (1e-6, 100.0), True,
    ),
    'step_limit': Param(
        _TASK.step_limit, 'Lattice steps per path leg.' + FROM_TOPICS, (1, 100_000), True
    ),
    'phase_bins': Param(
        _TASK.phase_bins, "Bins of moving lights' joint cycle." + FROM_TOPICS, (1, 10_000), True
    ),
    'step_seconds': Param(
        _TASK.step_seconds,
        'Seconds per lattice step where lights move; 0: one bin.' + FROM_TOPICS,
        (0.0, 3600.0), True,
    ),
}  # fmt: skip
TASK_PARAMETERS = tuple(field.name for field in dataclasses.fields(TaskNumbers))


def task_numbers(values: dict) -> TaskNumbers:
    """The TaskNumbers of the parameters' values."""
    return TaskNumbers(**{name: values[name] for name in TASK_PARAMETERS})
