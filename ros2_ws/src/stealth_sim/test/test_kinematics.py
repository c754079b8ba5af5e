"""Unicycle integration, velocity and acceleration limits, and collision without tunnelling."""

import math

import numpy as np
import pytest
from sim_test_maps import RESOLUTION, as_map, room
from stealth_core.kinematics import (
    DiscFootprint,
    Limits,
    Pose,
    RobotState,
    compose,
    integrate,
    relative,
    step_robot,
    wrap_angle,
)
from stealth_core.occupancy_map import OCCUPIED, UNKNOWN

DT = 0.02
LIMITS = Limits(max_linear_speed=0.5, max_angular_speed=1.5, max_linear_accel=1.0)


def open_floor(radius: float = 0.2) -> DiscFootprint:
    """A 20 x 20 m room: nothing in reach of the tests that are about motion alone."""
    return DiscFootprint(as_map(room(400, 400)), radius)


def run(state, command, steps, footprint, limits=LIMITS, dt=DT):
    bumps = []
    for _ in range(steps):
        state, bumped = step_robot(state, *command, limits, dt, footprint)
        bumps.append(bumped)
    return state, bumps


def test_straight_line_is_exact_with_the_acceleration_ramp():
    start = Pose(5.0, 6.0, 0.3)
    state, bumps = run(RobotState(start), (0.4, 0.0), 100, open_floor())
    # From rest the speed grows by accel * dt per step until it reaches the command.
    speeds = [min(0.4, LIMITS.max_linear_accel * DT * k) for k in range(1, 101)]
    distance = sum(speeds) * DT
    assert state.pose.x == pytest.approx(5.0 + distance * math.cos(0.3), abs=1e-12)
    assert state.pose.y == pytest.approx(6.0 + distance * math.sin(0.3), abs=1e-12)
    assert state.pose.yaw == pytest.approx(0.3, abs=1e-15)
    assert state.linear == pytest.approx(0.4) and not any(bumps)


def test_turn_in_place_is_exact_and_does_not_move():
    start = Pose(5.0, 6.0, 3.0)
    state, _ = run(RobotState(start), (0.0, 1.0), 150, open_floor())
    rates = [min(1.0, LIMITS.max_angular_accel * DT * k) for k in range(1, 151)]
    assert state.pose.yaw == pytest.approx(wrap_angle(3.0 + sum(rates) * DT), abs=1e-12)
    assert (state.pose.x, state.pose.y) == (5.0, 6.0)


