"""Benchmark: RL steps per second through the whole ROS loop, beside a bare rclpy ping-pong.

One step of the loop is: agent publishes RLAction -> env_node calls sim/execute_move ->
sim_node runs the move -> env_node judges it and publishes RLStateReward (and StepInfo) ->
agent answers at once with a random action. Episode ends and resets are part of the loop.
Measured in the same run, each in a private ROS domain, one after the other (no two compete
for the CPU):

1. **ping-pong**: round trips per second between two bare rclpy processes (std_msgs/Int64,
   reliable, each answering the other from its subscription callback): what one lockstep
   exchange between two Python processes costs at best;
2. **RL loop, sim_node**: sim_node with its cheapest settings (0.1 s physics steps, a fast
   robot, 10 particles, 8 beams, one filter update per move), env_node and a minimal agent process;
3. **RL loop, composed**: the same two nodes in one process (``stealth_bringup sim_env``), where
   the environment calls the simulator's services directly instead of over the middleware
   (``stealth_node_kit.in_process``); also at sim_node's default settings (200 particles,
   0.04 s physics steps, 60 beams), where the simulator's own work bounds the loop;
4. **RL loop, stub simulator**: the same as 2, with a stand-in for sim_node that answers each
   move at once on the move lattice (no physics, no localisation): what the ROS plumbing costs.

Each is measured REPEATS times and the best counts: other processes on the machine can only
slow a run down.

A step of the separate-process loop is two lockstep exchanges (topic and service) plus the
simulator's work, so its rate is at most half the ping-pong's; composed, one exchange plus the
work. The target, at least 0.3 of the ping-pong, is judged on the composed loop at the cheapest
settings. Also reported: the simulator's own moves per second in-process at the same settings,
the bound the loop can never beat. Needs the workspace built (``make setup``).
Run: ``source scripts/ros_env.sh && python bench/bench_ros_loop.py``.
"""

from __future__ import annotations

from pathlib import Path
import re
import sys
import tempfile
import time

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT / 'tests'))

from ros_support import (  # noqa: E402
    NodeProcesses,
    remove_orphaned_shm,
    reserved_domain_id,
    shm_segments,
)

SCENARIO = 'simple-maze'
ROUND_TRIPS = 3000
RESULT_NAMES = {'sim_node': 'separate'}  # in results.json: ros_loop_<name>_...
STEPS = {'sim_node': 2000, 'composed': 3000, 'composed_defaults': 1000, 'stub': 3000}
WARMUP = 200  # steps or round trips before the clock starts
REPEATS = 2  # each measurement; the best counts (other load on the machine only slows down)
TARGET_RATIO = 0.3
# A random walker's episodes on simple-maze last ~250 steps; far fewer means the environment
# aborts them (a simulator stand-in that rejects its moves did, unnoticed, for a while).
MIN_EPISODE_STEPS = 5
TIMEOUT = 600.0  # s for any one measurement
BIN = REPO_ROOT / 'ros2_ws' / 'install'
SIM_NODE = BIN / 'stealth_sim' / 'lib' / 'stealth_sim' / 'sim_node'
ENV_NODE = BIN / 'stealth_env' / 'lib' / 'stealth_env' / 'env_node'
SIM_ENV = BIN / 'stealth_bringup' / 'lib' / 'stealth_bringup' / 'sim_env'
FAST_SIM = {
    'physics_dt': 0.1,
    'particles': 10,
    'laser_beams': 8,
    # A filter update only at the end of each move (AMCL's forced update on a stop).
    'update_min_d': 5.0,
    'update_min_a': 3.14,
    'max_linear_speed': 5.0,
    'max_angular_speed': 10.0,
    'max_linear_accel': 20.0,
    'max_angular_accel': 50.0,
}
RELIABLE = """
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
"""

