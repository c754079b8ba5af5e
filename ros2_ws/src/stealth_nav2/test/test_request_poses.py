"""A request's poses checked before planning (plain pytest): every float64 a start or goal
field can hold, extremes included, gives a planar pose or a PlanError with a documented code
and a one-line message; never another exception (an OverflowError reached the node as a
traceback and the client as error code 0)."""

import itertools
import math
import random
import struct
import sys

import pytest
from stealth_core.kinematics import wrap_angle
from stealth_nav2.covert_planning import CovertPlanner, Pose
from stealth_nav2.plan_errors import PlanError
from stealth_nav2.request_poses import (
    ORIENTATION_FIELDS,
    POSITION_FIELDS,
    TRANSFORM_FIELDS,
    check_on_map,
    planar_pose,
    planar_yaw,
    point,
    request_pose,
)
from stealth_nav2.scene_source import scene_from_scenario
from stealth_node_kit.conversions import quaternion_yaw, yaw_quaternion

BIG = sys.float_info.max
TINY = 5e-324  # the smallest subnormal
EXTREMES = (
    0.0, -0.0, TINY, -TINY, sys.float_info.min, 1e-300, 0.5, -1.0, 7.25, 1e6, -1e6, 1e154,
    1e308, -1e308, BIG, -BIG, math.nan, math.inf, -math.inf,
)  # fmt: skip
UNIT = (0.0, 0.0, 0.0, 1.0)


@pytest.fixture(scope='module')
def lgfloor():
    return scene_from_scenario('lgfloor')


def outcome(occupancy, role, position, orientation):
    """('ok', pose) or (code, message): what a request's pose comes to before planning."""
    try:
        pose = request_pose(role, role.lower(), position, orientation)
        check_on_map(occupancy, pose, role, role.lower())
    except PlanError as error:
        message = str(error)
        assert message and '\n' not in message and len(message) < 300, message
        return error.code, message
    return 'ok', pose


def random_double(rng: random.Random) -> float:
    """Any float64 bit pattern: nan payloads, subnormals, infinities, huge and tiny values."""
    return struct.unpack('<d', rng.getrandbits(64).to_bytes(8, 'little'))[0]


@pytest.mark.parametrize('role', ['START', 'GOAL'])
def test_every_extreme_position_is_a_pose_or_a_named_error(lgfloor, role):
    occupancy = lgfloor.map
    x_min, y_min, x_max, y_max = occupancy.bounds
    for x, y, z in itertools.product(EXTREMES, EXTREMES, (0.0, 1e308, math.nan, -math.inf)):
        code, detail = outcome(occupancy, role, (x, y, z), UNIT)
        finite = all(math.isfinite(v) for v in (x, y, z))
        on_map = finite and x_min <= x < x_max and y_min <= y < y_max
        if not finite:
            bad = next(n for n, v in zip(POSITION_FIELDS, (x, y, z), strict=True)
                       if not math.isfinite(v))  # fmt: skip
            assert code == f'{role}_OUTSIDE_MAP', (x, y, z)
            assert detail.startswith(f'{role.lower()} {bad} is ') and 'expected a finite' in detail
        elif not on_map:
            assert code == f'{role}_OUTSIDE_MAP', (x, y, z)
            assert f'{role.lower()} {point(x, y)} is outside the map: expected x in' in detail
        else:
            assert code in ('ok', f'{role}_OCCUPIED'), (x, y, z, detail)
            if code == 'ok':
                assert (detail.x, detail.y) == (x, y)  # z is ignored


def test_every_extreme_orientation_is_a_heading_or_a_named_error(lgfloor):
    occupancy, (x, y, _) = lgfloor.map, lgfloor.scenario.start
    values = (0.0, TINY, -1e-300, 0.5, -2.0, 1e300, -BIG, math.nan, math.inf)
    for quaternion in itertools.product(values, repeat=4):
        code, detail = outcome(occupancy, 'GOAL', (x, y, 0.0), quaternion)
        if not all(math.isfinite(v) for v in quaternion):
            bad = next(n for n, v in zip(ORIENTATION_FIELDS, quaternion, strict=True)
                       if not math.isfinite(v))  # fmt: skip
            assert code == 'GOAL_OUTSIDE_MAP' and detail.startswith(f'goal {bad} is ')
        elif not any(quaternion):
            assert code == 'GOAL_OUTSIDE_MAP'
            assert 'orientation is (0, 0, 0, 0): expected a rotation' in detail
        else:
            assert code == 'ok', (quaternion, detail)
            assert -math.pi <= detail.yaw <= math.pi


