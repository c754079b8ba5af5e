"""The environment's scene for RViz and Foxglove: the searchlights, their markers, the lit area,
the planned path and, on the sensed track, the light sensed so far, all transient local (frame
``map``); and the check that the simulator's latched ``map`` is the scenario's.

Static lights go out once (and again to a new viewer: a volatile one gets nothing from transient
local); moving lights again every ``marker_period`` of wall time, drawn at the episode's clock.
The marker geometry is :mod:`stealth_env.markers`'; the messages :mod:`stealth_env.env_messages`'.
"""

from __future__ import annotations

from collections.abc import Callable

from nav_msgs.msg import OccupancyGrid, Path
from stealth_interfaces.msg import SearchlightArray
from stealth_node_kit.endpoints import QUIET_PUBLISHER, QUIET_SUBSCRIPTION
from stealth_node_kit.qos import kept_qos
from visualization_msgs.msg import MarkerArray

from stealth_env.env_messages import (
    grid_msg,
    map_mismatch,
    marker_array_msg,
    path_msg,
    searchlight_array_msg,
    visibility_grid_msg,
)
from stealth_env.markers import WallMap, any_moving, scene_markers, visibility_levels

LATCHED_QOS = kept_qos(1)
TOPICS = {
    'searchlights': 'searchlights',
    'markers': 'searchlight_markers',
    'visibility_grid': 'visibility_grid',
    'planned_path': 'planned_path',
    'sensed_light': 'sensed_light',
    'map': 'map',
}


class ScenePublisher:
    """The scene's publishers on `node`. `scene_time`: the lights' time to draw them at (s of
    the episode's clock); `clock`: the clock of the ``marker_period`` timer; `sensed`: the
    SensedTrack of track sensed (``sensed_light``), or None."""

    def __init__(self, node, scenario, goal: str, scene_time: Callable[[], float], clock,
                 sensed=None):  # fmt: skip
        self.node = node
        self.scenario = scenario
        self.goal = goal
        self._scene_time = scene_time
        self._clock = clock
        self._walls = WallMap.of(scenario.map)
        self.moving_lights = any_moving(scenario)
        self._timer = None
        self._published = dict.fromkeys(('searchlights', 'markers', 'visibility_grid'), (-1.0, 0))
        self._markers_cache: tuple[float, MarkerArray] | None = None
        self._publishers = {
            'searchlights': (self._publisher(SearchlightArray, 'searchlights'), self._lights),
            'markers': (self._publisher(MarkerArray, 'markers'), self._markers),
            'visibility_grid': (self._publisher(OccupancyGrid, 'visibility_grid'), self._grid),
        }
        self._sensed = None  # (publisher, SensedTrack) on the sensed track
        if sensed is not None:
            self._sensed = (self._publisher(OccupancyGrid, 'sensed_light'), sensed)
        node.create_subscription(
            OccupancyGrid, TOPICS['map'], self._check_map, LATCHED_QOS,
            event_callbacks=QUIET_SUBSCRIPTION,
        )  # fmt: skip

    def _publisher(self, message_type, key: str):
        return self.node.create_publisher(
            message_type, TOPICS[key], LATCHED_QOS, event_callbacks=QUIET_PUBLISHER
        )

    def schedule(self, period: float) -> None:
        """Publish (when something changed) every `period` s; never when it is 0."""
        if self._timer is not None:
            self.node.destroy_timer(self._timer)
            self._timer = None
        if period > 0:
            self._timer = self.node.create_timer(period, self.publish, clock=self._clock)

    def publish(self, force: bool = False) -> None:
        """SearchlightArray, markers and the visibility grid: when lights moved since they were
        last sent, or when a new subscriber came (a volatile viewer gets nothing from transient
        local). Moving lights republish all three here, every marker_period: this is the hook."""
        t = self._scene_time() if self.moving_lights else 0.0
        for key, (publisher, build) in self._publishers.items():
            subscribers = publisher.get_subscription_count()
            last_t, last_subscribers = self._published[key]
            if force or (subscribers and (t != last_t or subscribers > last_subscribers)):
                publisher.publish(build(t))
                last_t = t
            self._published[key] = (last_t, subscribers)

    def publish_plan(self) -> None:
        """planned_path: value iteration's optimum from the start to the goal (frame map)."""
        from stealth_core.planners import optimal_path

        publisher = self._publisher(Path, 'planned_path')
        points, _ = optimal_path(self.scenario, self.goal)
        publisher.publish(path_msg(points))

    def publish_sensed(self, t: float) -> None:
        """sensed_light (nav_msgs/OccupancyGrid): the light sensed so far at each lattice node
        (one cell per node), 0-100 of the detection threshold, -1 never sensed or no node; at
        each state sent, built only while someone subscribes."""
        if self._sensed is None:
            return
        publisher, track = self._sensed
        if publisher.get_subscription_count():
            resolution, x, y = track.grid_geometry()
            publisher.publish(grid_msg(track.levels(), resolution, (x, y, 0.0), t))

    def _lights(self, t: float) -> SearchlightArray:
        return searchlight_array_msg(self.scenario.lights, t)

    def _markers(self, t: float) -> MarkerArray:
        if self._markers_cache is None or self._markers_cache[0] != t:
            specs = scene_markers(self.scenario, self.goal, t, self._walls)
            self._markers_cache = (t, marker_array_msg(specs, t))
        return self._markers_cache[1]

    def _grid(self, t: float) -> OccupancyGrid:
        """The lit area at time t on the scenario's map grid: static lights' field from the disk
        cache, moving lights' computed afresh (a cache file per time would only pile up)."""
        from stealth_core.visibility import visibility_field
        from stealth_core.visibility_cache import scenario_visibility

        occupancy = self.scenario.map
        if self.moving_lights:
            total, _ = visibility_field(
                occupancy.blocked, occupancy.resolution, occupancy.origin, self.scenario.lights, t
            )
        else:
            total, _ = scenario_visibility(self.scenario)
        levels = visibility_levels(total, self.scenario.detection_threshold)
        return visibility_grid_msg(occupancy, levels, t)

    def _check_map(self, grid: OccupancyGrid) -> None:
        """The simulator's map must be the scenario's, or the judge sees other walls."""
        problem = map_mismatch(self.scenario.map, grid)
        if problem:
            self.node.get_logger().error(
                f"the simulator's map is not the map of scenario {self.scenario.name!r} "
                f'({self.scenario.map_path}): {problem}; start the simulator with that map'
            )
        else:
            self.node.get_logger().debug("the simulator's map is the scenario's")