# argv: role (ping | pong), warm-up, count. The ping prints 'RESULT <count> <seconds>'.
PING_PONG = (
    """
import sys, time
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.task import Future
from std_msgs.msg import Int64
"""
    + RELIABLE
    + """
role, warmup, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
rclpy.init()
node = rclpy.create_node(f'bench_{role}')
executor = SingleThreadedExecutor()
executor.add_node(node)
try:
    if role == 'pong':
        pong = node.create_publisher(Int64, 'pong', QOS)
        node.create_subscription(Int64, 'ping', pong.publish, QOS)
        executor.spin()
    else:
        ping = node.create_publisher(Int64, 'ping', QOS)
        done, clock = Future(), {}
        def on_pong(message):
            if message.data == warmup:
                clock['start'] = time.perf_counter()
            if message.data == warmup + count:
                clock['end'] = time.perf_counter()
                done.set_result(True)
            else:
                ping.publish(Int64(data=message.data + 1))
        replies = node.create_subscription(Int64, 'pong', on_pong, QOS)
        while ping.get_subscription_count() == 0 or replies.get_publisher_count() == 0:
            executor.spin_once(timeout_sec=0.05)
        executor.spin_until_future_complete(Future(), timeout_sec=0.5)  # let matching settle
        ping.publish(Int64(data=0))
        executor.spin_until_future_complete(done)
        print(f"RESULT {count} {clock['end'] - clock['start']}", flush=True)
        executor.spin()  # until stopped
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    node.destroy_node()
    rclpy.try_shutdown()
"""
)

# argv: warm-up, steps, seed. Answers every state at once; prints 'RESULT <steps> <seconds>
# <episodes>' once it has the state that answers its last action.
AGENT = (
    """
import random, sys, time
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.task import Future
from stealth_interfaces.msg import RLAction, RLExperimentInfo, RLStateReward
"""
    + RELIABLE
    + """
warmup, steps, seed = map(int, sys.argv[1:4])
rclpy.init()
node = rclpy.create_node('bench_agent')
executor = SingleThreadedExecutor()
executor.add_node(node)
actions = node.create_publisher(RLAction, 'rl_agent/rl_action', QOS)
infos = node.create_publisher(RLExperimentInfo, 'rl_agent/rl_experiment_info', QOS)
rng = random.Random(seed)
counts = {'sent': 0, 'episodes': 0, 'measured_episodes': 0}
done, clock = Future(), {}

def on_state(message):
    sent = counts['sent']
    if sent == warmup and 'start' not in clock:
        clock['start'] = time.perf_counter()
    if sent == warmup + steps and not done.done():
        clock['end'] = time.perf_counter()
        done.set_result(True)
        return
    if message.terminal:
        infos.publish(RLExperimentInfo(episode_number=counts['episodes']))
        counts['episodes'] += 1
        counts['measured_episodes'] += 'start' in clock
    else:
        actions.publish(RLAction(action=rng.randrange(4)))
        counts['sent'] += 1

node.create_subscription(RLStateReward, 'rl_env/rl_state_reward', on_state, QOS)
try:
    executor.spin_until_future_complete(done)
    print(f"RESULT {steps} {clock['end'] - clock['start']} {counts['measured_episodes']}",
          flush=True)
    executor.spin()
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    node.destroy_node()
    rclpy.try_shutdown()
"""
)

# argv: scenario. sim_node's two services, answered at once on the move lattice: a move the
# lattice forbids leaves the robot where it is (as a bump would), the estimate is the truth,
# and each move takes 1 s of simulated time (a hold its seconds). It serves the kinds the
# environment sends (GO_TO a lattice node, TURN_TO_HEADING, HOLD) besides the grid moves.
STUB_SIM = """
import math, sys
import rclpy
from rclpy.executors import ExternalShutdownException
from stealth_core.move_lattice import ACTIONS, MoveLattice
from stealth_core.scenario import load_scenario
from stealth_interfaces.srv import ExecuteMove, ResetRobot

scenario = load_scenario(sys.argv[1])
lattice = MoveLattice.from_scenario(scenario)
HEADINGS = (math.pi / 2, -math.pi / 2, math.pi, 0.0)
rclpy.init()
node = rclpy.create_node('simulator')
state = {'node': (0, 0), 'heading': scenario.start[2], 'time': 0.0}

def set_pose(field):
    x, y = lattice.node_to_point(state['node'])
    field.position.x, field.position.y = x, y
    field.orientation.z = math.sin(state['heading'] / 2)
    field.orientation.w = math.cos(state['heading'] / 2)

def execute_move(request, response):
    seconds = 1.0
    if request.kind <= ExecuteMove.Request.RIGHT:
        target = lattice.successor(state['node'], request.kind)
        state['heading'] = HEADINGS[request.kind]
    elif request.kind == ExecuteMove.Request.GO_TO:  # what the environment sends: a lattice node
        target = lattice.point_to_node(request.x, request.y)
        if target != state['node']:
            x, y = lattice.node_to_point(state['node'])
            state['heading'] = math.atan2(request.y - y, request.x - x)
    elif request.kind == ExecuteMove.Request.TURN_TO_HEADING:
        target, state['heading'] = state['node'], request.heading
    elif request.kind == ExecuteMove.Request.HOLD:
        target, seconds = state['node'], request.seconds
    else:
        response.outcome, response.message = ExecuteMove.Response.REJECTED, 'not simulated'
        return response
    if target is None:
        response.outcome = ExecuteMove.Response.BUMPED
    else:
        state['node'] = target
    state['time'] += seconds
    set_pose(response.true_pose)
    set_pose(response.estimate.pose)
    response.duration = seconds
    response.stamp.sec = int(state['time'])
    response.stamp.nanosec = int(state['time'] % 1.0 * 1e9)
    return response

def reset(request, response):
    state['node'] = lattice.point_to_node(request.x, request.y)
    state['heading'] = request.yaw
    response.success = True
    return response

node.create_service(ExecuteMove, 'sim/execute_move', execute_move)
node.create_service(ResetRobot, 'sim/reset', reset)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    node.destroy_node()
    rclpy.try_shutdown()
"""


