"""Benchmark: RL moves per second of the simulator core, fast path against the reference, and
through the simulator node's sim/execute_move service.

The same seeded random walk (grid moves of 0.5 m on a project map, chosen from the returned
estimate) runs at the settings training uses (stealth_bringup's simulator.yaml: 200 particles,
0.04 s physics steps, 180 laser beams of which the filter weighs 60): in-process on a
``Simulator`` with its compiled fast path and with ``reference=True`` (the Python
implementation it is proven equal to), alternately in the same process so that other load on
the machine hits both alike, after one untimed move that pays numba's first call (a compile,
or a load from its cache; reported); then through the service of
a ``sim_node`` process at real_time_factor 0, called from this process. All runs see identical
moves and poses. Needs the workspace built (``make setup``).
Run: ``source scripts/ros_env.sh && python bench/bench_sim.py``.
"""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path
import sys
import tempfile
import time

import numpy as np

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT / 'tests'))
sys.path.insert(0, str(REPO_ROOT / 'ros2_ws' / 'src' / 'stealth_sim'))

from ros_support import NodeProcesses, reserved_domain_id  # noqa: E402
from stealth_core.kinematics import DiscFootprint, Pose  # noqa: E402
from stealth_core.moves import GRID_HEADINGS, MoveKind, MoveRequest  # noqa: E402
from stealth_core.occupancy_map import load_map  # noqa: E402
from stealth_sim.localisation import FilterConfig  # noqa: E402
from stealth_sim.move_executor import execute_move  # noqa: E402
from stealth_sim.simulator import SimConfig, Simulator  # noqa: E402

MAP = REPO_ROOT / 'maps' / 'simple-maze.yaml'
START = Pose(1.5, 1.5, math.pi / 2)  # the simple-maze scenario's start
MOVES = 150
ROUNDS = 3  # alternate fast and reference runs; the best of each counts
STEP = 0.5
SEED = 7
TRAINING_PARAMETERS = REPO_ROOT / 'ros2_ws/src/stealth_bringup/config/simulator.yaml'
SIM_NODE = REPO_ROOT / 'ros2_ws' / 'install' / 'stealth_sim' / 'lib' / 'stealth_sim' / 'sim_node'


class MoveChooser:
    """A seeded random grid move that keeps the robot's disc (plus a margin) clear of walls."""

    def __init__(self, occupancy_map, radius: float, seed: int):
        self.footprint = DiscFootprint(occupancy_map, radius + 0.1)
        self.rng = np.random.default_rng(seed)

    def choose(self, x: float, y: float) -> int:
        possible = [
            kind
            for kind, heading in GRID_HEADINGS.items()
            if self.footprint.sweep_is_free(
                x, y, x + STEP * math.cos(heading), y + STEP * math.sin(heading)
            )
        ]
        return int(self.rng.choice(possible or list(GRID_HEADINGS)))


def training_settings() -> dict:
    """The particles and physics step of stealth_bringup's simulator.yaml (what runs use)."""
    import yaml

    values = yaml.safe_load(TRAINING_PARAMETERS.read_text())['simulator']['ros__parameters']
    return {name: values[name] for name in ('particles', 'physics_dt')}


def training_config(settings: dict) -> SimConfig:
    return SimConfig(
        physics_dt=settings['physics_dt'],
        filter=FilterConfig(particles=settings['particles']),
        seed=SEED,
    )


def first_call(occupancy_map, config: SimConfig) -> float:
    """Seconds for the first compiled move of this process: numba compiles the kernels (or
    loads them from its cache) here, so the timed runs do not pay for it."""
    sim = Simulator(occupancy_map, config, START)
    started = time.perf_counter()
    execute_move(sim, MoveRequest(MoveKind.UP, STEP))
    return time.perf_counter() - started


def in_process(occupancy_map, config: SimConfig, reference: bool) -> tuple[float, float, list]:
    """Moves per second and simulated seconds per move, calling the core directly.

    Only ``execute_move`` is timed: the walk's chooser (a few Python sweep checks and a random
    choice, ~0.3 ms a move) is the benchmark's driver, not the simulator.
    """
    sim = Simulator(occupancy_map, config, START, reference=reference)
    _ = sim.caster._free_samples  # a table built on the first cast: part of the setup
    chooser = MoveChooser(occupancy_map, sim.config.robot_radius, SEED)
    trajectory = []
    elapsed = 0.0
    for _ in range(MOVES):
        estimate = sim.estimate
        move = MoveRequest(chooser.choose(estimate.x, estimate.y), STEP)
        started = time.perf_counter()
        execute_move(sim, move)
        elapsed += time.perf_counter() - started
        trajectory.append((*sim.ground_truth, *sim.estimate))
    return MOVES / elapsed, sim.time / MOVES, trajectory


