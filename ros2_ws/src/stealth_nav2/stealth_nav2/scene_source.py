"""Where a Nav2-facing node's scene comes from: the map and the lights as plain data (no rclpy).

Two sources, one ``Scene``:

- a scenario file (``scene_from_scenario``): its map and lights, and the scenario itself (the
  task's numbers: robot radius, step, detection threshold, step limit, phase bins);
- the topics a running system publishes (``SceneSource``): a ``nav_msgs/OccupancyGrid`` (the
  map server's ``/map``) and a ``stealth_interfaces/SearchlightArray`` (the environment
  node's ``searchlights``), converted by ``map_from_message`` and ``lights_from_message``.
  Messages are read by attribute (no rclpy: plain pytest builds them).

A light's motion counts from its own t = 0 (``stealth_core.searchlight``). A SearchlightArray
gives each light as it is at the message's stamp (the environment stamps it with the episode's
time, the lights' clock); the light at t = 0 is rebuilt from it: a static light as it is, a
patrol from its route (which starts where every lap starts), a sweep by turning it back by the
stamp (a sweep at t = 0 turns counter-clockwise first, as every ``Searchlight`` does, which
settles which way it turns at the stamp).

    scene = scene_from_scenario('lgfloor')          # SceneError: one line naming the problem
    source = SceneSource()                           # or SceneSource(scene) for a fixed scene
    source.update_map(grid_msg); source.update_lights(lights_msg)
    scene = source.current()                         # SceneMissingError names what has not arrived
    scene.blocked, scene.resolution, scene.origin, scene.lights, scene.identity()
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import os

import numpy as np
from stealth_core.occupancy_map import MapError, OccupancyMap, from_occupancy_grid
from stealth_core.scenario import Scenario, ScenarioError, content_identity, load_scenario
from stealth_core.searchlight import LightError, PatrolMotion, Searchlight, SweepMotion
from stealth_node_kit.conversions import quaternion_yaw, seconds

MAP_FRAME = 'map'
# stealth_interfaces/Searchlight.MOTION_*
MOTION_STATIC, MOTION_SWEEP, MOTION_PATROL = 0, 1, 2


class SceneError(ValueError):
    """A scene that cannot be used; the message names the file or message and the field."""


class SceneMissingError(SceneError):
    """Part of the scene has not arrived yet; ``missing`` names the parts ('map', 'lights')."""

    def __init__(self, missing: tuple[str, ...], message: str):
        super().__init__(message)
        self.missing = missing


@dataclasses.dataclass(frozen=True, eq=False)
class Scene:
    """The map and the lights, in ``frame_id`` (m, rad).

    map: the occupancy grid (``OccupancyMap``: int8 cells, row 0 the bottom, -1 unknown);
    lights: each at its own t = 0 (``Searchlight.at(t)`` gives it at time t of the lights'
    clock); scenario: the scenario file's, when the scene came from one (None from topics);
    source: where it came from, for messages.
    """

    map: OccupancyMap
    lights: tuple[Searchlight, ...]
    source: str
    frame_id: str = MAP_FRAME
    scenario: Scenario | None = None

    @property
    def grid(self) -> np.ndarray:
        """(rows, cols) int8 occupancy, nav_msgs/OccupancyGrid's values, row 0 the bottom."""
        return self.map.data

    @property
    def blocked(self) -> np.ndarray:
        """(rows, cols) bool: occupied or unknown cells (walls for light and robot alike)."""
        return self.map.blocked

    @property
    def resolution(self) -> float:
        return self.map.resolution

    @property
    def origin(self) -> tuple[float, float, float]:
        return self.map.origin

    @property
    def has_moving_lights(self) -> bool:
        return any(light.is_moving for light in self.lights)

    def identity(self) -> dict[str, str]:
        """SHA-256 of the grid and of the lights, as ``stealth_core.scenario.content_identity``
        (what saved policies carry): equal identities, equal scenes."""
        return content_identity(self)

    @functools.cached_property
    def key(self) -> tuple[str, str]:
        """(grid_sha256, lights_sha256): a cache key that changes with the content (hashed
        once: a scene is never changed)."""
        identity = self.identity()
        return identity['grid_sha256'], identity['lights_sha256']