def _ros_args(params: dict) -> list[str]:
    args = ['--ros-args']
    for key, value in params.items():
        args += ['-p', f'{key}:={value}']
    return args


def _result(process, what: str) -> list[float]:
    """The numbers of the process's RESULT line, once it prints one."""
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline:
        match = re.search(r'^RESULT (.*)$', process.log_path.read_text(), re.MULTILINE)
        if match:
            return [float(v) for v in match.group(1).split()]
        if process.poll() is not None:
            break
        time.sleep(0.05)
    raise RuntimeError(f'{what}: no result; its log:\n{process.log_path.read_text()}')


class _Run:
    """A private domain and processes that are gone (and their shared memory too) afterwards."""

    def __enter__(self) -> NodeProcesses:
        self._domain = reserved_domain_id()
        domain_id = self._domain.__enter__()
        self._logs = tempfile.TemporaryDirectory(prefix='bench_ros_loop_')
        self._before = shm_segments()
        self.processes = NodeProcesses(domain_id, Path(self._logs.name))
        return self.processes

    def __exit__(self, *exc_info) -> None:
        try:
            self.processes.stop_all()
            if self.processes.any_killed:
                remove_orphaned_shm(self._before)
        finally:
            self._logs.cleanup()
            self._domain.__exit__(*exc_info)


def ping_pong() -> float:
    """Round trips per second between two bare rclpy processes."""
    with _Run() as processes:
        processes.start_python(PING_PONG, 'pong', 'pong', '0', '0')
        ping = processes.start_python(PING_PONG, 'ping', 'ping', str(WARMUP), str(ROUND_TRIPS))
        count, seconds = _result(ping, 'ping-pong')
    return count / seconds


def _params_file(directory: Path, node: str, values: dict) -> Path:
    import yaml

    path = directory / f'{node}.yaml'
    path.write_text(yaml.safe_dump({node: {'ros__parameters': values}}))
    return path


def rl_loop(simulator: str) -> tuple[float, float]:
    """(RL steps per second, episodes per second) with 'sim_node', 'composed' (sim_env at the
    FAST_SIM settings), 'composed_defaults' (sim_env, sim_node's defaults) or the 'stub'."""
    from stealth_core.scenario import load_scenario

    scenario = load_scenario(SCENARIO)
    x, y, yaw = scenario.start
    sim_params = {'map': str(scenario.map_path), 'initial_pose': [float(x), float(y), float(yaw)]}
    if simulator != 'composed_defaults':
        sim_params.update(FAST_SIM)
    env_params = {'scenario': SCENARIO, 'marker_period': 0.0, 'log_every': 0}
    with _Run() as processes:
        if simulator == 'sim_node':
            sim_file = _params_file(processes.log_dir, 'simulator', sim_params)
            processes.start([str(SIM_NODE), '--ros-args', '--params-file', str(sim_file)],
                            'sim_node')  # fmt: skip
        elif simulator == 'stub':
            processes.start_python(STUB_SIM, 'stub_sim', SCENARIO)
        if simulator.startswith('composed'):
            files = [
                _params_file(processes.log_dir, 'simulator', sim_params),
                _params_file(processes.log_dir, 'environment', env_params),
            ]
            args = [a for f in files for a in ('--params-file', str(f))]
            processes.start([str(SIM_ENV), '--ros-args', *args], 'sim_env')
        else:
            processes.start([str(ENV_NODE), *_ros_args(env_params)], 'env_node')
        steps = STEPS[simulator]
        agent = processes.start_python(AGENT, 'agent', str(WARMUP), str(steps), '7')
        steps, seconds, episodes = _result(agent, f'RL loop with {simulator}')
        if episodes > steps / MIN_EPISODE_STEPS:  # a loop of aborts measures nothing
            log = sorted(processes.log_dir.glob('*env*.log'))[-1]
            raise RuntimeError(
                f'RL loop with {simulator}: {episodes:.0f} episodes in {steps:.0f} steps, the '
                f'environment ends them at once; its log ends:\n{log.read_text()[-2000:]}'
            )
    return steps / seconds, episodes / seconds


