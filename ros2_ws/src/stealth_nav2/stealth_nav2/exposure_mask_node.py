"""The exposure mask node (``exposure_mask``): the lit area of a scenario as a mask for Nav2's
keepout filter (``nav2_costmap_2d::KeepoutFilter``), with the CostmapFilterInfo that tells the
filter where to find it, as Nav2's ``costmap_filter_info_server`` and a ``map_server`` of the
mask would. The values are ``stealth_nav2.exposure_mask``'s: 100 where the light is at or above
the detection threshold, a graded band 1..99 below it, 0 in the dark, -1 on walls and unknown
cells. ``config/nav2_exposure_filter.yaml`` is the costmap side.

    stealth run stealth_nav2 exposure_mask --ros-args -p scenario:=lgfloor-moving
    stealth run stealth_nav2 exposure_mask   # the scene from the map and searchlights topics

The scene (``stealth_nav2.scene_source``, shared with the planner server): a scenario file's map,
lights and detection threshold; without one, the latest ``map`` and ``searchlights`` messages
and the ``detection_threshold`` parameter, the mask built again whenever they change the scene.

## Topics

Both reliable, transient local, depth 1: the QoS the keepout filter subscribes with, so a
costmap that starts later still gets them.

* publishes ``filter_info_topic`` (``/costmap_filter_info``; nav2_msgs/CostmapFilterInfo) once:
  type 0 (keepout), ``filter_mask_topic`` the mask's topic, base 0.0 and multiplier 1.0 (the
  values the keepout filter requires);
* publishes ``mask_topic`` (``/exposure_mask``; nav_msgs/OccupancyGrid in the map's frame,
  ``map``, with the map's cells, resolution and origin), stamped with the node-clock time it
  shows. Static lights: once, and again only when the values change (a new scene, a new
  ``band_start``). Moving lights: every ``1 / update_rate`` s of the node's clock (simulated
  time under ``use_sim_time``: the simulator publishes ``/clock``), the lights where they are
  at that time less ``lights_time_offset``, published when the values differ from the last
  mask sent. Under ``use_sim_time``, a ``/clock`` that stops for ``CLOCK_STALL`` s of wall time
  while lights move is reported (a warning: the mask stays at the lights of that time), and
  its return too.
* subscribes ``map`` (nav_msgs/OccupancyGrid) and ``searchlights``
  (stealth_interfaces/SearchlightArray), both transient local, when no scenario is given; a
  message that cannot be used is dropped with a warning naming the topic and the field.

## Parameters

``PARAMETERS`` below. An unusable scenario stops the node with one line saying why and exit
code 2.
"""

from __future__ import annotations

import time

from nav2_msgs.msg import CostmapFilterInfo
from nav_msgs.msg import OccupancyGrid
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from stealth_env.env_messages import grid_msg
from stealth_interfaces.msg import SearchlightArray
from stealth_node_kit.conversions import time_msg
from stealth_node_kit.endpoints import QUIET_PUBLISHER, QUIET_SUBSCRIPTION
from stealth_node_kit.param_table import Param
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.qos import kept_qos
from stealth_node_kit.running import StartupNode, run_node

from stealth_nav2.covert_planning import TaskNumbers
from stealth_nav2.exposure_mask import DEFAULT_BAND_START, ExposureMask
from stealth_nav2.scene_source import (
    Scene,
    SceneError,
    SceneMissingError,
    SceneSource,
    scene_from_scenario,
)

NODE_NAME = 'exposure_mask'
KEEPOUT = 0  # CostmapFilterInfo.type of nav2_costmap_2d::KeepoutFilter (filter_values.hpp)
BASE, MULTIPLIER = 0.0, 1.0  # what KeepoutFilter requires (BASE_DEFAULT, MULTIPLIER_DEFAULT)
LATCHED_QOS = kept_qos(1)
SLOW_LOG_PERIOD = 10.0  # s of wall time between lines about updates slower than the period
CLOCK_STALL = 5.0  # s of wall time without /clock moving, while lights move, that are reported

