"""What a navigation goal asks, decided without rclpy: its frame, its planner (the goal's
``behavior_tree`` field), the poses of NavigateThroughPoses still ahead, FollowWaypoints'
sequence and the error codes a goal ends with.

Error codes are Nav2's: a plan that fails ends the goal with the planner's own code
(ComputePathToPose 200-208, ComputePathThroughPoses 300-309); a path the robot cannot follow
with FollowPath's (the controller server's, 100-107), as Nav2's BT navigator passes its servers'
codes on; what the navigator itself refuses with the codes Nav2 Kilted gives NavigateToPose
(9000-9003) and NavigateThroughPoses (9100-9103) (Jazzy's definitions have only NONE);
FollowWaypoints with its own (600, 601) and each missed waypoint with its navigation's code.
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import NamedTuple

from stealth_core.kinematics import Pose, compose, relative

from stealth_nav2.covert_planning import PLANNER_IDS

__all__ = ['PLANNER_IDS', 'Frames', 'ViaPoses', 'WaypointRun', 'goal_in_map', 'planner_for']

# Nav2 Kilted's NavigateToPose result codes; NavigateThroughPoses' are these + 100.
UNKNOWN = 9000
FAILED_TO_LOAD_BEHAVIOR_TREE = 9001
TF_ERROR = 9002
TIMEOUT = 9003
THROUGH_POSES_OFFSET = 100
# nav2_msgs/action/FollowPath's: the robot cannot follow the path.
FAILED_TO_MAKE_PROGRESS = 105
# nav2_msgs/action/FollowWaypoints'.
WAYPOINTS_UNKNOWN = 600


def navigator_code(code: int, through_poses: bool) -> int:
    """A navigator-level code (9000-9003) for NavigateToPose, or NavigateThroughPoses'."""
    return code + THROUGH_POSES_OFFSET if through_poses else code


def planner_for(behavior_tree: str, default: str, known: Sequence[str]) -> tuple[str, str]:
    """(planner id, '') for a goal's ``behavior_tree`` field, or ('', why not).

    This navigator runs no behaviour trees: the field selects the planner instead. '' is the
    navigator's ``planner_id``; a planner id (``policy``: the learned policy) selects it."""
    if not behavior_tree:
        return default, ''
    if behavior_tree in known:
        return behavior_tree, ''
    return '', (
        f"behavior_tree '{behavior_tree}': this navigator runs no behaviour trees; give '' "
        f'(the planner_id parameter, {default}) or a planner id: {", ".join(known)}'
    )


class Frames(NamedTuple):
    """The frames a goal may come in: the map, the odometry's and the robot's own."""

    map: str = 'map'
    odom: str = 'odom'
    robot: str = 'base_link'


def goal_in_map(
    frame: str, pose: Pose, frames: Frames, estimate: Pose | None, odom: Pose | None
) -> tuple[Pose | None, str]:
    """The goal in the map frame, or (None, why not). A goal in the odometry's frame goes
    through the localisation's correction (estimate (+) odom^-1, AMCL's map -> odom), one in the
    robot's frame is relative to the robot's estimate now."""
    if frame == frames.map:
        return pose, ''
    if frame in (frames.odom, frames.robot) and (estimate is None or odom is None):
        return None, f"frame '{frame}': no pose of the robot yet to transform it to '{frames.map}'"
    if frame == frames.odom:
        offset = relative(odom, pose)
        return compose(estimate, *offset), ''
    if frame == frames.robot:
        return compose(estimate, pose.x, pose.y, pose.yaw), ''
    return None, (
        f"header.frame_id '{frame}': expected '{frames.map}' (or '{frames.odom}', "
        f"'{frames.robot}', transformed through the robot's pose)"
    )


class ViaPoses:
    """The poses of a NavigateThroughPoses goal still ahead: passed in order once the robot
    comes within ``radius`` of the next one (Nav2's RemovePassedGoals)."""

    def __init__(self, poses: Sequence[Pose], radius: float):
        self.poses = list(poses)
        self.radius = radius

    def passed(self, estimate: Pose) -> bool:
        """Drop the next poses the robot has reached (never the last: that is the goal);
        whether any was."""
        dropped = False
        while len(self.poses) > 1 and math.dist(estimate[:2], self.poses[0][:2]) <= self.radius:
            self.poses.pop(0)
            dropped = True
        return dropped


class Missed(NamedTuple):
    """A waypoint FollowWaypoints did not reach: its index, and its navigation's code."""

    index: int
    error_code: int
    message: str


class WaypointRun:
    """FollowWaypoints' order: from ``goal_index``, each waypoint in turn, the whole list
    ``number_of_loops`` more times; a failed waypoint is missed, and ends the run when
    ``stop_on_failure`` (Nav2's waypoint_follower, whose default is to stop)."""

    def __init__(self, count: int, goal_index: int, loops: int, stop_on_failure: bool):
        self.count = count
        self.index = goal_index
        self.loops_left = loops
        self.stop_on_failure = stop_on_failure
        self.missed: list[Missed] = []

    def problem(self) -> str:
        if self.count == 0:
            return 'poses: no waypoints given'
        if self.index >= self.count:
            return f'goal_index {self.index}: expected less than the {self.count} waypoints'
        return ''

    def finished(self, succeeded: bool, error_code: int = 0, message: str = '') -> bool:
        """The current waypoint's navigation ended: whether the run is over (else ``index`` is
        the next waypoint)."""
        if not succeeded:
            self.missed.append(Missed(self.index, error_code, message))
            if self.stop_on_failure:
                return True
        self.index += 1
        if self.index < self.count:
            return False
        if self.loops_left == 0:
            return True
        self.loops_left -= 1
        self.index = 0
        return False