def simulator_in_process(moves: int = 300) -> float:
    """Moves per second of the Simulator core at FAST_SIM settings, no ROS at all."""
    from stealth_core.kinematics import Limits, Pose
    from stealth_core.moves import MoveRequest
    from stealth_core.scenario import load_scenario
    from stealth_sim.laser import LaserConfig
    from stealth_sim.localisation import FilterConfig
    from stealth_sim.move_executor import execute_move
    from stealth_sim.simulator import SimConfig, Simulator

    scenario = load_scenario(SCENARIO)
    config = SimConfig(
        physics_dt=FAST_SIM['physics_dt'],
        limits=Limits(
            FAST_SIM['max_linear_speed'],
            FAST_SIM['max_angular_speed'],
            FAST_SIM['max_linear_accel'],
            FAST_SIM['max_angular_accel'],
        ),
        laser=LaserConfig(beams=FAST_SIM['laser_beams']),
        filter=FilterConfig(
            particles=FAST_SIM['particles'],
            update_min_d=FAST_SIM['update_min_d'],
            update_min_a=FAST_SIM['update_min_a'],
        ),
    )
    sim = Simulator(scenario.map, config, Pose(*scenario.start))
    # Untimed, as bench_sim's: the process's first compiled move loads numba's kernels (or
    # compiles them), which is no part of a move's cost (it was a third of this figure).
    execute_move(sim, MoveRequest(1, scenario.step_distance))
    started = time.perf_counter()
    for index in range(moves):
        execute_move(sim, MoveRequest(index % 2, scenario.step_distance))  # up and down
    return moves / (time.perf_counter() - started)


def run(report=print) -> dict:
    for path in (SIM_NODE, ENV_NODE, SIM_ENV):
        if not path.exists():
            raise RuntimeError(f'{path} is missing: build the workspace first (make setup)')
    round_trips = max(ping_pong() for _ in range(REPEATS))
    loops = {kind: max(rl_loop(kind) for _ in range(REPEATS)) for kind in STEPS}
    core = simulator_in_process()
    ratios = {kind: steps / round_trips for kind, (steps, _) in loops.items()}
    ratio = ratios['composed']
    verdict = 'met' if ratio >= TARGET_RATIO else 'NOT met'
    report(
        f'ROS loop, {SCENARIO}, a random agent answering at once (all in one run, best of '
        f'{REPEATS}):'
    )
    report(f'  bare rclpy ping-pong (two processes): {round_trips:.0f} round trips/s')
    lines = {
        'composed': 'simulator and environment composed (sim_env), cheapest settings',
        'sim_node': 'sim_node and env_node, separate processes, cheapest settings',
        'composed_defaults': "composed, sim_node's default settings",
        'stub': 'a stub simulator (no physics), separate processes',
    }
    for kind, what in lines.items():
        steps, episodes = loops[kind]
        target = f' (target >= {TARGET_RATIO}: {verdict})' if kind == 'composed' else ''
        report(
            f'  RL loop, {what}: {steps:.0f} steps/s ({episodes:.1f} episodes/s), '
            f'{ratios[kind]:.2f} of ping-pong{target}'
        )
    report(
        f'  the simulator core alone at the cheapest settings: {core:.0f} moves/s in-process '
        f'(a bound on the loop at those settings)'
    )
    results = {
        'ros_loop_ping_pong_round_trips_per_second': round(round_trips, 1),
        'ros_loop_target_ratio': TARGET_RATIO,
        'ros_loop_target_met': bool(ratio >= TARGET_RATIO),
        'ros_loop_sim_core_moves_per_second': round(core, 1),
    }
    for kind, (steps, episodes) in loops.items():
        name = 'ros_loop_' + RESULT_NAMES.get(kind, kind)
        results[f'{name}_steps_per_second'] = round(steps, 1)
        results[f'{name}_ratio_to_ping_pong'] = round(ratios[kind], 3)
        results[f'{name}_episodes_per_second'] = round(episodes, 2)
    return results


def main() -> dict:
    return run()


if __name__ == '__main__':
    main()
