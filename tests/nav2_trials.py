"""Repeated runs of the navigator to lgfloor's hard goal at the simulator's default odometry
noise: how many reach the goal undetected (a measurement, not a test: `make test` does not
collect it). Each run has its own simulator seed, private DDS domain and processes.

    source scripts/ros_env.sh
    python tests/nav2_trials.py --runs 10 [--first-seed 1] [--set clearance_margin:=0.0 ...]

The code before a change: extract it (``git archive <rev> ros2_ws/src/stealth_nav2/stealth_nav2
ros2_ws/src/stealth_core/stealth_core ros2_ws/src/stealth_env/stealth_env | tar -x -C /tmp/old``)
and pass ``--pythonpath /tmp/old/ros2_ws/src/stealth_nav2:/tmp/old/ros2_ws/src/stealth_core:``
``/tmp/old/ros2_ws/src/stealth_env``.

One line per run (outcome, recoveries, the robot's least clearance from a wall on the ground
truth, the largest localisation error, the peak visibility on the way), then the tally.
"""

import argparse
import math
import os
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from action_msgs.msg import GoalStatus  # noqa: E402
from geometry_msgs.msg import PoseWithCovarianceStamped  # noqa: E402
from nav2_msgs.action import NavigateToPose  # noqa: E402
import numpy as np  # noqa: E402
import rclpy  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402
from ros_support import NodeProcesses, reserved_domain_id, ros_environment  # noqa: E402
from stealth_core.kinematics import DiscFootprint  # noqa: E402
from stealth_core.scenario import find_scenario, load_scenario  # noqa: E402
from stealth_core.task import StealthTask  # noqa: E402
from stealth_node_kit.conversions import seconds  # noqa: E402
from test_env_node import start_sim, wait_for_log  # noqa: E402
from test_nav2_navigator import (  # noqa: E402
    Commander,
    start_navigator,
    start_planner,
    until_reached,
)
from test_nav2_planner import stamped  # noqa: E402

SIM = {'real_time_factor': 2.0, 'idle_period': 0.025, 'publish_rate': 10.0}


def wall_clearance(footprint: DiscFootprint, x: float, y: float) -> float:
    """How far the robot's disc at (x, y) is from the nearest blocked cell (m; < 0 inside)."""
    res = footprint.resolution
    cell = footprint.cell_of(x, y)
    if cell is None:
        return -math.inf
    row, col = cell
    reach = 12
    window = footprint.blocked[max(row - reach, 0) : row + reach + 1,
                               max(col - reach, 0) : col + reach + 1]  # fmt: skip
    rows, cols = np.nonzero(window)
    if rows.size == 0:
        return math.inf
    left = footprint.origin_x + (cols + max(col - reach, 0)) * res
    bottom = footprint.origin_y + (rows + max(row - reach, 0)) * res
    dx = np.maximum(np.maximum(left - x, x - (left + res)), 0.0)
    dy = np.maximum(np.maximum(bottom - y, y - (bottom + res)), 0.0)
    return float(np.sqrt(dx * dx + dy * dy).min()) - footprint.radius


