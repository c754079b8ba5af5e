"""Searchlight parameters, validation and motion (sweep and patrol) at given times."""

import math

import numpy as np
import pytest
from stealth_core.searchlight import (
    LightError,
    PatrolMotion,
    Searchlight,
    SweepMotion,
    poses_at,
)

PI = math.pi


def light(**overrides):
    values = {'name': 'L1', 'x': 1.0, 'y': 2.0, 'direction': 0.0, 'fov': PI / 2, 'range': 4.0}
    values.update(overrides)
    return Searchlight(**values)


def test_beta_puts_delta_at_the_range():
    assert light().beta == pytest.approx(0.9 / (0.1 * 16))  # 0.5625, by hand
    assert light(delta=0.5, range=2.0).beta == pytest.approx(0.25)


def test_defaults_and_immutability():
    lamp = light()
    assert (lamp.delta, lamp.soft_edge, lamp.motion) == (0.1, 0.0, None)
    with pytest.raises(AttributeError):
        lamp.x = 3.0
    assert hash(lamp) == hash(light())


def test_numbers_are_normalised_to_float():
    lamp = light(x=1, y=np.float32(2.0), range=np.int64(4))
    assert type(lamp.x) is float and type(lamp.y) is float and type(lamp.range) is float


def test_the_error_message_names_light_field_and_expectation():
    with pytest.raises(LightError) as caught:
        light(delta=1.5)
    assert str(caught.value) == (
        "searchlight 'L1': field 'delta': expected a number in (0, 1), got 1.5"
    )
    assert isinstance(caught.value, ValueError)


@pytest.mark.parametrize(
    ('field', 'value'),
    [
        ('x', math.nan),
        ('y', math.inf),
        ('x', '1.0'),
        ('x', True),
        ('direction', -math.inf),
        ('fov', 0.0),
        ('fov', 2 * PI + 1e-9),
        ('fov', -1.0),
        ('range', 0.0),
        ('range', -4.0),
        ('range', math.inf),
        ('delta', 0.0),
        ('delta', 1.0),
        ('delta', math.nan),
        ('soft_edge', -0.1),
        ('soft_edge', 1.1),
        ('motion', 'sweep'),
    ],
)
def test_out_of_range_parameters_are_refused(field, value):
    with pytest.raises(LightError, match=f"field '{field}'"):
        light(**{field: value})


@pytest.mark.parametrize('name', ['', None, 3])
def test_a_light_needs_a_name(name):
    with pytest.raises(LightError, match='name'):
        light(name=name)


def test_edge_values_are_accepted():
    light(fov=2 * PI, soft_edge=1.0, delta=1e-6)
    light(soft_edge=0.0, delta=0.999999)


# --- sweep -------------------------------------------------------------------------------------


def sweeping(direction=PI / 4, low=0.0, high=PI / 2, speed=PI / 4):
    return light(direction=direction, motion=SweepMotion(low, high, speed))


@pytest.mark.parametrize(
    ('t', 'expected'),
    [
        (0.0, PI / 4),  # starts at its direction
        (1.0, PI / 2),  # turns counter-clockwise first, reaches max after (pi/4)/(pi/4) s
        (2.0, PI / 4),  # bounces back
        (3.0, 0.0),  # reaches min
        (4.0, PI / 4),  # one period 2*(pi/2)/(pi/4) = 4 s later, as at t = 0
        (4.5, 3 * PI / 8),
        (-1.0, 0.0),  # periodic backwards too
    ],
)
def test_sweep_is_a_triangle_wave_starting_at_the_direction(t, expected):
    assert sweeping().at(t).direction == pytest.approx(expected, abs=1e-12)


def test_the_pose_at_a_time_is_static_and_keeps_the_rest():
    lamp = sweeping().at(1.0)
    assert lamp.motion is None
    assert (lamp.x, lamp.y, lamp.fov, lamp.range, lamp.name) == (1.0, 2.0, PI / 2, 4.0, 'L1')
    static = light()
    assert static.at(12.5) is static


def test_sweep_direction_may_be_given_modulo_two_pi():
    lamp = sweeping(direction=-PI / 2, low=PI, high=2 * PI, speed=0.0)
    assert lamp.at(10.0).direction == pytest.approx(3 * PI / 2)


def test_a_still_sweep_stays_put():
    assert sweeping(speed=0.0).at(7.0).direction == pytest.approx(PI / 4)
    assert sweeping(direction=1.0, low=1.0, high=1.0).at(7.0).direction == 1.0


