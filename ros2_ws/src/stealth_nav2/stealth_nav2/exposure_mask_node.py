"""The exposure mask node (``exposure_mask``): the lit area of a scenario as a mask for Nav2's
keepout filter (``nav2_costmap_2d::KeepoutFilter``), with the CostmapFilterInfo that tells the
filter where to find it, as Nav2's ``costmap_filter_info_server`` and a ``map_server`` of the
mask would. The values are ``stealth_nav2.exposure_mask``'s: 100 where the light is at or above
the detection threshold, a graded band 1..99 below it, 0 in the dark, -1 on walls and unknown
cells. ``config/nav2_exposure_filter.yaml`` is the costmap side.

    stealth run stealth_nav2 exposure_mask --ros-args -p scenario:=lgfloor-moving

## Topics

Both reliable, transient local, depth 1: the QoS the keepout filter subscribes with, so a
costmap that starts later still gets them.

* publishes ``filter_info_topic`` (``/costmap_filter_info``; nav2_msgs/CostmapFilterInfo) once:
  type 0 (keepout), ``filter_mask_topic`` the mask's topic, base 0.0 and multiplier 1.0 (the
  values the keepout filter requires);
* publishes ``mask_topic`` (``/exposure_mask``; nav_msgs/OccupancyGrid, frame ``map``, the
  scenario map's cells, resolution and origin), stamped with the node-clock time it shows.
  Static lights: once, and again only when the values change (``band_start``). Moving lights:
  every ``1 / update_rate`` s of the node's clock (simulated time under ``use_sim_time``: the
  simulator publishes ``/clock``), the lights where they are at that time, published when the
  values differ from the last mask sent.

## Parameters

``PARAMETERS`` below. A missing or unusable scenario stops the node with one line saying why
and exit code 2.
"""

from __future__ import annotations

import time

from nav2_msgs.msg import CostmapFilterInfo
from nav_msgs.msg import OccupancyGrid
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from stealth_env.env_messages import grid_msg
from stealth_env.scenario import ScenarioError, load_scenario
from stealth_node_kit.conversions import time_msg
from stealth_node_kit.endpoints import QUIET_PUBLISHER
from stealth_node_kit.param_table import Param
from stealth_node_kit.parameters import StartupError, declare_parameters, non_finite
from stealth_node_kit.qos import kept_qos
from stealth_node_kit.running import StartupNode, run_node

from stealth_nav2.exposure_mask import DEFAULT_BAND_START, ExposureMask

NODE_NAME = 'exposure_mask'
KEEPOUT = 0  # CostmapFilterInfo.type of nav2_costmap_2d::KeepoutFilter (filter_values.hpp)
BASE, MULTIPLIER = 0.0, 1.0  # what KeepoutFilter requires (BASE_DEFAULT, MULTIPLIER_DEFAULT)
LATCHED_QOS = kept_qos(1)
SLOW_LOG_PERIOD = 10.0  # s of wall time between lines about updates slower than the period

PARAMETERS = {
    'scenario': Param(
        '',
        'Scenario (required): a name such as lgfloor-moving (scenarios/ or '
        '$STEALTH_NAV_SCENARIOS) or the path of a scenario YAML: the map, the lights and the '
        'detection threshold.',
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
    'time_origin': Param(
        0.0,
        "The node-clock time (s) at which the scenario's lights are at their time 0: a moving "
        "light's pose at clock time c is the scenario's at c - time_origin.",
    ),
}  # fmt: skip


class ExposureMaskNode(StartupNode):
    """The mask of one scenario and its filter info, kept up to date while lights move."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)

    def set_up(self) -> None:
        self._configured = False
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        values = declare_parameters(self, PARAMETERS)
        self.scenario = self._load_scenario(values['scenario'])
        self.time_origin = values['time_origin']
        try:
            self.mask = ExposureMask.of_scenario(self.scenario, values['band_start'])
        except ValueError as error:  # e.g. a light off the map
            raise StartupError(f'parameter scenario: {self.scenario.path}: {error}') from None
        self.mask_topic = values['mask_topic']
        self._info_publisher = self.create_publisher(
            CostmapFilterInfo, values['filter_info_topic'], LATCHED_QOS,
            event_callbacks=QUIET_PUBLISHER,
        )  # fmt: skip
        self._mask_publisher = self.create_publisher(
            OccupancyGrid, self.mask_topic, LATCHED_QOS, event_callbacks=QUIET_PUBLISHER
        )
        self._last: np.ndarray | None = None  # the values last published
        self.published = 0  # masks sent
        self._slow_logged = -SLOW_LOG_PERIOD
        self._timer = None
        self.publish_info()
        self.update()
        if self.mask.moving:
            self._schedule(values['update_rate'])
        self._configured = True
        occupancy = self.scenario.map
        timing = (
            f"updated at {values['update_rate']:g} Hz of the node's clock while its lights move"
            if self.mask.moving
            else 'static lights: published once'
        )
        self.get_logger().info(
            f"exposure mask of scenario '{self.scenario.name}' ({self.scenario.path}) on "
            f'{self.mask_topic}: {occupancy.width} x {occupancy.height} cells of '
            f'{occupancy.resolution:g} m, lethal at light >= {self.mask.threshold:g}, graded '
            f'above {self.mask.band_start * self.mask.threshold:g}; {timing}; filter info on '
            f'{values["filter_info_topic"]}'
        )

    def _load_scenario(self, name: str):
        if not name:
            raise StartupError(
                'parameter scenario: required, a scenario name (e.g. lgfloor-moving) or the path '
                'of a scenario YAML'
            )
        try:
            return load_scenario(name)
        except (ScenarioError, OSError, ValueError) as error:
            raise StartupError(f'parameter scenario: {error}') from None

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
        started = time.perf_counter()
        now = self.clock_seconds()
        levels = self.mask.at(now - self.time_origin)
        if force or self._last is None or not np.array_equal(levels, self._last):
            occupancy = self.scenario.map
            self._mask_publisher.publish(
                grid_msg(levels, occupancy.resolution, occupancy.origin, now)
            )
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
        if self._timer is not None:
            self.destroy_timer(self._timer)
        self._timer = self.create_timer(1.0 / rate, self.update)  # the node's clock

    # --- parameters -----------------------------------------------------------------------------

    def _validate_parameters(self, changes) -> SetParametersResult:
        """rclpy checks types, ranges and read-only; this checks what it cannot."""
        reason = non_finite(changes)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply_parameters(self, changes) -> None:
        if not self._configured:
            return
        for change in changes:
            if change.name == 'update_rate' and self.mask.moving:
                self._schedule(change.value)
            elif change.name == 'band_start':
                self.mask.band_start = change.value
                self.update()
            elif change.name == 'time_origin':
                self.time_origin = change.value
                self.update()
        names = ', '.join(f'{c.name}={c.value}' for c in changes)
        self.get_logger().info(f'parameters changed: {names}')


def main(args=None) -> int:
    return run_node(ExposureMaskNode, NODE_NAME, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
