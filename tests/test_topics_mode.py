"""System tests of the environment's ``topics`` robot interface: the real simulator standing in
for Stage + AMCL over its standard topics (cmd_vel, odom, amcl_pose, scan, ground_truth,
initialpose), the environment driving it closed-loop, a scripted agent in the test process."""

import math
import time

from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
import pytest
from rclpy.qos import qos_profile_sensor_data
from stealth_bringup.run_plan import SIM_TIME, TOPICS_ENVIRONMENT, TOPICS_SIMULATOR
from stealth_core.scenario import find_scenario, load_scenario
from stealth_core.task import StealthTask
from stealth_interfaces.msg import EpisodeSummary, RLAction, RLExperimentInfo
from test_env_node import (
    LATCHED,
    LEFT,
    RIGHT,
    SCENARIO,
    UP,
    ScriptedAgent,
    check_step,
    copy_scenario,
    covert_actions,
    start_env,
    start_sim,
    stop,
    totals,
    wait_for_log,
)

# A simulator paced on its own clock, as a robot is, and the environment on the wall clock; at
# 4x, where 20x failed moves when the machine was busy (the clock ran on while the controller
# waited for a core: a 9 s move timeout was 0.45 s of wall time).
PACED_SIM = {'real_time_factor': 4.0, 'idle_period': 0.01, 'publish_rate': 5.0}
PACED_ENV = {'robot_interface': 'topics', 'marker_period': 0.0}
# What the run sets for topics mode (stealth_bringup's run plan): the simulator in lockstep with
# the controller (one odometry per 0.2 s control period, the next as soon as its command came),
# both nodes on simulated time.
TOPICS_SIM = {**TOPICS_SIMULATOR, **SIM_TIME}
TOPICS_ENV = {**PACED_ENV, **TOPICS_ENVIRONMENT, **SIM_TIME}


@pytest.fixture
def agent(node_processes, ros_context):
    """As test_env_node's: set up after (so torn down before) node_processes."""
    scripted = ScriptedAgent(ros_context)
    yield scripted
    scripted.close()


def test_covert_path_over_topics_reaches_the_goal_then_teleports_back(agent, node_processes):
    scenario = load_scenario(SCENARIO)
    task = StealthTask(scenario, 'easy')
    start_sim(node_processes, scenario, **TOPICS_SIM)
    env = start_env(node_processes, scenario=SCENARIO, goal='easy', **TOPICS_ENV)
    wait_for_log(env, 'robot over topics (/cmd_vel, /odom, /amcl_pose, /scan, /ground_truth')
    first = agent.next_state(timeout=30.0)
    assert (list(first.state), first.terminal) == ([1.5, 1.5], False)
    actions = covert_actions(find_scenario(SCENARIO), 'easy')
    started = time.monotonic()
    for number, action in enumerate(actions, start=1):
        state, info = agent.act(action)
        check_step(task, state, info)
        assert (info.episode, info.step, info.action) == (0, number, action)
        assert math.isfinite(info.true_pose.x)  # ground_truth is published: judged on it
        if state.terminal:
            break
    elapsed = time.monotonic() - started
    print(f'\ntopics: {number} covert moves in {elapsed:.1f} s ({number / elapsed:.1f} steps/s)')
    assert state.terminal and number >= len(actions) - 3, f'step {number}: {info}'
    assert agent.spin_until(lambda: agent.summaries, 5.0)
    assert agent.summaries[0].outcome == EpisodeSummary.SUCCESS
    assert agent.summaries[0].path_length == pytest.approx(0.5 * number, rel=0.1)

    # Into a wall the map shows: the robot keeps its node (as on the lattice), judged like any
    # step; the episode goes on.
    agent.info_pub.publish(RLExperimentInfo(episode_number=0, number_actions=number))
    again = agent.next_state(timeout=30.0)
    assert (list(again.state), again.terminal) == ([1.5, 1.5], False)
    node = (1.5, 1.5)
    for _ in range(2):  # one step west, then the west wall blocks the move
        expected = task.move_target(*node, LEFT)
        state, info = agent.act(LEFT)
        check_step(task, state, info)
        assert (list(state.state), state.terminal) == ([*expected], False)
        assert math.dist((info.true_pose.x, info.true_pose.y), expected) < 0.1
        node = expected
    assert node == (1.0, 1.5)  # the second move was blocked: the robot kept its node
    log = stop(env)
    assert 'the robot met a wall or unknown space and stopped' not in log
    counts = totals(log)
    assert counts['received'] == counts['executed'] == number + 2