@pytest.mark.parametrize(
    ('direction', 'low', 'high', 'speed', 'field'),
    [
        (PI, 0.0, PI / 2, 1.0, 'direction'),  # starts outside its sweep
        (0.5, 1.0, 0.0, 1.0, 'motion.max_direction'),  # max < min
        (0.5, 0.0, 7.0, 1.0, 'motion.max_direction'),  # more than a full turn
        (0.5, 0.0, 1.0, -1.0, 'motion.angular_speed'),
        (0.5, 0.0, 1.0, math.nan, 'motion.angular_speed'),
        (0.5, math.inf, 1.0, 1.0, 'motion.min_direction'),
    ],
)
def test_bad_sweeps_are_refused(direction, low, high, speed, field):
    with pytest.raises(LightError, match=f"field '{field}'"):
        sweeping(direction, low, high, speed)


# --- patrol ------------------------------------------------------------------------------------

SQRT2 = math.sqrt(2.0)
LAP = 2.0 + 2.0 + 2 * SQRT2  # (0,0) -> (2,0) -> (2,2) -> back to (0,0)


def patrolling(speed=1.0):
    return light(x=0.0, y=0.0, direction=1.0, motion=PatrolMotion(((2.0, 0.0), (2, 2)), speed))


@pytest.mark.parametrize(
    ('t', 'expected'),
    [
        (0.0, (0.0, 0.0)),  # its own x, y at t = 0
        (1.0, (1.0, 0.0)),
        (2.0, (2.0, 0.0)),  # first waypoint
        (3.0, (2.0, 1.0)),
        (4.0, (2.0, 2.0)),
        (4.0 + SQRT2, (1.0, 1.0)),  # on the way back to the start
        (LAP, (0.0, 0.0)),  # lap done
        (LAP + 1.0, (1.0, 0.0)),
        (-1.0, (1 / SQRT2, 1 / SQRT2)),  # a second before t = 0: on the last leg
    ],
)
def test_patrol_walks_the_closed_route_from_its_position(t, expected):
    lamp = patrolling().at(t)
    assert (lamp.x, lamp.y) == pytest.approx(expected, abs=1e-12)
    assert lamp.direction == 1.0 and lamp.motion is None


def test_patrol_speed_scales_time():
    assert (patrolling(speed=2.0).at(1.5).x, patrolling(speed=2.0).at(1.5).y) == pytest.approx(
        (2.0, 1.0)
    )
    still = patrolling(speed=0.0).at(3.0)
    assert (still.x, still.y) == (0.0, 0.0)


def test_waypoints_are_stored_as_float_tuples():
    lamp = light(motion=PatrolMotion([[1, 2], (3, 4)], 1))
    assert lamp.motion.waypoints == ((1.0, 2.0), (3.0, 4.0))
    assert isinstance(lamp.motion.speed, float)


@pytest.mark.parametrize(
    ('waypoints', 'speed', 'field'),
    [
        ((), 1.0, 'motion.waypoints'),
        (((1.0, 2.0, 3.0),), 1.0, r'motion.waypoints\[0\]'),
        (((1.0, math.nan),), 1.0, r'motion.waypoints\[0\].y'),
        (((1.0, 2.0),), -0.5, 'motion.speed'),
        (((1.0, 2.0),), math.inf, 'motion.speed'),
    ],
)
def test_bad_patrols_are_refused(waypoints, speed, field):
    with pytest.raises(LightError, match=f"field '{field}'"):
        light(motion=PatrolMotion(waypoints, speed))


@pytest.mark.parametrize('t', [math.nan, math.inf, None])
def test_time_must_be_finite(t):
    with pytest.raises(LightError, match='time'):
        sweeping().at(t)


@pytest.mark.parametrize(
    'motion',
    [
        None,
        SweepMotion(0.5, 2.5, 0.8),
        SweepMotion(1.0, 1.0, 0.8),
        PatrolMotion(((4.0, 1.0), (4.0, 5.0)), 0.6),
        PatrolMotion(((1.0, 1.0),), 0.0),
    ],
)
def test_poses_at_many_times_are_the_light_at_each(motion):
    light = Searchlight('l', 1.0, 1.0, 1.0, 0.5, 3.0, motion=motion)
    ts = np.linspace(-7.0, 40.0, 301)
    xs, ys, directions = poses_at(light, ts)
    for t, x, y, direction in zip(ts, xs, ys, directions, strict=True):
        at = light.at(float(t))
        assert (x, y) == pytest.approx((at.x, at.y), abs=1e-9)
        assert direction == pytest.approx(at.direction, abs=1e-9)