def scene_from_scenario(name_or_path: str | os.PathLike) -> Scene:
    """The scene of a scenario file (a path, or a bare name such as ``lgfloor``)."""
    try:
        scenario = load_scenario(name_or_path)
    except ScenarioError as error:
        raise SceneError(str(error)) from None
    return Scene(
        map=scenario.map,
        lights=scenario.lights,
        source=f'scenario {scenario.name} ({scenario.path})',
        scenario=scenario,
    )


def scene_from_messages(grid_msg, lights_msg) -> Scene:
    """The scene of a nav_msgs/OccupancyGrid and a stealth_interfaces/SearchlightArray, both in
    the same frame."""
    occupancy, frame = map_from_message(grid_msg)
    lights, lights_frame = lights_from_message(lights_msg)
    if lights and lights_frame != frame:
        raise SceneError(
            f"SearchlightArray: field 'header.frame_id': expected the map's frame {frame!r}, "
            f'got {lights_frame!r}'
        )
    return Scene(map=occupancy, lights=lights, source='topics', frame_id=frame)


def map_from_message(grid_msg) -> tuple[OccupancyMap, str]:
    """(the map, its frame) of a nav_msgs/OccupancyGrid; SceneError naming the field."""
    info = grid_msg.info
    frame = grid_msg.header.frame_id or MAP_FRAME
    yaw = quaternion_yaw(info.origin.orientation)
    if not math.isclose(yaw, 0.0, abs_tol=1e-6):
        raise SceneError(
            "OccupancyGrid: field 'info.origin.orientation': expected no rotation (yaw 0, as "
            f'map_server publishes), got yaw {yaw:g} rad'
        )
    origin = (float(info.origin.position.x), float(info.origin.position.y), 0.0)
    # The message carries a float32: 0.05 arrives as 0.05000000075, which moves cone edges by a
    # cell against the scenario's map. Its shortest decimal is the resolution that was meant.
    resolution = float(str(np.float32(info.resolution)))
    try:
        occupancy = from_occupancy_grid(
            int(info.width), int(info.height), resolution, origin, grid_msg.data
        )
    except (MapError, ValueError) as error:
        raise SceneError(str(error)) from None
    return occupancy, frame


def lights_from_message(lights_msg) -> tuple[tuple[Searchlight, ...], str]:
    """(the lights at their t = 0, their frame) of a stealth_interfaces/SearchlightArray whose
    header stamp is the time the lights' state holds for (see the module for the sweep's
    guess)."""
    t = seconds(lights_msg.header.stamp)
    lights = []
    for index, light in enumerate(lights_msg.lights):
        try:
            lights.append(_light_at_zero(light, t))
        except LightError as error:
            raise SceneError(f'SearchlightArray: lights[{index}]: {error}') from None
    return tuple(lights), lights_msg.header.frame_id or MAP_FRAME