def test_constant_arc_closes_the_circle_exactly():
    steps = 400
    angular = 2 * math.pi / (steps * DT)
    linear = 0.4
    radius = linear / angular
    limits = Limits(max_linear_speed=1.0, max_angular_speed=2.0)
    start = RobotState(Pose(10.0, 5.0, 0.0), linear, angular)
    half, _ = run(start, (linear, angular), steps // 2, open_floor(), limits)
    assert half.pose.x == pytest.approx(10.0, abs=1e-9)
    assert half.pose.y == pytest.approx(5.0 + 2 * radius, abs=1e-9)
    full, _ = run(half, (linear, angular), steps // 2, open_floor(), limits)
    assert full.pose.x == pytest.approx(10.0, abs=1e-9)
    assert full.pose.y == pytest.approx(5.0, abs=1e-9)
    assert abs(wrap_angle(full.pose.yaw)) < 1e-9


def test_integrate_matches_the_closed_form_arc_and_the_line_as_the_turn_rate_vanishes():
    pose = Pose(1.0, 2.0, 0.7)
    linear, dt = 0.5, 0.1
    for angular in (1.0, 1e-2, 1e-3, 1e-5):  # on both sides of the series threshold
        radius = linear / angular
        end_yaw = 0.7 + angular * dt
        moved = integrate(pose, linear, angular, dt)
        assert moved.x == pytest.approx(
            1.0 + radius * (math.sin(end_yaw) - math.sin(0.7)), abs=1e-11
        )
        assert moved.y == pytest.approx(
            2.0 - radius * (math.cos(end_yaw) - math.cos(0.7)), abs=1e-11
        )
    straight = integrate(pose, linear, 0.0, dt)
    assert straight == (1.0 + 0.05 * math.cos(0.7), 2.0 + 0.05 * math.sin(0.7), 0.7)


def test_speed_and_acceleration_limits_hold_for_any_command():
    state = RobotState(Pose(10.0, 10.0, 0.0))
    rng = np.random.default_rng(3)
    footprint = open_floor()
    for command in rng.uniform(-10, 10, size=(300, 2)):
        new, _ = step_robot(state, *command, LIMITS, DT, footprint)
        assert abs(new.linear) <= LIMITS.max_linear_speed
        assert abs(new.angular) <= LIMITS.max_angular_speed
        assert abs(new.linear - state.linear) <= LIMITS.max_linear_accel * DT + 1e-12
        assert abs(new.angular - state.angular) <= LIMITS.max_angular_accel * DT + 1e-12
        state = new


def test_limits_reject_non_positive_values():
    with pytest.raises(ValueError, match='max_linear_speed'):
        Limits(max_linear_speed=0.0)
    with pytest.raises(ValueError, match='max_angular_accel'):
        Limits(max_angular_accel=math.nan)


def test_compose_and_relative_are_inverse():
    origin = Pose(1.0, -2.0, 2.5)
    pose = Pose(-0.3, 0.4, -2.9)
    back = compose(origin, *relative(origin, pose))
    assert back == pytest.approx(pose, abs=1e-12)


# --- collision --------------------------------------------------------------------------------


def thin_wall_room(value: int = OCCUPIED) -> np.ndarray:
    """A 10 x 3 m room with a wall one cell thick at x in [5.0, 5.05), floor to ceiling."""
    data = room(200, 60)
    data[:, 100] = value
    return data


@pytest.mark.parametrize('radius', [0.0, 0.2])
@pytest.mark.parametrize('value', [OCCUPIED, UNKNOWN])
@pytest.mark.parametrize(('speed', 'dt'), [(0.5, DT), (5.0, DT), (1000.0, 0.1)])
def test_no_tunnelling_through_a_one_cell_wall_at_any_speed(radius, value, speed, dt):
    footprint = DiscFootprint(as_map(thin_wall_room(value)), radius)
    limits = Limits(max_linear_speed=speed, max_linear_accel=1e6)
    state = RobotState(Pose(4.0, 1.5, 0.0))
    state, bumps = run(state, (speed, 0.0), 200, footprint, limits, dt)
    wall_face = 100 * RESOLUTION
    assert any(bumps)
    assert state.pose.x < wall_face - radius + 1e-12
    # Stopped at contact: within 2**-12 of one step (at most 100 m here) of the wall.
    assert state.pose.x > wall_face - radius - speed * dt / 4096 - 1e-9
    assert state.linear == 0.0


def test_a_bump_keeps_the_turn_and_is_reported_every_time_the_robot_pushes():
    footprint = DiscFootprint(as_map(thin_wall_room()), 0.2)
    limits = Limits(max_linear_accel=100.0, max_angular_accel=100.0)
    state = RobotState(Pose(4.795, 1.5, 0.0))
    for push in range(1, 4):
        state, bumped = step_robot(state, 0.5, 1.0, limits, DT, footprint)
        assert bumped
        assert state.pose.yaw == pytest.approx(push * DT * 1.0, abs=1e-12)
        assert (state.linear, state.angular) == (0.0, 0.0)
        assert 4.795 < state.pose.x < 4.8


def test_the_robot_cannot_leave_the_map_even_without_walls():
    data = np.zeros((40, 40), np.int8)  # all free, no walls: the edge of the map stops it
    footprint = DiscFootprint(as_map(data), 0.1)
    state, bumps = run(RobotState(Pose(1.0, 1.0, 0.0)), (0.5, 0.0), 200, footprint)
    assert any(bumps) and state.pose.x < 2.0 - 0.1


def brute_force_distance(occupancy_map, x, y) -> float:
    """Distance from a point to the nearest blocked square, over every cell of the map."""
    rows, cols = np.nonzero(occupancy_map.blocked)
    left, bottom = cols * RESOLUTION, rows * RESOLUTION
    dx = np.maximum(np.maximum(left - x, x - left - RESOLUTION), 0)
    dy = np.maximum(np.maximum(bottom - y, y - bottom - RESOLUTION), 0)
    return float(np.sqrt(dx * dx + dy * dy).min())


def test_fits_agrees_with_brute_force_distances_to_every_blocked_square():
    data = room(60, 60)
    data[20:23, 25:40] = OCCUPIED
    data[35, 10] = UNKNOWN
    occupancy_map = as_map(data)
    footprint = DiscFootprint(occupancy_map, 0.23)
    rng = np.random.default_rng(7)
    for x, y in rng.uniform(0.06, 2.94, size=(1500, 2)):
        distance = brute_force_distance(occupancy_map, x, y)
        if abs(distance - 0.23) > 1e-9:  # a point exactly at the radius is either
            assert footprint.fits(x, y) == (distance >= 0.23), (x, y, distance)


def test_sweeps_are_free_exactly_when_every_point_along_them_fits():
    data = room(60, 60)
    data[30, 5:55] = OCCUPIED
    data[30, 28:32] = 0  # a door 0.2 m wide: too narrow for the disc of radius 0.15
    occupancy_map = as_map(data)
    footprint = DiscFootprint(occupancy_map, 0.15)
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(300):
        x0, y0 = rng.uniform(0.3, 2.7, 2)
        if not footprint.fits(x0, y0):
            continue
        x1, y1 = np.array([x0, y0]) + rng.normal(0, 0.4, 2)
        samples = np.linspace(0, 1, 2001)
        nearest = min(
            brute_force_distance(occupancy_map, x0 + t * (x1 - x0), y0 + t * (y1 - y0))
            for t in samples[::50]
        )
        free = footprint.sweep_is_free(x0, y0, x1, y1)
        if free:
            assert nearest >= 0.15 - 1e-9
        elif nearest >= 0.15 + 0.02:  # blocked though the samples look clear: check densely
            assert not all(footprint.fits(x0 + t * (x1 - x0), y0 + t * (y1 - y0)) for t in samples)
        checked += 1
    assert checked > 100
    assert not footprint.sweep_is_free(1.5, 1.2, 1.5, 1.8)  # through the narrow door
