"""Simulated time (issue 28): a `stealth train` run through the topics interface runs on the
simulator's /clock, in lockstep with the controller and faster than the wall clock, with every
node on use_sim_time; a /clock that stops is reported and ends the episode, never waited on."""

import json
import os
import re
import select
import signal
import time

from rcl_interfaces.srv import GetParameters
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_support import SpinningNode, ros_environment
from rosgraph_msgs.msg import Clock
from stealth_core.scenario import load_scenario
from stealth_interfaces.msg import EpisodeSummary, RLAction, RLExperimentInfo
from test_env_node import RIGHT, SCENARIO, ScriptedAgent, start_env, start_sim, wait_for_log
import test_system

system = test_system.system  # the fixture of `stealth` runs, with its checks afterwards
RUN_NODES = ('recorder', 'simulator', 'environment', 'agent')
# What stealth train sets for a topics run (stealth_bringup.run_plan), on simulated time.
LOCKSTEP_SIM = {'real_time_factor': 0.0, 'publish_rate': 5.0, 'use_sim_time': True}
LOCKSTEP_ENV = {
    'robot_interface': 'topics',
    'command_latency': 0.0,
    'marker_period': 0.0,
    'use_sim_time': True,
}


def _domain_of(run, timeout: float = 60.0) -> int:
    """The run's private ROS_DOMAIN_ID, from its opening lines (stdout or stderr)."""
    deadline = time.monotonic() + timeout
    seen = ''
    while time.monotonic() < deadline and run.poll() is None:
        ready, _, _ = select.select([run.stdout], [], [], 0.2)
        if ready:
            seen += run.stdout.readline()
        found = re.search(r'ROS_DOMAIN_ID (\d+)', seen + run.stderr_path.read_text())
        if found:
            return int(found.group(1))
    raise AssertionError(f'no ROS_DOMAIN_ID announced:\n{seen}{run.stderr_path.read_text()}')


def _use_sim_time(probe: SpinningNode, nodes: tuple[str, ...], run) -> dict[str, bool | None]:
    """Each node's use_sim_time as its parameter service answers (None: no answer). All are
    asked at once, while the run lives: a short run may end before a one-by-one probe is done."""
    clients = {
        node: probe.node.create_client(GetParameters, f'/{node}/get_parameters') for node in nodes
    }
    try:
        # Each request goes again every second until answered (SpinningNode.handshake: why).
        request = GetParameters.Request(names=['use_sim_time'])
        answers = probe.handshake(
            {node: (client, request) for node, client in clients.items()},
            80.0,
            alive=lambda: run.poll() is None,
        )
        return {
            node: answers[node].values[0].bool_value if node in answers else None for node in nodes
        }
    finally:
        for client in clients.values():
            probe.node.destroy_client(client)


def test_a_topics_run_is_on_simulated_time_faster_than_the_wall(system, monkeypatch):
    """Every node of the run says use_sim_time is true; its /clock advances in lockstep with
    the controller, and over the run more simulated than wall seconds pass (loosely: a move
    takes seconds of robot time and a small fraction of that on the wall)."""
    import rclpy

    scenario = test_system.short_scenario(system.tmp_path)
    run = system.start(
        'train', '--scenario', str(scenario), '--goal', 'easy', '--episodes', '8', '--seed', '3',
        '--set', 'environment.robot_interface=topics', '--name', 'topics', log='topics.txt',
    )  # fmt: skip
    domain = _domain_of(run)
    for key, value in ros_environment(domain).items():
        if key.startswith('ROS_'):
            monkeypatch.setenv(key, value)
    monkeypatch.delenv('ROS_LOCALHOST_ONLY', raising=False)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    try:
        probe = SpinningNode('sim_time_probe', context)
        clocks = []
        best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        probe.node.create_subscription(Clock, '/clock', clocks.append, best_effort)
        answers = _use_sim_time(probe, RUN_NODES, run)
        assert probe.spin_until(lambda: len(clocks) > 1, 30.0), 'no /clock'
        probe.close()
    finally:
        context.try_shutdown()
    assert answers == dict.fromkeys(RUN_NODES, True), (
        f'run ended ({run.returncode}) before every node answered'
        if run.poll() is not None
        else 'a node did not answer or is not on simulated time'
    )

    assert run.wait(600) == 0, run.stderr_path.read_text()
    directory = system.runs / 'topics'
    summary = json.loads((directory / 'summary.json').read_text())
    wall = summary['wall_time_s']
    steps = test_system.read_bag(directory / 'recording.mcap')[1]['/rl_env/step_info']
    stamp = steps[-1].header.stamp
    simulated = stamp.sec + stamp.nanosec * 1e-9
    print(f'\n{len(steps)} steps: {simulated:.0f} s of simulated time in {wall:.0f} s of wall')
    assert simulated > wall


def test_a_stopped_clock_ends_the_episode_with_a_line_naming_it(node_processes, ros_context):
    """The simulator stops (SIGSTOP) under a move: the environment, on simulated time, does not
    wait for ever but ends the episode ABORTED saying /clock has not advanced and for how long;
    once the simulator runs again the next episode goes on."""
    scenario = load_scenario(SCENARIO)
    sim = start_sim(node_processes, scenario, **LOCKSTEP_SIM)
    env = start_env(node_processes, scenario=SCENARIO, clock_timeout=2.0, **LOCKSTEP_ENV)
    agent = ScriptedAgent(ros_context)
    try:
        agent.next_state(timeout=60.0)
        state, _ = agent.act(RIGHT, timeout=60.0)  # the loop runs on the simulator's clock
        assert list(state.state) == [2.0, 1.5]
        os.killpg(sim.pid, signal.SIGSTOP)
        try:
            agent.action_pub.publish(RLAction(action=RIGHT))
            aborted = agent.next_state(timeout=60.0)
            assert aborted.terminal and aborted.reward == 0.0
            log = wait_for_log(env, 'ABORTED after 1 steps: /clock has not advanced for ')
            line = next(x for x in log.splitlines() if 'ABORTED after 1 steps' in x)
            silent = float(re.search(r'advanced for ([\d.]+) s of wall time', line).group(1))
            assert silent >= 2.0, line
            assert 'clock_timeout 2 s: is the simulator running, or paused?' in line
        finally:
            os.killpg(sim.pid, signal.SIGCONT)
        assert agent.spin_until(lambda: agent.summaries, 10.0)
        assert agent.summaries[0].outcome == EpisodeSummary.ABORTED
        agent.info_pub.publish(RLExperimentInfo(episode_number=0, number_actions=2))
        first = agent.next_state(timeout=60.0)  # the teleport answers: the next episode
        assert (list(first.state), first.terminal) == ([1.5, 1.5], False)
        _, info = agent.act(RIGHT, timeout=60.0)
        # The episode goes on. (Where its first move ends is not asserted: under load the first
        # move after the simulator resumes sometimes ends where it began, a known open problem.)
        assert (info.episode, info.step) == (1, 1)
    finally:
        agent.close()
