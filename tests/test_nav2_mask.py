"""System tests of stealth_nav2's exposure_mask node, started with `stealth run` on a private
domain: the CostmapFilterInfo Nav2's keepout filter reads, the mask's QoS (a subscriber that
comes late still gets both), its geometry and values, and, on simulated time driven by the
test's own /clock, a moving scenario's masks following the lights at the clock's time."""

from nav2_msgs.msg import CostmapFilterInfo
from nav_msgs.msg import OccupancyGrid
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from ros_support import REPO_ROOT, SpinningNode, wait_for_output
from rosgraph_msgs.msg import Clock
from stealth_core.scenario import load_scenario
from stealth_env.env_messages import searchlight_array_msg
from stealth_interfaces.msg import SearchlightArray
from stealth_nav2.exposure_mask import LETHAL, ExposureMask
from stealth_nav2.scene_source import scene_from_messages
from stealth_node_kit.conversions import seconds, time_msg
from stealth_sim.sim_messages import occupancy_grid

STEALTH = str(REPO_ROOT / 'ros2_ws/install/stealth_tools/lib/stealth_tools/stealth')
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
STARTED = 'exposure mask of scenario'  # the node's startup line, logged after publishing


class MaskClient(SpinningNode):
    """The costmap's side: the filter info and the mask, subscribed as KeepoutFilter does."""

    def __init__(self, context):
        super().__init__('mask_test_client', context)
        self.infos: list[CostmapFilterInfo] = []
        self.masks: list[OccupancyGrid] = []
        self.clock = self.node.create_publisher(Clock, '/clock', 10)

    def subscribe(self, mask_topic: str = '/exposure_mask') -> None:
        self.node.create_subscription(
            CostmapFilterInfo, '/costmap_filter_info', self.infos.append, LATCHED
        )
        self.node.create_subscription(OccupancyGrid, mask_topic, self.masks.append, LATCHED)

    def publish_clock(self, t: float) -> None:
        self.clock.publish(Clock(clock=time_msg(t)))


@pytest.fixture
def client(node_processes, ros_context):
    """Set up after (so torn down before) node_processes, which checks for leftovers."""
    mask_client = MaskClient(ros_context)
    yield mask_client
    mask_client.close()


def start_mask(node_processes, scenario: str, *params: str):
    """`stealth run` of the node on the scenario ('': none, the scene from topics)."""
    args = [STEALTH, 'run', 'stealth_nav2', 'exposure_mask', '--ros-args']
    if scenario:
        args += ['-p', f'scenario:={scenario}']
    for param in params:
        args += ['-p', param]
    return node_processes.start(
        args, 'exposure_mask', extra_env={'RCUTILS_LOGGING_BUFFERED_STREAM': '0'}
    )


def latest_stamp(client: MaskClient) -> float:
    return seconds(client.masks[-1].header.stamp)


def values_of(mask: OccupancyGrid) -> np.ndarray:
    return np.asarray(mask.data, dtype=np.int8).reshape(mask.info.height, mask.info.width)


def test_static_scenario_latches_the_filter_info_and_the_mask(client, node_processes):
    process = start_mask(node_processes, 'map1')
    wait_for_output(process, STARTED, 60.0)
    client.subscribe()  # late: both were published before this subscriber existed
    assert client.spin_until(lambda: client.infos and client.masks, 30.0), (
        process.log_path.read_text()
    )
    info = client.infos[-1]
    assert info.type == 0  # keepout
    assert info.filter_mask_topic == '/exposure_mask'
    assert (info.base, info.multiplier) == (0.0, 1.0)

    publishers = client.node.get_publishers_info_by_topic('/exposure_mask')
    assert len(publishers) == 1
    qos = publishers[0].qos_profile
    assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert qos.reliability == ReliabilityPolicy.RELIABLE

    scenario = load_scenario('map1')
    occupancy, mask = scenario.map, client.masks[-1]
    assert mask.header.frame_id == 'map'
    assert (mask.info.width, mask.info.height) == (occupancy.width, occupancy.height)
    assert mask.info.resolution == pytest.approx(occupancy.resolution)
    origin = mask.info.origin.position
    assert (origin.x, origin.y) == pytest.approx(occupancy.origin[:2])
    expected = ExposureMask.of_scenario(scenario).at(0.0)
    assert np.array_equal(values_of(mask), expected)
    assert np.count_nonzero(expected == LETHAL) and np.count_nonzero(
        (expected > 0) & (expected < LETHAL)
    )

    client.spin_for(1.5)  # static lights: nothing more is sent
    assert len(client.masks) == 1

    parameters = AsyncParameterClient(client.node, 'exposure_mask')
    assert parameters.wait_for_services(10.0)
    future = parameters.set_parameters([Parameter('band_start', value=1.0)])
    assert client.spin_until(future.done, 10.0) and future.result().results[0].successful
    assert client.spin_until(lambda: len(client.masks) == 2, 10.0), process.log_path.read_text()
    values = values_of(client.masks[-1])
    assert set(np.unique(values).tolist()) <= {-1, 0, LETHAL}  # no band left
    assert np.array_equal(values == LETHAL, expected == LETHAL)