@pytest.mark.parametrize(
    ('sim_params', 'env_params'),
    [(PACED_SIM, PACED_ENV), (TOPICS_SIM, TOPICS_ENV)],
    ids=['paced', 'lockstep'],
)
def test_drive_reset_and_bad_estimates(agent, node_processes, tmp_path, sim_params, env_params):
    """reset_mode drive brings the robot back over the lattice and re-initialises AMCL; an
    amcl_pose in another frame or a NaN one is dropped with one line naming the topic. In
    lockstep too: the initialpose once came with a second odometry of its period, and every
    command after it acted a period late (the first move after a drive home timed out)."""
    path = copy_scenario(tmp_path, SCENARIO, step_limit=3)
    scenario = load_scenario(path)
    sim = start_sim(node_processes, scenario, **sim_params)
    env = start_env(node_processes, scenario=path, reset_mode='drive', **env_params)
    agent.next_state(timeout=30.0)
    for action in (RIGHT, RIGHT, UP):
        state, info = agent.act(action)
    assert list(state.state) == [2.5, 2.0] and state.terminal  # the step limit

    bad = agent.node.create_publisher(PoseWithCovarianceStamped, 'amcl_pose', LATCHED)
    message = PoseWithCovarianceStamped()
    message.header.frame_id = 'odom'
    bad.publish(message)
    wait_for_log(env, "amcl_pose: message dropped, frame 'odom', expected 'map'")
    message.header.frame_id = 'map'
    message.pose.pose.position.x = math.nan
    bad.publish(message)
    wait_for_log(env, 'amcl_pose: message dropped, pose (nan, 0.0, yaw 0.0) is not finite')
    agent.node.destroy_publisher(bad)

    truths = []
    agent.node.create_subscription(
        Odometry, 'ground_truth', truths.append, qos_profile_sensor_data
    )
    agent.info_pub.publish(RLExperimentInfo(episode_number=0, number_actions=3))
    first = agent.next_state(timeout=60.0)
    assert (list(first.state), first.terminal) == ([1.5, 1.5], False)
    wait_for_log(sim, 'initial pose set to (1.50, 1.50, 1.57)')
    assert agent.spin_until(lambda: truths, 5.0)
    truth = truths[-1].pose.pose.position
    assert math.dist((truth.x, truth.y), scenario.start[:2]) < 0.15
    state, info = agent.act(RIGHT)
    assert (info.episode, info.step, list(state.state)) == (1, 1, [2.0, 1.5])
    assert totals(stop(env))['states'] == len(agent.states)


def test_a_robot_that_ignores_cmd_vel_stops_the_run_with_a_clear_line(agent, node_processes):
    scenario = load_scenario(SCENARIO)
    start_sim(node_processes, scenario, **PACED_SIM)
    # cmd_vel goes nowhere: the robot never hears a command.
    env = start_env(
        node_processes,
        scenario=SCENARIO,
        unresponsive_moves=2,
        extra_args=['-r', 'cmd_vel:=nobody_listens'],
        **PACED_ENV,
    )
    agent.next_state(timeout=30.0)
    state, info = agent.act(RIGHT, timeout=60.0)  # TIMED_OUT, judged where the robot stands
    assert list(state.state) == [1.5, 1.5] and not state.terminal
    agent.action_pub.publish(RLAction(action=RIGHT))
    aborted = agent.next_state(timeout=60.0)
    assert aborted.terminal and aborted.reward == 0.0
    assert agent.spin_until(lambda: agent.summaries, 5.0)
    assert agent.summaries[0].outcome == EpisodeSummary.ABORTED
    assert env.wait(20) == 3
    log = env.log_path.read_text()
    assert (
        'stopping: the robot is not responding to /nobody_listens: 2 moves in a row timed '
        'out without it moving' in log
    ), log
    assert totals(log)['states'] == 3


def test_steps_per_second_topics_against_service(agent, node_processes):
    """Measured, not asserted: the same random walk through both robot interfaces."""
    scenario = load_scenario(SCENARIO)
    rates = {}
    service = {**PACED_ENV, 'robot_interface': 'service'}
    for interface, sim_params, env_params in (
        ('service', {}, service),
        ('topics', TOPICS_SIM, TOPICS_ENV),
    ):
        sim = start_sim(node_processes, scenario, name=f'sim_{interface}', **sim_params)
        env = start_env(node_processes, name=f'env_{interface}', scenario=SCENARIO, **env_params)
        agent.next_state(timeout=30.0)
        steps, started = 0, time.monotonic()
        actions = (RIGHT, RIGHT, UP, LEFT, 1, RIGHT, UP, LEFT, LEFT, 1) * 4  # 1: down
        for action in actions:
            state, _ = agent.act(action, timeout=60.0)
            steps += 1
            if state.terminal:
                break
        rates[interface] = steps / (time.monotonic() - started)
        stop(env)
        stop(sim)
        agent.disconnect()
        agent.connect()
    print(
        f'\nsteps/s: service {rates["service"]:.1f}, topics {rates["topics"]:.1f} '
        f'({rates["service"] / rates["topics"]:.1f}x)'
    )


def test_a_topics_run_is_on_simulated_time_in_lockstep_with_the_controller(tmp_path):
    """stealth train --set environment.robot_interface=topics: the simulator in lockstep
    (real_time_factor 0, one odom per 0.2 s control period), the controller told a command acts
    from the odometry it answers, and every node on use_sim_time; --set still wins, --watch
    stays real time, and a service run is on the wall clock as before."""
    from stealth_bringup.run_arguments import train_parser
    from stealth_bringup.run_plan import make_plan

    def parameters(*options: str) -> dict:
        argv = ['--runs-dir', str(tmp_path), *options]
        plan = make_plan(train_parser().parse_args(argv), 'train', argv)
        return {node: p.values for node, p in plan.parameters.items()}

    topics = ('--set', 'environment.robot_interface=topics')
    run = parameters(*topics)
    assert TOPICS_SIMULATOR.items() <= run['simulator'].items()
    assert TOPICS_ENVIRONMENT.items() <= run['environment'].items()
    assert sorted(run) == ['agent', 'environment', 'recorder', 'simulator']
    assert all(values['use_sim_time'] is True for values in run.values())
    service = parameters()
    assert service['simulator']['real_time_factor'] == 0.0
    assert not any('use_sim_time' in values for values in service.values())
    changed = parameters(*topics, '--set', 'simulator.real_time_factor=10.0')
    assert changed['simulator']['real_time_factor'] == 10.0
    watched = parameters(*topics, '--watch')
    assert watched['simulator']['real_time_factor'] == 1.0
    assert all(values['use_sim_time'] is True for values in watched.values())
