"""The fields of a scenario file that place things on its map: points inside the map and in
free cells, the searchlights and their motions, each checked with one :class:`ScenarioError`
that names the file, the field and what was expected (``stealth_core.scenario`` reads the rest).
"""

import math

from stealth_core.occupancy_map import OccupancyMap
from stealth_core.searchlight import LightError, PatrolMotion, Searchlight, SweepMotion
from stealth_core.yaml_fields import FieldReader

LIGHT_FIELDS = ('name', 'x', 'y', 'direction', 'fov', 'range', 'delta', 'soft_edge', 'motion')
POSITIVE = 'a number > 0'


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message names file, field and expectation."""


def check_inside(fields, occupancy: OccupancyMap, x, y, what: str, keys=('x', 'y')) -> None:
    """Fail, naming the x or the y field (whichever is off), unless (x, y) lies on the map."""
    if occupancy.contains_point(x, y):
        return
    x_min, y_min, x_max, y_max = occupancy.bounds
    axis, key, value, low, high = ('x', keys[0], x, x_min, x_max)
    if x_min <= x < x_max:
        axis, key, value, low, high = ('y', keys[1], y, y_min, y_max)
    fields.fail(key, f'{what} inside the map, {axis} in [{low:g}, {high:g})', value)


def point_in_free_space(fields: FieldReader, occupancy: OccupancyMap) -> tuple[float, float]:
    x = fields.number('x', 'a number (m)')
    y = fields.number('y', 'a number (m)')
    check_inside(fields, occupancy, x, y, 'a point')
    kind = blocked_kind(occupancy, x, y)
    if kind is not None:
        where = fields.prefix.rstrip('.')
        raise fields.error(
            f"{fields.source}: field '{where}': expected a point in a free cell of the map, "
            f'got ({x:g}, {y:g}) in an {kind} cell'
        )
    return x, y


def blocked_kind(occupancy: OccupancyMap, x, y) -> str | None:
    """'occupied' or 'unknown' when the point's cell is blocked, else None."""
    col, row = occupancy.world_to_cell(x, y)
    if not occupancy.blocked[row, col]:
        return None
    return 'unknown' if occupancy.unknown[row, col] else 'occupied'


def read_lights(fields: FieldReader, occupancy: OccupancyMap) -> tuple[Searchlight, ...]:
    entries = fields.raw('lights', 'a list of searchlights')
    if not isinstance(entries, list):
        fields.fail('lights', 'a list of searchlights', entries)
    lights, names = [], set()
    for index, entry in enumerate(entries):
        prefix = f'lights[{index}]'
        if not isinstance(entry, dict):
            fields.fail(prefix, 'a mapping of searchlight fields', entry)
        light = FieldReader(fields.source, entry, ScenarioError, f'{prefix}.')
        light.reject_unknown(LIGHT_FIELDS)
        name = light.string('name', 'a non-empty string', default=f'L{index + 1}')
        if name in names:
            light.fail('name', 'a name no other light has', name)
        names.add(name)
        x = light.number('x', 'a number (m)')
        y = light.number('y', 'a number (m)')
        check_inside(light, occupancy, x, y, 'a light position')
        kind = blocked_kind(occupancy, x, y)
        if kind is not None:  # in a wall a lamp lights little, facing into it nothing at all
            fields.fail_with(
                prefix,
                'a light in a free cell of the map',
                f'{name!r} at ({x:g}, {y:g}) in an {kind} cell; move it to a free cell or '
                'remove it',
            )
        direction = light.number('direction', 'an angle in degrees')
        try:
            lights.append(
                Searchlight(
                    name=name,
                    x=x,
                    y=y,
                    direction=math.radians(direction),
                    fov=math.radians(
                        light.number('fov', 'a full angle in (0, 360] degrees', _in_fov_range)
                    ),
                    range=light.number('range', f'{POSITIVE} (m)', lambda v: v > 0),
                    delta=light.number('delta', 'a number in (0, 1)', lambda v: 0 < v < 1, 0.1),
                    soft_edge=light.number(
                        'soft_edge', 'a number in [0, 1]', lambda v: 0 <= v <= 1, 0.0
                    ),
                    motion=_motion(light, occupancy, direction),
                )
            )
        except LightError as error:
            raise ScenarioError(f'{fields.where(prefix)}: {error}') from None
    return tuple(lights)


def _in_fov_range(degrees: float) -> bool:
    return 0 < degrees <= 360


def _motion(light: FieldReader, occupancy, direction: float) -> SweepMotion | PatrolMotion | None:
    if not light.has('motion'):
        return None
    expected = 'a mapping with type: sweep or type: patrol'
    motion = light.mapping('motion', expected)
    kind = motion.string('type', 'sweep or patrol')
    if kind == 'sweep':
        motion.reject_unknown(('type', 'min_direction', 'max_direction', 'angular_speed'))
        low = motion.number('min_direction', 'an angle in degrees')
        high = motion.number(
            'max_direction',
            f'an angle in degrees in [min_direction, min_direction + 360] = '
            f'[{low:g}, {low + 360:g}]',
            lambda v: low <= v <= low + 360,
        )
        speed = motion.number('angular_speed', 'a number > 0 (degrees/s)', lambda v: v > 0)
        if (direction - low) % 360 > high - low + 1e-9 and (low - direction) % 360 > 1e-9:
            light.fail('direction', f'an angle inside the sweep [{low:g}, {high:g}]', direction)
        return SweepMotion(math.radians(low), math.radians(high), math.radians(speed))
    if kind == 'patrol':
        motion.reject_unknown(('type', 'waypoints', 'speed'))
        entries = motion.raw('waypoints', 'a list of [x, y] points (m)')
        if not isinstance(entries, list) or not entries:
            motion.fail('waypoints', 'a non-empty list of [x, y] points (m)', entries)
        waypoints = []
        for index, entry in enumerate(entries):
            key = f'waypoints[{index}]'
            point = FieldReader(motion.source, {key: entry}, ScenarioError, motion.prefix)
            x, y = point.numbers(key, 2, 'an [x, y] point (m)')
            check_inside(point, occupancy, x, y, 'a waypoint', keys=(key, key))
            waypoints.append((x, y))
        speed = motion.number('speed', 'a number > 0 (m/s)', lambda v: v > 0)
        return PatrolMotion(tuple(waypoints), speed)
    motion.fail('type', 'sweep or patrol', kind)