def test_moving_scenario_follows_the_lights_on_simulated_time(client, node_processes):
    process = start_mask(
        node_processes, 'simple-maze-moving', 'use_sim_time:=true', 'update_rate:=10.0'
    )
    wait_for_output(process, STARTED, 60.0)
    client.subscribe()
    assert client.spin_until(lambda: client.masks, 30.0), process.log_path.read_text()
    assert seconds(client.masks[0].header.stamp) == 0.0  # no /clock yet: simulated time 0

    end, step = 3.0, 0.05
    for k in range(1, round(end / step) + 1):  # 3 s of simulated time, at its own pace
        t = k * step
        client.publish_clock(t)
        if k % 2 == 0:  # every timer period: wait for the mask of this time
            assert client.spin_until(lambda t=t: latest_stamp(client) >= t - 1e-6, 20.0), (
                t,
                process.log_path.read_text(),
            )
        else:
            client.spin_for(0.01)

    stamps = [seconds(mask.header.stamp) for mask in client.masks]
    assert stamps == sorted(stamps)
    assert len(client.masks) >= 5 * end  # >= 5 Hz of simulated time, each one different
    scenario = load_scenario('simple-maze-moving')
    model = ExposureMask.of_scenario(scenario)
    for before, after in zip(client.masks, client.masks[1:], strict=False):
        assert not np.array_equal(values_of(before), values_of(after))
    for mask in client.masks[-3:]:  # each the lights at its stamp, the node's clock time
        assert np.array_equal(values_of(mask), model.at(seconds(mask.header.stamp)))

    wait_for_output(process, '/clock has not moved for')  # the simulator stopped: said so
    client.publish_clock(end + step)
    wait_for_output(process, '/clock runs again at')


def test_scene_from_the_map_and_searchlights_topics(client, node_processes):
    """No scenario: the mask of the latest map and lights, built again when the lights change;
    a message that cannot be used is dropped with a line naming the topic."""
    process = start_mask(node_processes, '', 'detection_threshold:=0.3')
    wait_for_output(process, 'waiting for the scene on /map and /searchlights')
    scenario = load_scenario('simple-maze')
    map_publisher = client.node.create_publisher(OccupancyGrid, '/map', LATCHED)
    lights_publisher = client.node.create_publisher(SearchlightArray, '/searchlights', LATCHED)
    grid = occupancy_grid(scenario.map)
    map_publisher.publish(grid)
    lights_msg = searchlight_array_msg(scenario.lights, 0.0)
    lights_publisher.publish(lights_msg)
    client.subscribe()
    assert client.spin_until(lambda: client.masks, 30.0), process.log_path.read_text()
    expected = mask_of(grid, lights_msg, 0.3)
    assert np.array_equal(values_of(client.masks[-1]), expected)

    bad = searchlight_array_msg(scenario.lights, 0.0)
    bad.lights[0].range = -1.0
    lights_publisher.publish(bad)
    wait_for_output(process, '/searchlights: message ignored: SearchlightArray: lights[0]')
    one_light = searchlight_array_msg(scenario.lights[:1], 0.0)
    lights_publisher.publish(one_light)
    assert client.spin_until(lambda: len(client.masks) == 2, 30.0), process.log_path.read_text()
    fewer = mask_of(grid, one_light, 0.3)
    assert np.array_equal(values_of(client.masks[-1]), fewer)
    assert not np.array_equal(fewer, expected)


def mask_of(grid_msg: OccupancyGrid, lights_msg: SearchlightArray, threshold: float):
    """The mask of a map and lights as a subscriber gets them (the map's resolution float32)."""
    scene = scene_from_messages(
        *(deserialize_message(serialize_message(m), type(m)) for m in (grid_msg, lights_msg))
    )
    origin = scene.origin
    return ExposureMask(scene.blocked, scene.resolution, origin, scene.lights, threshold).at(0.0)


def test_a_missing_scenario_stops_the_node_with_one_line(node_processes):
    process = node_processes.start(
        [STEALTH, 'run', 'stealth_nav2', 'exposure_mask', '--ros-args', '-p', 'scenario:=nope'],
        'exposure_mask_bad',
    )
    assert process.wait(60) != 0
    output = process.log_path.read_text()
    assert "parameter scenario: scenario 'nope': not found" in output
    assert 'Traceback' not in output
