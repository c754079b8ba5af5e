"""Drives moved off walls: the least shift that gives the margin, bounded, corners where the
shifted lines cross, the path's end moved only towards the goal; and, on the shipped scenarios'
covert paths, the shifted legs stay in the light model's dark and in their lattice cells."""

import math

import numpy as np
import pytest
from stealth_core.clearance import LEVELS, Clearance, ClearanceSettings
from stealth_core.move_lattice import MoveLattice
from stealth_core.occupancy_map import OccupancyMap
from stealth_core.planners import optimal_path
from stealth_core.scenario import find_scenario, load_scenario
from stealth_core.task import StealthTask
from stealth_env.topic_moves import Pose
from stealth_nav2.leg_clearance import keep_clear
from stealth_nav2.path_following import (
    FollowSettings,
    LegKind,
    Move,
    PathFollower,
    TimedPose,
    legs_of,
)

RES = 0.05
SETTINGS = ClearanceSettings(robot_radius=0.2, margin=0.25, max_shift=0.2)


def room(walls, size=(4.0, 4.0)) -> OccupancyMap:
    """A free room (x 0..4, y 0..4) with occupied boxes (x0, y0, x1, y1) in metres."""
    data = np.zeros((round(size[1] / RES), round(size[0] / RES)), np.int8)
    for x0, y0, x1, y1 in walls:
        data[round(y0 / RES) : round(y1 / RES), round(x0 / RES) : round(x1 / RES)] = 100
    return OccupancyMap(data, RES, (0.0, 0.0, 0.0))


def path(*points):
    return [TimedPose(x, y, 0.0, 0.0) for x, y in points]


def drives(legs):
    return [(round(leg.x0, 3), round(leg.y0, 3), round(leg.x, 3), round(leg.y, 3))
            for leg in legs if leg.kind is LegKind.DRIVE]  # fmt: skip


def test_a_drive_along_a_wall_moves_off_it_by_the_least_shift_that_gives_the_margin():
    # A wall up to x = 1.15; the path north along x = 1.5: 0.35 m centre to wall, the disc
    # 0.15 m from it. Wanted: 0.45 m, so a shift of 0.1 m east (to the drive's right).
    clearance = Clearance(room([(0.0, 0.0, 1.15, 4.0)]), SETTINGS)
    legs = legs_of(path((1.5, 0.5), (1.5, 3.5)), Pose(1.5, 0.5, math.pi / 2), FollowSettings())
    assert clearance.level(1.5, 0.5, 1.5, 3.5) < LEVELS
    leg = legs[0]
    assert clearance.shift(leg.x0, leg.y0, leg.x, leg.y) == pytest.approx(-0.1)  # to the right
    shifted = keep_clear(legs, clearance, goal=(1.6, 3.5))
    assert drives(shifted) == [(1.5, 0.5, 1.6, 3.5)]  # from where the robot stands
    assert clearance.level(1.6, 0.5, 1.6, 3.5) == LEVELS


def test_a_drive_already_clear_is_driven_as_planned():
    clearance = Clearance(room([(0.0, 0.0, 0.5, 4.0)]), SETTINGS)
    legs = legs_of(path((2.0, 0.5), (2.0, 3.5)), Pose(2.0, 0.5, math.pi / 2), FollowSettings())
    assert keep_clear(legs, clearance, goal=(2.0, 3.5)) == legs
    assert keep_clear(legs, None) == legs


def test_in_a_narrow_corridor_the_drive_keeps_the_most_clearance_within_the_bound():
    # Walls at x <= 1.2 and x >= 1.9: the corridor's middle is x = 1.55, 0.35 m from each wall;
    # the full margin (0.45 m) fits nowhere. The path runs at x = 1.4: shifted as near the middle
    # as the levels tell, never beyond max_shift.
    clearance = Clearance(room([(0.0, 0.0, 1.2, 4.0), (1.9, 0.0, 4.0, 4.0)]), SETTINGS)
    legs = legs_of(path((1.4, 0.5), (1.4, 3.5)), Pose(1.4, 0.5, math.pi / 2), FollowSettings())
    shift = clearance.shift(legs[0].x0, legs[0].y0, legs[0].x, legs[0].y)
    assert -SETTINGS.max_shift <= shift < 0
    before = clearance.level(1.4, 0.5, 1.4, 3.5)
    assert before < clearance.level(1.4 - shift, 0.5, 1.4 - shift, 3.5) < LEVELS
    assert abs(1.4 - shift - 1.55) <= 0.05


def test_perpendicular_drives_meet_where_their_shifted_lines_cross_within_the_nodes_cell():
    # North along a west wall, then east along a north wall: the corner (1.5, 3.0) moves east
    # and south, each by its drive's own shift (the north wall across the first drive's end is
    # the second one's business).
    walls = [(0.0, 0.0, 1.15, 4.0), (0.0, 3.35, 4.0, 4.0)]
    clearance = Clearance(room(walls), SETTINGS)
    poses = path((1.5, 0.5), (1.5, 3.0), (3.5, 3.0))
    legs = keep_clear(legs_of(poses, Pose(1.5, 0.5, math.pi / 2), FollowSettings()), clearance,
                      goal=(3.5, 3.0))  # fmt: skip
    (_, _, cx, cy), (sx, sy, ex, ey) = drives(legs)
    assert (cx, cy) == (sx, sy)
    assert cx == pytest.approx(1.6) and cy == pytest.approx(2.9)
    assert (ex, ey) == (3.5, 3.0)  # the path's end: shifted, it would be further from the goal
    half_step = 0.25
    assert abs(cx - 1.5) < half_step and abs(cy - 3.0) < half_step