@contextlib.contextmanager
def ros_client(domain_id: int):
    """An rclpy context and node on the benchmark's private domain."""
    import rclpy

    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_LOCALHOST_ONLY', None)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('bench_sim_client', context=context)
    try:
        yield node
    finally:
        node.destroy_node()
        context.try_shutdown()


def through_service(occupancy_map, settings: dict) -> tuple[float, list]:
    """Moves per second through sim/execute_move of a sim_node process."""
    from rclpy.executors import SingleThreadedExecutor
    from stealth_interfaces.srv import ExecuteMove

    with reserved_domain_id() as domain_id, tempfile.TemporaryDirectory() as logs:
        processes = NodeProcesses(domain_id, Path(logs))
        try:
            processes.start(
                [
                    str(SIM_NODE),
                    '--ros-args',
                    '-p',
                    f'map:={MAP}',
                    '-p',
                    f'initial_pose:=[{START.x}, {START.y}, {START.yaw}]',
                    '-p',
                    f'seed:={SEED}',
                    '-p',
                    f'particles:={settings["particles"]}',
                    '-p',
                    f'physics_dt:={settings["physics_dt"]}',
                    '-p',
                    'real_time_factor:=0.0',
                ],
                'sim_node',
            )
            with ros_client(domain_id) as node:
                client = node.create_client(ExecuteMove, 'sim/execute_move')
                if not client.wait_for_service(timeout_sec=30.0):
                    raise RuntimeError('sim/execute_move did not come up within 30 s')
                executor = SingleThreadedExecutor(context=node.context)
                executor.add_node(node)
                chooser = MoveChooser(occupancy_map, SimConfig().robot_radius, SEED)
                estimate = START
                truths = []
                started = time.perf_counter()
                for _ in range(MOVES):
                    request = ExecuteMove.Request(
                        kind=chooser.choose(estimate.x, estimate.y), distance=STEP
                    )
                    future = client.call_async(request)
                    executor.spin_until_future_complete(future, timeout_sec=60.0)
                    response = future.result()
                    position = response.estimate.pose.position
                    estimate = Pose(position.x, position.y, 0.0)
                    truths.append((response.true_pose.position.x, response.true_pose.position.y))
                elapsed = time.perf_counter() - started
                executor.shutdown()
        finally:
            processes.stop_all()
    return MOVES / elapsed, truths


def run(report=print) -> dict:
    occupancy_map = load_map(MAP)
    settings = training_settings()
    config = training_config(settings)
    first_call_seconds = first_call(occupancy_map, config)
    rates = {False: 0.0, True: 0.0}
    trajectories = {}
    for _ in range(ROUNDS):
        for reference in (False, True):
            rate, sim_seconds, trajectories[reference] = in_process(
                occupancy_map, config, reference
            )
            rates[reference] = max(rates[reference], rate)
    fast_rate, reference_rate = rates[False], rates[True]
    fast_equal = np.allclose(trajectories[False], trajectories[True], rtol=0.0, atol=1e-9)
    service_rate, service_truths = through_service(occupancy_map, settings)
    fast_truths = [entry[:2] for entry in trajectories[False]]
    same = np.allclose(fast_truths, service_truths, atol=1e-9)
    report(
        f'simulator moves, {MOVES} grid moves of {STEP} m on {MAP.stem} (seed {SEED}), '
        f'{settings["particles"]} particles, {settings["physics_dt"]} s physics steps, '
        f'{config.laser.beams} laser beams:'
    )
    report(
        f'  in-process Simulator, fast path: {fast_rate:.1f} moves/s '
        f'({sim_seconds:.2f} simulated s per move, {fast_rate * sim_seconds:.0f}x real time)'
    )
    report(f'  in-process Simulator, reference path: {reference_rate:.1f} moves/s')
    report(
        f'  first compiled move of the process (numba compile or cache load, untimed): '
        f'{first_call_seconds:.2f} s'
    )
    report(
        f'  fast / reference: {fast_rate / reference_rate:.1f}x (best of {ROUNDS} alternating '
        f'runs each); same trajectory and estimate within 1e-9: {fast_equal}'
    )
    report(f'  through sim/execute_move from another process: {service_rate:.1f} moves/s')
    report(f'  service / in-process fast path: {service_rate / fast_rate:.2f}')
    report(f'  identical trajectories in-process and through the service: {same}')
    return {
        'sim_moves_per_second_service': round(service_rate, 1),
        'sim_moves_per_second_in_process': round(fast_rate, 1),
        'sim_moves_per_second_in_process_reference': round(reference_rate, 1),
        'sim_fast_to_reference_ratio': round(fast_rate / reference_rate, 2),
        'sim_fast_equals_reference': bool(fast_equal),
        'sim_first_compiled_move_seconds': round(first_call_seconds, 2),
        'sim_service_to_in_process_ratio': round(service_rate / fast_rate, 3),
        'sim_simulated_seconds_per_move': round(sim_seconds, 3),
        'sim_trajectories_identical': bool(same),
    }


def main() -> dict:
    return run()


if __name__ == '__main__':
    main()