def _light_at_zero(light, t: float) -> Searchlight:
    """One stealth_interfaces/Searchlight, given as it is at time t, as it is at t = 0."""
    fields = {
        'name': light.name,
        'x': float(light.position.x),
        'y': float(light.position.y),
        'direction': float(light.direction),
        'fov': float(light.field_of_view),
        'range': float(light.range),
        'delta': float(light.delta),
        'soft_edge': float(light.soft_edge),
    }
    if light.motion == MOTION_SWEEP:
        motion = SweepMotion(
            float(light.sweep_min), float(light.sweep_max), float(light.angular_speed)
        ).validate(light.name)
        span = motion.max_direction - motion.min_direction
        if span > 0.0 and motion.angular_speed > 0.0:
            offset = motion.start_offset(light.name, fields['direction'])
            # Along the triangle wave at t: offset turning ccw, or 2 * span - offset turning
            # back; at t = 0 the wave is on its ccw half (a Searchlight starts turning ccw).
            for along in (offset, 2 * span - offset):
                back = (along - motion.angular_speed * t) % (2 * span)
                if back >= 2 * span * (1 - 1e-12):  # just below a whole lap: rounding
                    back = 0.0
                if back <= span * (1 + 1e-9):
                    break
            # Rounded to 1e-9 rad along the sweep: the same light from every stamp, so the
            # scene stays the same while the lights move.
            fields['direction'] = motion.min_direction + min(round(back, 9), span)
        return Searchlight(**fields, motion=motion)
    if light.motion == MOTION_PATROL:
        route = [(float(p.x), float(p.y)) for p in light.waypoints]
        if not route:
            raise LightError(
                f"searchlight {light.name!r}: field 'waypoints': expected the patrol's route "
                '(at least its first point), got none'
            )
        fields['x'], fields['y'] = route[0]
        waypoints = tuple(route[1:]) or (route[0],)
        return Searchlight(**fields, motion=PatrolMotion(waypoints, float(light.linear_speed)))
    if light.motion != MOTION_STATIC:
        raise LightError(
            f"searchlight {light.name!r}: field 'motion': expected one of 0 (static), 1 (sweep),"
            f' 2 (patrol), got {light.motion!r}'
        )
    return Searchlight(**fields)


class SceneSource:
    """The current scene: fixed (from a scenario file) or the latest map and lights messages.

    ``current()`` gives the scene, built again only when a message changed it, or raises
    ``SceneMissingError`` naming what has not arrived; a bad message raises SceneError from
    ``update_*`` and leaves the previous scene in place.
    """

    def __init__(self, scene: Scene | None = None, map_topic='/map', lights_topic='searchlights'):
        self._fixed = scene
        self._map: tuple[OccupancyMap, str] | None = None
        self._lights: tuple[tuple[Searchlight, ...], str] | None = None
        self._scene: Scene | None = None
        self.map_topic, self.lights_topic = map_topic, lights_topic

    @property
    def fixed(self) -> bool:
        return self._fixed is not None

    def update_map(self, grid_msg) -> None:
        self._map = map_from_message(grid_msg)
        self._scene = None

    def update_lights(self, lights_msg) -> None:
        lights = lights_from_message(lights_msg)
        if self._lights is None or _lights_digest(lights[0]) != _lights_digest(self._lights[0]):
            self._scene = None
        self._lights = lights

    def current(self) -> Scene:
        if self._fixed is not None:
            return self._fixed
        missing = []
        if self._map is None:
            missing.append(('map', f'nothing on {self.map_topic} (nav_msgs/OccupancyGrid)'))
        if self._lights is None:
            missing.append(
                ('lights', f'nothing on {self.lights_topic} (stealth_interfaces/SearchlightArray)')
            )
        if missing:
            raise SceneMissingError(
                tuple(name for name, _ in missing),
                f'no scene yet: {"; ".join(text for _, text in missing)}; publish it (the '
                'environment node does) or start with -p scenario:=<scenario.yaml>',
            )
        if self._scene is None:
            (occupancy, frame), (lights, lights_frame) = self._map, self._lights
            if lights and lights_frame != frame:
                raise SceneError(
                    f"{self.lights_topic}: field 'header.frame_id': expected the map's frame "
                    f'{frame!r}, got {lights_frame!r}'
                )
            self._scene = Scene(
                map=occupancy,
                lights=lights,
                source=f'topics {self.map_topic} and {self.lights_topic}',
                frame_id=frame,
            )
        return self._scene


def _lights_digest(lights: tuple[Searchlight, ...]) -> str:
    """A digest of the lights' content (their t = 0 state): unchanged lights keep the scene."""
    text = json.dumps([dataclasses.asdict(light) for light in lights], sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()