def test_the_last_drive_ends_shifted_only_when_that_is_no_further_from_the_goal():
    clearance = Clearance(room([(0.0, 0.0, 1.15, 4.0)]), SETTINGS)
    legs = legs_of(path((1.5, 0.5), (1.5, 3.5)), Pose(1.5, 0.5, math.pi / 2), FollowSettings())
    towards = keep_clear(legs, clearance, goal=(2.0, 3.5))
    away = keep_clear(legs, clearance, goal=(1.0, 3.5))
    assert drives(towards)[-1][2:] == (1.6, 3.5)
    assert drives(away)[-1][2:] == (1.5, 3.5)


def test_turns_and_waits_move_with_the_drive_that_ends_there():
    clearance = Clearance(room([(0.0, 0.0, 1.15, 4.0), (0.0, 3.35, 4.0, 4.0)]), SETTINGS)
    poses = [TimedPose(1.5, 0.5, math.pi / 2, 0.0), TimedPose(1.5, 3.0, math.pi / 2, 5.0),
             TimedPose(1.5, 3.0, math.pi / 2, 9.0), TimedPose(1.5, 3.0, 0.0, 10.0),
             TimedPose(3.5, 3.0, 0.0, 14.0)]  # fmt: skip
    legs = keep_clear(legs_of(poses, Pose(1.5, 0.5, math.pi / 2), FollowSettings()), clearance,
                      goal=(3.5, 3.0))  # fmt: skip
    kinds = [leg.kind for leg in legs]
    assert kinds == [LegKind.WAIT, LegKind.DRIVE, LegKind.WAIT, LegKind.TURN, LegKind.DRIVE]
    corner = (legs[1].x, legs[1].y)
    assert corner == (pytest.approx(1.6), pytest.approx(2.9))
    for leg in legs[2:4]:
        assert (leg.x0, leg.y0, leg.x, leg.y) == (*corner, *corner)


def test_the_follower_drives_the_shifted_legs_and_ends_at_the_last_ones_end():
    clearance = Clearance(room([(0.0, 0.0, 1.15, 4.0)]), SETTINGS)
    poses = path((1.5, 0.5), (1.5, 3.5))
    follower = PathFollower(
        poses, Pose(1.5, 0.5, math.pi / 2), FollowSettings(),
        keep_clear=lambda legs: keep_clear(legs, clearance, (2.0, 3.5)),
    )  # fmt: skip
    move = follower.next_move(0.0)
    assert isinstance(move, Move)
    assert move.goal.target == (pytest.approx(1.6), pytest.approx(3.5))
    assert follower.end == (pytest.approx(1.6), pytest.approx(3.5))
    plain = PathFollower(poses, Pose(1.5, 0.5, math.pi / 2), FollowSettings())
    assert plain.end == (1.5, 3.5)


STATIC = [('lgfloor', goal) for goal in ('easy', 'medium', 'hard')] + [
    ('simple-maze', None), ('map1', None), ('floorplan', None)
]  # fmt: skip


@pytest.mark.parametrize(('name', 'goal'), STATIC)
def test_shifted_covert_paths_stay_dark_in_their_cells_and_clearer(name, goal):
    """The light model judges the shifted legs (sampled every 2 cm, at every heading the drive
    has) as the planner judged the path: below the detection threshold; every corner stays in
    its node's lattice cell; no drive keeps less clearance than planned."""
    scenario = load_scenario(find_scenario(name))
    goal = goal or scenario.default_goal
    task = StealthTask(scenario, goal)
    points, _ = optimal_path(scenario, goal)
    poses = [TimedPose(x, y, 0.0, float(k)) for k, (x, y) in enumerate(points)]
    legs = legs_of(poses, Pose(*scenario.start), FollowSettings())
    clearance = Clearance(scenario.map, ClearanceSettings(scenario.robot_radius, 0.25, 0.2))
    shifted = keep_clear(legs, clearance, (task.goal.x, task.goal.y))
    lattice = MoveLattice.from_scenario(scenario)
    peak = 0.0
    for old, new in zip(legs, shifted, strict=True):
        assert lattice.point_to_node(new.x, new.y) == lattice.point_to_node(old.x, old.y)
        if new.kind is not LegKind.DRIVE:
            continue
        assert clearance.level(new.x0, new.y0, new.x, new.y) >= clearance.level(
            old.x0, old.y0, old.x, old.y)  # fmt: skip
        samples = max(2, math.ceil(math.dist((new.x0, new.y0), (new.x, new.y)) / 0.02))
        for s in np.linspace(0.0, 1.0, samples + 1):
            x, y = new.x0 + s * (new.x - new.x0), new.y0 + s * (new.y - new.y0)
            peak = max(peak, task.visibility(x, y, 0.0, new.heading))
    assert peak < scenario.detection_threshold, f'{name} {goal}: visibility {peak:.3f}'
    assert math.dist((shifted[-1].x, shifted[-1].y), (task.goal.x, task.goal.y)) <= (
        scenario.goal_radius + 1e-9
    )