PARAMETERS = {
    'scenario': Param(
        '',
        'Scenario (a name such as lgfloor-moving, from scenarios/ or $STEALTH_NAV_SCENARIOS, or '
        'the path of a scenario YAML): the map, the lights and the detection threshold; empty: '
        'the map topic (nav_msgs/OccupancyGrid) and the searchlights topic '
        '(stealth_interfaces/SearchlightArray) give the map and the lights.',
        read_only=True,
    ),
    'detection_threshold': Param(
        TaskNumbers.detection_threshold,
        'Light at which the robot is seen: the mask is lethal (100) from it. Scene from topics '
        'only (a scenario file brings its own).',
        (1e-6, 100.0),
        read_only=True,
    ),
    'mask_topic': Param(
        '/exposure_mask', 'Topic of the mask (nav_msgs/OccupancyGrid), named in the filter info.',
        read_only=True,
    ),
    'filter_info_topic': Param(
        '/costmap_filter_info',
        "Topic of the nav2_msgs/CostmapFilterInfo: the keepout filter's filter_info_topic.",
        read_only=True,
    ),
    'update_rate': Param(
        10.0, "Mask updates per second of the node's clock while lights move.", (0.1, 100.0)
    ),
    'band_start': Param(
        DEFAULT_BAND_START,
        'Where the graded band (mask values 1..99) starts, as a fraction of the detection '
        'threshold: light above band_start * threshold and below the threshold is graded; 1 = '
        'no band (only 0 and 100).',
        (0.0, 1.0),
    ),
    'lights_time_offset': Param(
        0.0,
        "The lights' clock is the node's clock (use_sim_time honoured) minus this (s): where "
        "their motions stand at t = 0 (as the planner server's parameter).",
        (-1e9, 1e9),
    ),
}  # fmt: skip