def test_random_float64_requests_never_escape_as_another_exception(lgfloor):
    """10,000 poses of random bit patterns mixed with the extremes, through the checks and the
    planner: a path, or one of the documented codes."""
    rng = random.Random(40)
    planner = CovertPlanner()
    occupancy, start = lgfloor.map, lgfloor.scenario.start
    inside = (start[0], start[1], 0.0)
    codes = {'ok'}
    for _ in range(10_000):
        fields = [rng.choice((random_double(rng), rng.choice(EXTREMES), rng.uniform(-20, 20)))
                  for _ in range(7)]  # fmt: skip
        role = rng.choice(('START', 'GOAL'))
        code, detail = outcome(occupancy, role, fields[:3], fields[3:])
        codes.add(code)
        assert code in ('ok', f'{role}_OUTSIDE_MAP', f'{role}_OCCUPIED'), (fields, detail)
    assert codes >= {'ok', 'START_OUTSIDE_MAP', 'GOAL_OUTSIDE_MAP'}
    for goal in ((1e308, 1e308), (-BIG, BIG), (TINY, -TINY), (1e154, 0.0)):
        for start_pose, goal_pose in ((inside[:2], goal), (goal, inside[:2])):
            try:
                planner.plan(lgfloor, Pose(*start_pose), Pose(*goal_pose))
            except PlanError as error:
                assert error.code.endswith(('_OUTSIDE_MAP', '_OCCUPIED', 'NO_VALID_PATH'))


@pytest.mark.parametrize(
    ('start', 'goal', 'code', 'words'),
    [
        ((-12.0, 0.0), (1e308, 1e308), 'GOAL_OUTSIDE_MAP', 'goal (1e+308, 1e+308) is outside'),
        ((-12.0, 0.0), (-BIG, 0.0), 'GOAL_OUTSIDE_MAP', 'goal (-1.8e+308, 0.00) is outside'),
        ((BIG, BIG), (12.0, -9.0), 'START_OUTSIDE_MAP', 'start (1.8e+308, 1.8e+308) is'),
        ((-12.0, 0.0), (math.inf, 0.0), 'GOAL_OUTSIDE_MAP', 'goal (inf, 0.00) is outside'),
        ((-12.0, math.nan), (12.0, -9.0), 'START_OUTSIDE_MAP', 'start (-12.00, nan) is outside'),
    ],
)
def test_the_planner_answers_a_huge_pose_as_outside_the_map(lgfloor, start, goal, code, words):
    """(1e308, 1e308) gave an OverflowError (a cell index of infinity) instead of this."""
    with pytest.raises(PlanError) as caught:
        CovertPlanner().plan(lgfloor, Pose(*start), Pose(*goal))
    assert caught.value.code == code
    assert words in str(caught.value) and 'expected x in [-15, 15)' in str(caught.value)


def test_the_heading_of_a_quaternion_of_any_length():
    for yaw in (-3.0, -1.0, 0.0, 0.5, 2.0, math.pi):
        q = yaw_quaternion(yaw)
        unit = (q.x, q.y, q.z, q.w)
        assert math.isclose(wrap_angle(planar_yaw(*unit) - yaw), 0.0, abs_tol=1e-12)
        assert math.isclose(planar_yaw(*unit), quaternion_yaw(q), abs_tol=1e-12)
        for scale in (1e-300, 3.0, 1e300, BIG):  # (subnormals hold too few digits for this)
            scaled = tuple(v * scale for v in unit)
            assert math.isclose(wrap_angle(planar_yaw(*scaled) - yaw), 0.0, abs_tol=1e-12)
    # Roll and pitch are ignored: the heading of the rotation's x axis seen from above.
    half = math.sqrt(0.5)
    assert math.isclose(planar_yaw(half, 0.0, 0.0, half), 0.0)  # a roll of 90 degrees
    assert math.isclose(planar_yaw(0.0, 0.0, 10.0, 10.0), math.pi / 2)  # length 14: 90 degrees
    with pytest.raises(ValueError, match=r'^\(0, 0, 0, 0\): expected a rotation'):
        planar_yaw(0.0, -0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match=r'^rotation is \(0, 0, 0, 0\): expected a rotation'):
        planar_pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), TRANSFORM_FIELDS)
    with pytest.raises(ValueError, match=r'^translation.y is nan: expected a finite number'):
        planar_pose((0.0, math.nan, 0.0), (0.0, 0.0, 0.0, 1.0), TRANSFORM_FIELDS)


def test_a_far_pose_in_messages_is_short():
    assert point(500.0, 0.0) == '(500.00, 0.00)'
    assert point(1e308, -math.inf) == '(1e+308, -inf)'
    assert point(math.nan, 123456789.0) == '(nan, 1.23e+08)'
