"""System tests of the environment node's sensed track (``track: sensed``): the real simulator
and environment as processes on a private domain, a scripted agent in the test process, and the
Gym env's sensed track as the reference for the same actions."""

from nav_msgs.msg import OccupancyGrid
import numpy as np
import pytest
from stealth_core.gym_env import StealthNavEnv
from stealth_core.scenario import find_scenario, load_scenario
from stealth_core.sensing import flat_observation
from test_env_node import (
    LATCHED,
    SCENARIO,
    ScriptedAgent,
    covert_actions,
    start_env,
    start_sim,
    stop,
)

STEPS = 6


@pytest.fixture
def agent(node_processes, ros_context):
    """test_env_node's scripted agent (set up after node_processes, torn down before)."""
    scripted = ScriptedAgent(ros_context)
    yield scripted
    scripted.close()


def test_the_sensed_state_is_the_gym_envs_and_the_sensed_light_is_drawn(agent, node_processes):
    grids: list[OccupancyGrid] = []
    agent.node.create_subscription(OccupancyGrid, 'sensed_light', grids.append, LATCHED)
    scenario = load_scenario(SCENARIO)
    gym = StealthNavEnv(SCENARIO, goal='easy', track='sensed')
    observation, _ = gym.reset(seed=0)
    expected = [flat_observation(observation)]
    actions = covert_actions(find_scenario(SCENARIO), 'easy')[:STEPS]
    for action in actions:
        observation, *_ = gym.step(action)
        expected.append(flat_observation(observation))

    start_sim(node_processes, scenario)
    env = start_env(node_processes, scenario=SCENARIO, goal='easy', track='sensed')
    assert agent.spin_until(lambda: agent.received['description'], 20.0), env.log_path.read_text()
    description = agent.received['description'][0]
    length = len(expected[0])
    assert len(description.min_state_range) == len(description.max_state_range) == length
    assert description.num_states == gym.task.description()['num_states']
    low, high = np.array(description.min_state_range), np.array(description.max_state_range)

    states = [agent.next_state()]
    states += [agent.act(action)[0] for action in actions]
    for step, (state, want) in enumerate(zip(states, expected, strict=True)):
        got = np.array(state.state, dtype=np.float32)
        np.testing.assert_array_equal(got, want, err_msg=f'step {step}')
        assert np.all((got >= low) & (got <= high)), step

    rows, cols = gym.sensor.sensing.shape
    light = gym.sensor.sensing.grid(gym.sensor.memory.node_light)  # after the same actions
    known = light >= 0
    assert known.any() and (~known).any()
    levels = np.minimum(np.rint(light[known] / scenario.detection_threshold * 100), 100)

    def drawn(grid) -> np.ndarray:
        return np.array(grid.data, dtype=np.int8).reshape(grid.info.height, grid.info.width)

    def final_drawn() -> bool:
        """The last grid is the one after every action (counting grids is not enough: one
        published before the subscription matched is not delivered, only the latest is)."""
        if not grids or (grids[-1].info.height, grids[-1].info.width) != (rows, cols):
            return False
        cells = drawn(grids[-1])
        return bool((cells[~known] == -1).all() and np.array_equal(cells[known], levels))

    assert agent.spin_until(final_drawn, 10.0), [g.data.count(-1) for g in grids]
    grid = grids[-1]
    assert grid.header.frame_id == 'map' and grid.info.resolution == scenario.step_distance
    cells = drawn(grid)
    assert (cells[known] >= 0).all() and (cells[known] <= 100).all()
    assert (grids[0].data.count(-1) > grid.data.count(-1)) or len(grids) == 1
    stop(env)


def test_a_track_that_is_none_stops_the_node_with_one_clear_line(node_processes):
    process = start_env(node_processes, scenario=SCENARIO, track='partial')
    assert process.wait(30) == 2
    log = process.log_path.read_text()
    lines = [line for line in log.splitlines() if '[environment]' in line]
    assert len(lines) == 1 and 'not starting:' in lines[0] and 'Traceback' not in log, log
    assert "track must be one of full, sensed, got 'partial'" in lines[0]