class ExposureMaskNode(StartupNode):
    """The mask of the scene and its filter info, kept up to date while lights move."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)

    def set_up(self) -> None:
        self._configured = False
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        values = declare_parameters(self, PARAMETERS)
        try:
            scene = scene_from_scenario(values['scenario']) if values['scenario'] else None
        except SceneError as error:
            raise StartupError(f'parameter scenario: {error}') from None
        self.detection_threshold = values['detection_threshold']
        self.band_start = values['band_start']
        self.lights_offset = values['lights_time_offset']
        self.update_rate = values['update_rate']
        self.mask_topic = values['mask_topic']
        self.source = SceneSource(
            scene,
            map_topic=self.resolve_topic_name('map'),
            lights_topic=self.resolve_topic_name('searchlights'),
        )
        self.scene: Scene | None = None
        self.mask: ExposureMask | None = None
        self._last: np.ndarray | None = None  # the values last published
        self.published = 0  # masks sent
        self._timer = None
        self._slow_logged = -SLOW_LOG_PERIOD
        self._clock_seen = (time.monotonic(), -1)  # (wall time, clock ns) it last moved
        self._clock_stalled = False
        self._info_publisher = self.create_publisher(
            CostmapFilterInfo, values['filter_info_topic'], LATCHED_QOS,
            event_callbacks=QUIET_PUBLISHER,
        )  # fmt: skip
        self._mask_publisher = self.create_publisher(
            OccupancyGrid, self.mask_topic, LATCHED_QOS, event_callbacks=QUIET_PUBLISHER
        )
        if scene is None:
            self.create_subscription(
                OccupancyGrid, 'map', self._on_map, LATCHED_QOS,
                event_callbacks=QUIET_SUBSCRIPTION,
            )  # fmt: skip
            self.create_subscription(
                SearchlightArray, 'searchlights', self._on_lights, LATCHED_QOS,
                event_callbacks=QUIET_SUBSCRIPTION,
            )  # fmt: skip
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(1.0, self._check_clock, clock=steady)
        self.publish_info()
        self._configured = True
        if scene is not None:
            self._use_scene(scene)
        else:
            self.get_logger().info(
                f'exposure mask on {self.mask_topic}: waiting for the scene on '
                f'{self.source.map_topic} and {self.source.lights_topic}; filter info on '
                f'{values["filter_info_topic"]}'
            )

    # --- the scene ------------------------------------------------------------------------------

    def _on_map(self, message: OccupancyGrid) -> None:
        self._on_scene_message(self.source.update_map, message, self.source.map_topic)

    def _on_lights(self, message: SearchlightArray) -> None:
        self._on_scene_message(self.source.update_lights, message, self.source.lights_topic)

    def _on_scene_message(self, update, message, topic: str) -> None:
        """A map or lights message: the mask built again when it changed the scene."""
        try:
            update(message)
        except SceneError as error:
            self.get_logger().warning(f'{topic}: message ignored: {error}')
            return
        try:
            scene = self.source.current()
        except SceneMissingError:
            return  # the other part is still to come
        except SceneError as error:  # e.g. the lights in another frame than the map
            self.get_logger().warning(f'scene not used: {error}')
            return
        if scene is not self.scene:
            self._use_scene(scene)

    def _use_scene(self, scene: Scene) -> None:
        scenario = scene.scenario
        threshold = scenario.detection_threshold if scenario else self.detection_threshold
        try:
            self.mask = ExposureMask(
                scene.blocked, scene.resolution, scene.origin, scene.lights, threshold,
                self.band_start, bounce=scenario.bounce if scenario else None,
            )  # fmt: skip
        except ValueError as error:  # a light off the map, say
            if self.scene is None and scenario is not None:
                raise StartupError(f'parameter scenario: {scene.source}: {error}') from None
            self.get_logger().error(f'scene from {scene.source} not used: {error}')
            return
        self.scene = scene
        self.update(force=True)
        self._schedule(self.update_rate if self.mask.moving else 0.0)
        occupancy = scene.map
        timing = (
            f"updated at {self.update_rate:g} Hz of the node's clock while its lights move"
            if self.mask.moving
            else 'static lights: published once'
        )
        self.get_logger().info(
            f'exposure mask of {scene.source} on {self.mask_topic}: {occupancy.width} x '
            f'{occupancy.height} cells of {occupancy.resolution:g} m, lethal at light >= '
            f'{threshold:g}, graded above {self.band_start * threshold:g}; {timing}'
        )

    # --- publishing -----------------------------------------------------------------------------

    def clock_seconds(self) -> float:
        """The node's clock now (s): simulated time under use_sim_time."""
        return self.get_clock().now().nanoseconds * 1e-9

    def publish_info(self) -> None:
        info = CostmapFilterInfo(
            type=KEEPOUT, filter_mask_topic=self.mask_topic, base=BASE, multiplier=MULTIPLIER
        )
        info.header.stamp = time_msg(self.clock_seconds())  # frame '' as Nav2's info server
        self._info_publisher.publish(info)

    def update(self, force: bool = False) -> None:
        """Compute the mask at the node's clock now; publish it when its values changed."""
        if self.mask is None:
            return
        started = time.perf_counter()
        now = self.clock_seconds()
        levels = self.mask.at(now - self.lights_offset)
        if force or self._last is None or not np.array_equal(levels, self._last):
            occupancy = self.scene.map
            message = grid_msg(levels, occupancy.resolution, occupancy.origin, now)
            message.header.frame_id = self.scene.frame_id
            self._mask_publisher.publish(message)
            self._last = levels
            self.published += 1
        self._check_cost(time.perf_counter() - started)

    def _check_cost(self, seconds: float) -> None:
        """A line (at most every SLOW_LOG_PERIOD s) when an update takes longer than its
        period: the mask then lags the lights."""
        if self._timer is None:
            return
        period = self._timer.timer_period_ns * 1e-9
        wall = time.monotonic()
        if seconds > period and wall - self._slow_logged >= SLOW_LOG_PERIOD:
            self._slow_logged = wall
            self.get_logger().warning(
                f'a mask update took {seconds * 1e3:.0f} ms, longer than its period '
                f'{period * 1e3:.0f} ms (update_rate {1 / period:g} Hz): the mask lags the '
                'lights; lower update_rate'
            )

    def _schedule(self, rate: float) -> None:
        """Update every 1/rate s of the node's clock; never when rate is 0."""
        if self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = None
        if rate > 0:
            self._timer = self.create_timer(1.0 / rate, self.update)  # the node's clock

    def _check_clock(self) -> None:
        """Under use_sim_time, with lights moving: a /clock that stopped, and its return."""
        if self._timer is None or not self.get_parameter('use_sim_time').value:
            return
        wall, now = time.monotonic(), self.get_clock().now().nanoseconds
        seen_at, seen = self._clock_seen
        if now != seen:
            self._clock_seen = (wall, now)
            if self._clock_stalled:
                self._clock_stalled = False
                self.get_logger().info(f'/clock runs again at {now * 1e-9:.3f} s')
        elif not self._clock_stalled and wall - seen_at >= CLOCK_STALL:
            self._clock_stalled = True
            self.get_logger().warning(
                f'/clock has not moved for {wall - seen_at:.0f} s (use_sim_time): the mask '
                f'stays at the lights of {now * 1e-9:.3f} s until it does'
            )

    # --- parameters -----------------------------------------------------------------------------

    def _validate_parameters(self, changes) -> SetParametersResult:
        """rclpy checks types, ranges and read-only; this checks what it cannot."""
        reason = non_finite(changes)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply_parameters(self, changes) -> None:
        if not self._configured:
            return
        for change in changes:
            if change.name == 'update_rate':
                self.update_rate = change.value
                if self.mask is not None and self.mask.moving:
                    self._schedule(change.value)
            elif change.name == 'band_start':
                self.band_start = change.value
                if self.mask is not None:
                    self.mask.band_start = change.value
                self.update()
            elif change.name == 'lights_time_offset':
                self.lights_offset = change.value
                self.update()
        names = ', '.join(f'{c.name}={c.value}' for c in changes)
        self.get_logger().info(f'parameters changed: {names}')


def main(args=None) -> int:
    return run_node(ExposureMaskNode, NODE_NAME, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