def one_run(
    seed: int, navigator_params: dict, log_root: pathlib.Path, timeout: float, pythonpath: str
) -> dict:
    scenario = load_scenario(find_scenario('lgfloor'))
    task = StealthTask(scenario, 'hard')
    footprint = DiscFootprint(scenario.map, scenario.robot_radius)
    log_dir = log_root / f'seed{seed}'
    log_dir.mkdir(parents=True, exist_ok=True)
    with reserved_domain_id() as domain:
        for key, value in ros_environment(domain).items():
            if key.startswith('ROS_'):
                os.environ[key] = value
        os.environ.pop('ROS_LOCALHOST_ONLY', None)
        processes = NodeProcesses(domain, log_dir)
        if pythonpath:  # another copy of the packages (say, the code before a change)
            processes.env['PYTHONPATH'] = f'{pythonpath}:{processes.env["PYTHONPATH"]}'
        context = rclpy.Context()
        # Ctrl-C stops the runs (and their processes) rather than only this context.
        rclpy.init(context=context, domain_id=domain,
                   signal_handler_options=SignalHandlerOptions.NO)  # fmt: skip
        commander = None
        try:
            start_sim(processes, scenario, seed=seed, **SIM)
            start_planner(processes, str(find_scenario('lgfloor')))
            navigator = start_navigator(processes, **navigator_params)
            wait_for_log(navigator, 'navigator ready', timeout=60.0)
            commander = Commander(context)
            estimates = []
            commander.node.create_subscription(
                PoseWithCovarianceStamped, 'amcl_pose',
                lambda m: estimates.append((seconds(m.header.stamp), m.pose.pose.position.x,
                                            m.pose.pose.position.y)), 10)  # fmt: skip
            commander.wait_until_active()
            started = time.monotonic()
            goal = NavigateToPose.Goal(pose=stamped(task.goal.x, task.goal.y))
            handle = commander.send('to_pose', goal)
            answer = commander.result(handle, timeout=timeout)
            elapsed = time.monotonic() - started
            truths = list(commander.truths)
            way = until_reached(truths, task, scenario.goal_radius)
            peak = max((task.visibility(x, y, t, yaw) for t, x, y, yaw, _ in way), default=0.0)
            clearance = min((wall_clearance(footprint, x, y) for _, x, y, *_ in truths),
                            default=math.inf)  # fmt: skip
            stamps = np.array([t for t, *_ in truths])
            error = 0.0
            for t, ex, ey in estimates:
                k = int(np.clip(np.searchsorted(stamps, t), 0, len(stamps) - 1))
                error = max(error, math.dist((ex, ey), truths[k][1:3]))
            log = navigator.log_path.read_text()
            recoveries = max((m.number_of_recoveries for _, m in commander.feedback), default=0)
            succeeded = answer.status == GoalStatus.STATUS_SUCCEEDED
            return {
                'seed': seed,
                'succeeded': succeeded,
                'undetected': peak < scenario.detection_threshold,
                'message': answer.result.error_msg,
                'recoveries': recoveries,
                'back_offs': log.count('backing off'),
                'clearance': clearance,
                'error': error,
                'peak': peak,
                'wall': elapsed,
                'sim': truths[-1][0] - truths[0][0] if truths else 0.0,
            }
        finally:
            if commander is not None:
                commander.close()
            processes.stop_all()
            context.try_shutdown()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--runs', type=int, default=10)
    parser.add_argument('--first-seed', type=int, default=1)
    parser.add_argument('--timeout', type=float, default=600.0, help='wall s per goal')
    parser.add_argument('--set', nargs='*', default=[], metavar='NAME:=VALUE',
                        help="the navigator's parameters")  # fmt: skip
    parser.add_argument(
        '--pythonpath',
        default='',
        help="put first on the nodes' PYTHONPATH (another copy of the code)",
    )
    args = parser.parse_args()
    params = dict(item.split(':=', 1) for item in args.set)
    log_root = pathlib.Path(tempfile.mkdtemp(prefix='nav2_trials_'))
    print(f'logs in {log_root}; load {os.getloadavg()}', flush=True)
    reached = 0
    for seed in range(args.first_seed, args.first_seed + args.runs):
        run = one_run(seed, params, log_root, args.timeout, args.pythonpath)
        ok = run['succeeded'] and run['undetected']
        reached += ok
        print(f"seed {seed}: {'REACHED' if ok else 'FAILED'} undetected={run['undetected']} "
              f"recoveries={run['recoveries']} back_offs={run['back_offs']} "
              f"least_wall_clearance={run['clearance']:.3f} m "
              f"max_localisation_error={run['error']:.3f} m peak={run['peak']:.3f} "
              f"wall={run['wall']:.0f} s sim={run['sim']:.0f} s load={os.getloadavg()[0]:.1f} "
              f"{run['message']}", flush=True)  # fmt: skip
    print(f'{reached} of {args.runs} reached the goal undetected', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
