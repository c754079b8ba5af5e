"""A planning request that gets no path: Nav2's error name and one line saying why (no rclpy).

The names are ``nav2_msgs/action/ComputePathToPose`` and ``ComputePathThroughPoses``'s result
constants; the node turns a name into the action's own code (``getattr(Result, name)``).
"""

# Nav2's error names (ComputePathToPose / ComputePathThroughPoses result constants).
ERROR_NAMES = (
    'UNKNOWN',
    'INVALID_PLANNER',
    'TF_ERROR',
    'START_OUTSIDE_MAP',
    'GOAL_OUTSIDE_MAP',
    'START_OCCUPIED',
    'GOAL_OCCUPIED',
    'TIMEOUT',
    'NO_VALID_PATH',
    'NO_VIAPOINTS_GIVEN',
)


class PlanError(Exception):
    """A request that gets no path: ``code`` is Nav2's error name, the message says why."""

    def __init__(self, code: str, message: str):
        if code not in ERROR_NAMES:
            raise ValueError(f'code: expected one of {", ".join(ERROR_NAMES)}, got {code!r}')
        super().__init__(message)
        self.code = code
