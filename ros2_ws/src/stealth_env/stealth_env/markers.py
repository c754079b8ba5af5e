"""What RViz and Foxglove draw of a scenario: marker geometry as plain data (no rclpy).

``scene_markers(scenario, goal, t)`` gives every marker of the scene at simulated time t as
:class:`MarkerSpec` (the node turns each into a visualization_msgs/Marker, frame ``map``):

========== ============== ============================================================
namespace  kind           what
========== ============== ============================================================
cones      triangle_list  each light's cone, one colour per vertex by the light's
                          intensity there (YlOrRd, as the scenario pictures; more opaque
                          where brighter), cut where the first wall stops the ray
ranges     line_strip     each cone's outline out to its range, ignoring walls
detection  line_strip     where this light alone reaches the detection threshold
                          (the arc at that distance, cut at walls like the cone)
motion     line_strip     a sweep's whole sector, or a patrol's closed route (moving
                          lights only)
lamps      sphere         each lamp
names      text           each light's name, above its lamp
start      cylinder       the start (robot-sized disc)
goals      cylinder       every goal's acceptance disc; the one pursued is opaque
labels     text           'start' and the goals' names
========== ============== ============================================================

``searchlight_fields(light, t)`` is a light as stealth_interfaces/Searchlight's fields.

``visibility_levels(total, threshold)`` is the lit area as a costmap shows it: the data of the
``visibility_grid`` OccupancyGrid, 0-100 = total visibility as a percentage of the detection
threshold (100 at or above it: a cell where the robot would be seen).

The cone's cut at walls is for display: rays marched from the lamp in half-cell steps stop in
the first blocked cell other than the lamp's own (a lamp may sit in a wall). Judging uses the
exact model (``stealth_core.lighting``), never this picture.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from stealth_core.lighting import cone_factor, intensity
from stealth_core.palette import (
    MARKER_DETECTION,
    MARKER_GOAL,
    MARKER_HEATMAP_STOPS,
    MARKER_LAMP,
    MARKER_LIGHT,
    MARKER_MOTION,
    MARKER_OTHER_GOAL_ALPHA,
    MARKER_START,
    MARKER_TEXT,
)
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion

RGBA = tuple[float, float, float, float]
Point = tuple[float, float, float]
KINDS = ('triangle_list', 'line_strip', 'sphere', 'cylinder', 'text')
MAX_RAY_STEP = math.radians(5.0)  # angle between neighbouring rays of a cone (at most)
RINGS = 6  # cone rings, at evenly spaced intensities from 1 down to delta
# Heights (m) that keep the layers apart above the map (z = 0).
Z_CONE, Z_DISC, Z_LINE, Z_TEXT = 0.01, 0.02, 0.03, 0.6
LINE_WIDTH = 0.05  # m
TEXT_HEIGHT = 0.4  # m
_YLORRD = np.array(MARKER_HEATMAP_STOPS)  # the pictures' YlOrRd at 0, 0.25, ... 1


class MarkerSpec(NamedTuple):
    """One marker; lengths in metres, map frame. ``colors`` (triangle_list) is per point."""

    namespace: str
    id: int
    kind: str  # one of KINDS
    points: tuple[Point, ...] = ()
    colors: tuple[RGBA, ...] = ()
    color: RGBA = (1.0, 1.0, 1.0, 1.0)
    position: Point = (0.0, 0.0, 0.0)
    scale: Point = (1.0, 1.0, 1.0)
    text: str = ''


def intensity_colour(value: float) -> RGBA:
    """The colour of an intensity in [0, 1] (clipped): YlOrRd, alpha from 0.3 to 0.8."""
    value = min(max(float(value), 0.0), 1.0)
    position = value * (len(_YLORRD) - 1)
    low = min(int(position), len(_YLORRD) - 2)
    r, g, b = _YLORRD[low] + (position - low) * (_YLORRD[low + 1] - _YLORRD[low])
    return (float(r), float(g), float(b), 0.3 + 0.5 * value)


# --- rays ---------------------------------------------------------------------------------------


class WallMap(NamedTuple):
    """What the rays need of an occupancy map (``blocked`` computed once)."""

    blocked: np.ndarray  # (height, width) bool, row 0 the bottom row
    resolution: float
    origin_x: float
    origin_y: float

    @classmethod
    def of(cls, occupancy) -> WallMap:
        x0, y0, _ = occupancy.origin
        return cls(np.asarray(occupancy.blocked, dtype=bool), occupancy.resolution, x0, y0)


def ray_reach(walls: WallMap, x: float, y: float, angles, max_range: float) -> np.ndarray:
    """How far (m) rays from (x, y) at these angles (rad) get before the first blocked cell
    other than the start's own cell, or the map's edge; at most max_range."""
    angles = np.asarray(angles, dtype=np.float64)
    step = walls.resolution / 2
    distances = np.arange(1, math.ceil(max_range / step) + 1) * step
    xs = x + np.cos(angles)[:, None] * distances
    ys = y + np.sin(angles)[:, None] * distances
    cols = np.floor((xs - walls.origin_x) / walls.resolution).astype(np.int64)
    rows = np.floor((ys - walls.origin_y) / walls.resolution).astype(np.int64)
    height, width = walls.blocked.shape
    inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
    blocked = ~inside
    blocked[inside] = walls.blocked[rows[inside], cols[inside]]
    own_col = math.floor((x - walls.origin_x) / walls.resolution)
    own_row = math.floor((y - walls.origin_y) / walls.resolution)
    blocked &= ~((cols == own_col) & (rows == own_row))
    stopped = blocked.any(axis=1)
    first = np.argmax(blocked, axis=1)
    reach = np.where(stopped, distances[first], max_range)
    return np.minimum(reach, max_range)


def cone_angles(light: Searchlight) -> np.ndarray:
    """Ray angles (rad) across the cone, edge to edge, at most MAX_RAY_STEP apart."""
    sectors = max(2, math.ceil(light.fov / MAX_RAY_STEP))
    return light.direction + np.linspace(-light.fov / 2, light.fov / 2, sectors + 1)


def ring_radii(light: Searchlight) -> np.ndarray:
    """Ring distances (m) from the lamp: intensities evenly spaced from 1 to delta."""
    levels = np.linspace(1.0, light.delta, RINGS + 1)
    radii = np.sqrt((1.0 / levels - 1.0) / light.beta)
    radii[-1] = light.range  # exactly, whatever the rounding
    return radii


# --- one light ----------------------------------------------------------------------------------


def cone_mesh(light: Searchlight, walls: WallMap) -> tuple[tuple[Point, ...], tuple[RGBA, ...]]:
    """Triangles (3 points each) filling the static light's cone up to the walls, with a colour
    per point by the intensity there."""
    angles = cone_angles(light)
    reach = ray_reach(walls, light.x, light.y, angles, light.range)
    radii = np.minimum(ring_radii(light)[None, :], reach[:, None])  # (rays, rings + 1)
    shade = cone_factor(angles - light.direction, light.fov, light.soft_edge)
    xs = light.x + np.cos(angles)[:, None] * radii
    ys = light.y + np.sin(angles)[:, None] * radii
    colours = [
        [intensity_colour(shade[k] * intensity(radii[k, j], light.beta)) for j in range(RINGS + 1)]
        for k in range(len(angles))
    ]
    points: list[Point] = []
    colors: list[RGBA] = []

    def corner(k: int, j: int) -> None:
        points.append((float(xs[k, j]), float(ys[k, j]), Z_CONE))
        colors.append(colours[k][j])

    for k in range(len(angles) - 1):
        for j in range(RINGS):
            near_a, far_a = radii[k, j], radii[k, j + 1]
            near_b, far_b = radii[k + 1, j], radii[k + 1, j + 1]
            if far_a <= near_a and far_b <= near_b:
                continue  # both rays stopped before this ring: nothing to fill
            if j == 0:  # the apex: one triangle
                for corner_k, corner_j in ((k, 0), (k, 1), (k + 1, 1)):
                    corner(corner_k, corner_j)
                continue
            for corner_k, corner_j in ((k, j), (k, j + 1), (k + 1, j + 1)):
                corner(corner_k, corner_j)
            for corner_k, corner_j in ((k, j), (k + 1, j + 1), (k + 1, j)):
                corner(corner_k, corner_j)
    return tuple(points), tuple(colors)


def sector_outline(x: float, y: float, direction: float, fov: float, radii) -> tuple[Point, ...]:
    """Lamp -> arc at ``radii`` (one per ray, or one for all) -> lamp; a closed circle when the
    sector is a full turn."""
    full = fov >= 2 * math.pi - 1e-9
    sectors = max(2, math.ceil(fov / MAX_RAY_STEP))
    angles = direction + np.linspace(-fov / 2, fov / 2, sectors + 1)
    radii = np.broadcast_to(np.asarray(radii, dtype=np.float64), angles.shape)
    arc = [
        (float(x + r * math.cos(a)), float(y + r * math.sin(a)), Z_LINE)
        for a, r in zip(angles, radii, strict=True)
    ]
    if full:
        return (*arc[:-1], arc[0])
    lamp = (float(x), float(y), Z_LINE)
    return (lamp, *arc, lamp)


def detection_distance(light: Searchlight, threshold: float) -> float | None:
    """Distance (m) within which this light alone reaches ``threshold`` on its axis; None when
    it never does."""
    if threshold > 1.0:
        return None
    distance = math.sqrt(max(1.0 / threshold - 1.0, 0.0) / light.beta)
    return min(distance, light.range)


def light_markers(
    index: int, light: Searchlight, now: Searchlight, walls: WallMap, threshold: float
) -> list[MarkerSpec]:
    """The markers of one light (``now``: the light at the time drawn, static)."""
    points, colors = cone_mesh(now, walls)
    markers = [
        MarkerSpec('cones', index, 'triangle_list', points, colors),
        MarkerSpec(
            'ranges',
            index,
            'line_strip',
            sector_outline(now.x, now.y, now.direction, now.fov, now.range),
            color=MARKER_LIGHT,
            scale=(LINE_WIDTH, 0.0, 0.0),
        ),
        MarkerSpec(
            'lamps',
            index,
            'sphere',
            color=MARKER_LAMP,
            position=(now.x, now.y, Z_LINE),
            scale=(0.3, 0.3, 0.3),
        ),
        MarkerSpec(
            'names',
            index,
            'text',
            color=MARKER_TEXT,
            position=(now.x, now.y, Z_TEXT),
            scale=(0.0, 0.0, TEXT_HEIGHT),
            text=light.name,
        ),
    ]
    distance = detection_distance(now, threshold)
    if distance is not None:
        angles = cone_angles(now)
        reach = np.minimum(ray_reach(walls, now.x, now.y, angles, now.range), distance)
        arc = tuple((float(p[0]), float(p[1]), Z_LINE) for p in _arc_points(now, angles, reach))
        markers.append(
            MarkerSpec(
                'detection', index, 'line_strip', arc, color=MARKER_DETECTION, scale=(0.03, 0, 0)
            )
        )
    motion = _motion_outline(light, now)
    if motion:
        markers.append(
            MarkerSpec(
                'motion',
                index,
                'line_strip',
                motion,
                color=MARKER_MOTION,
                scale=(0.03, 0.0, 0.0),
            )
        )
    return markers


def _arc_points(light: Searchlight, angles: np.ndarray, radii: np.ndarray):
    return zip(light.x + np.cos(angles) * radii, light.y + np.sin(angles) * radii, strict=True)


def _motion_outline(light: Searchlight, now: Searchlight) -> tuple[Point, ...]:
    if isinstance(light.motion, SweepMotion):
        low, high = light.motion.min_direction, light.motion.max_direction
        span = min(high - low + light.fov, 2 * math.pi)
        return sector_outline(now.x, now.y, (low + high) / 2, span, light.range)
    if isinstance(light.motion, PatrolMotion):
        route = [(light.x, light.y), *light.motion.waypoints, (light.x, light.y)]
        return tuple((float(x), float(y), Z_LINE) for x, y in route)
    return ()


# --- the scene ----------------------------------------------------------------------------------


def scene_markers(scenario, goal: str, t: float = 0.0, walls: WallMap | None = None):
    """Every marker of the scenario with its lights at simulated time t (s); ``goal`` is the
    name of the goal pursued. Pass ``walls`` (WallMap.of(scenario.map)) when drawing often."""
    walls = walls if walls is not None else WallMap.of(scenario.map)
    markers: list[MarkerSpec] = []
    for index, light in enumerate(scenario.lights):
        markers += light_markers(index, light, light.at(t), walls, scenario.detection_threshold)
    x, y, _ = scenario.start
    size = max(2 * scenario.robot_radius, 0.2)
    markers.append(
        MarkerSpec(
            'start', 0, 'cylinder', color=MARKER_START, position=(x, y, Z_DISC),
            scale=(size, size, 0.02),
        )
    )  # fmt: skip
    markers.append(_label(0, x, y, 'start'))
    for index, (name, target) in enumerate(scenario.goals.items()):
        colour = MARKER_GOAL if name == goal else (*MARKER_GOAL[:3], MARKER_OTHER_GOAL_ALPHA)
        markers.append(
            MarkerSpec(
                'goals', index, 'cylinder', color=colour, position=(target.x, target.y, Z_DISC),
                scale=(2 * target.radius, 2 * target.radius, 0.02),
            )
        )  # fmt: skip
        text = f'goal: {name}' if name == goal else name
        markers.append(_label(index + 1, target.x, target.y, text))
    return markers


def _label(index: int, x: float, y: float, text: str) -> MarkerSpec:
    return MarkerSpec(
        'labels',
        index,
        'text',
        color=MARKER_TEXT,
        position=(float(x), float(y), Z_TEXT),
        scale=(0.0, 0.0, TEXT_HEIGHT),
        text=text,
    )


def any_moving(scenario) -> bool:
    return any(light.is_moving for light in scenario.lights)


# --- the visibility grid -----------------------------------------------------------------------

GRID_MAX = 100  # nav_msgs/OccupancyGrid's top value: here, visibility at the detection threshold


def visibility_levels(total: np.ndarray, threshold: float) -> np.ndarray:
    """int8 levels 0-100 of a total-visibility field (rows from the bottom, as the map's):
    visibility / threshold * 100, rounded, capped at 100; ValueError for a threshold <= 0 or a
    field that is not finite."""
    if not (math.isfinite(threshold) and threshold > 0):
        raise ValueError(f'detection threshold: expected a finite number > 0, got {threshold}')
    total = np.asarray(total, dtype=np.float64)
    if total.ndim != 2 or not np.all(np.isfinite(total)):
        raise ValueError('visibility field: expected a 2-D array of finite numbers')
    scaled = np.rint(np.clip(total, 0.0, None) / threshold * GRID_MAX)
    return np.minimum(scaled, GRID_MAX).astype(np.int8)


# --- stealth_interfaces/Searchlight -------------------------------------------------------------

MOTION_STATIC, MOTION_SWEEP, MOTION_PATROL = 0, 1, 2  # Searchlight.MOTION_*


def searchlight_fields(light: Searchlight, t: float = 0.0) -> dict:
    """stealth_interfaces/Searchlight's fields (but the header) for a light at time t: position
    and direction where it is then, the motion's parameters as given (a patrol's waypoints
    from the light's own point, where every lap starts)."""
    now = light.at(t)
    fields = {
        'name': light.name,
        'position': (now.x, now.y),
        'direction': now.direction,
        'field_of_view': light.fov,
        'range': light.range,
        'delta': light.delta,
        'soft_edge': light.soft_edge,
        'motion': MOTION_STATIC,
        'sweep_min': 0.0,
        'sweep_max': 0.0,
        'angular_speed': 0.0,
        'waypoints': (),
        'linear_speed': 0.0,
    }
    if isinstance(light.motion, SweepMotion):
        fields.update(
            motion=MOTION_SWEEP,
            sweep_min=light.motion.min_direction,
            sweep_max=light.motion.max_direction,
            angular_speed=light.motion.angular_speed,
        )
    elif isinstance(light.motion, PatrolMotion):
        # The message's route is visited in order and closed back to its first point; the
        # scenario's starts at the light's own point (where it is at t = 0).
        route = [(light.x, light.y)]
        for point in light.motion.waypoints:
            if point != route[-1]:
                route.append(point)
        fields.update(
            motion=MOTION_PATROL, waypoints=tuple(route), linear_speed=light.motion.speed
        )
    return fields
