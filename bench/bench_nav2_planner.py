"""Benchmark: planning time per request of the covert planner server's core
(``stealth_nav2.covert_planning``), against the harness's way to the same optimum.

Per scenario: the scene's lattice model is built once (the server does it at start-up:
reported apart, as 'scene'); then each goal is asked for from the scenario's start: the first
request for a goal is *cold* (value iteration for that goal, then following it), every later
one *warm* (the goal's policy cached: following it only), at several times of the lights'
cycle where they move. The goals: the scenario's three and up to five other lattice nodes
(seeded), whatever the answer (a NO_VALID_PATH costs the same planning). The baseline, in the
same process: ``stealth_core.planners.optimal_path`` (the lattice model and value iteration from
scratch for one goal, as the harness and the environment's planned path compute it).
Targets (issue 28): <= 100 ms a request on static lgfloor, <= 1 s where lights move.

Then what a Nav2 client sees: ComputePathToPose round trips (send the goal, get the result,
as nav2_simple_commander's getPath) to a planner_server node in this process on a private
ROS domain, lgfloor's hard goal (warm), against the core's own time for the same request.
Run: source scripts/ros_env.sh && python bench/bench_nav2_planner.py
"""

from __future__ import annotations

import os
import statistics
import time

import numpy as np
from stealth_core.planners import optimal_path
from stealth_nav2.covert_planning import CovertPlanner, Pose
from stealth_nav2.plan_errors import PlanError
from stealth_nav2.scene_source import scene_from_scenario

SCENES = (('lgfloor', 0.1), ('lgfloor-moving', 1.0), ('simple-maze-moving', 1.0))
EXTRA_GOALS = 5
WARM_REPEATS = 5
ACTION_TRIPS = 50
TIMES = (0.0, 5.5, 13.0)  # s of the lights' clock: other start bins where lights move


def _goals(scene, planner) -> list[Pose]:
    goals = [Pose(goal.x, goal.y) for goal in scene.scenario.goals.values()]
    points = planner.model.points[: len(planner.model.nodes)]
    rng = np.random.default_rng(0)
    for i in rng.choice(len(points), min(EXTRA_GOALS, len(points)), replace=False):
        goals.append(Pose(*map(float, points[i])))
    return goals


def _request(planner, scene, start, goal, t) -> tuple[float, bool]:
    started = time.perf_counter()
    try:
        planner.plan(scene, start, goal, t=t)
        found = True
    except PlanError:
        found = False
    return time.perf_counter() - started, found


def bench_scene(name: str, target: float, report) -> dict:
    scene = scene_from_scenario(name)
    planner = CovertPlanner()
    started = time.perf_counter()
    planner.prepare(scene)
    scene_seconds = time.perf_counter() - started
    start = Pose(*scene.scenario.start)
    goals = _goals(scene, planner)
    times = TIMES if scene.has_moving_lights else (0.0,)
    cold, warm, found = [], [], 0
    for goal in goals:
        seconds, ok = _request(planner, scene, start, goal, 0.0)
        cold.append(seconds)
        found += ok
        for _ in range(WARM_REPEATS):
            for t in times:
                warm.append(_request(planner, scene, start, goal, t)[0])
    baseline = min(_timed(lambda: optimal_path(scene.scenario, 'hard')) for _ in range(2))
    cold_median, warm_median = statistics.median(cold), statistics.median(warm)
    report(
        f'{name} ({len(planner.model.nodes)} nodes, {planner.model.size} '
        f'places; {len(goals)} goals, {found} with a covert path):'
    )
    report(f'  scene (lattice model, once at start-up): {scene_seconds * 1e3:.0f} ms')
    report(
        f'  cold request (a new goal): median {cold_median * 1e3:.1f} ms, max '
        f'{max(cold) * 1e3:.1f} ms'
    )
    report(
        f'  warm request (a cached goal, {len(warm)} requests): median '
        f'{warm_median * 1e3:.2f} ms, max {max(warm) * 1e3:.2f} ms'
    )
    report(
        f'  baseline optimal_path (model + value iteration): {baseline * 1e3:.0f} ms; '
        f'speed-up cold {baseline / cold_median:.1f}x, warm {baseline / warm_median:.0f}x '
        f'(target <= {target * 1e3:.0f} ms a request: cold '
        f'{"met" if max(cold) <= target else "MISSED"}, warm '
        f'{"met" if max(warm) <= target else "MISSED"})'
    )
    key = name.replace('-', '_')
    return {
        f'{key}_scene_ms': round(scene_seconds * 1e3, 1),
        f'{key}_cold_median_ms': round(cold_median * 1e3, 2),
        f'{key}_cold_max_ms': round(max(cold) * 1e3, 2),
        f'{key}_warm_median_ms': round(warm_median * 1e3, 3),
        f'{key}_warm_max_ms': round(max(warm) * 1e3, 3),
        f'{key}_baseline_ms': round(baseline * 1e3, 1),
        f'{key}_cold_speedup': round(baseline / cold_median, 2),
        f'{key}_warm_speedup': round(baseline / warm_median, 1),
        f'{key}_target_met': bool(max(cold) <= target and max(warm) <= target),
    }


def _timed(call) -> float:
    started = time.perf_counter()
    call()
    return time.perf_counter() - started


def bench_action(report) -> dict:
    """Round trips of ComputePathToPose to a planner_server in this process (see the module)."""
    from nav2_msgs.action import ComputePathToPose
    import rclpy
    from rclpy.action import ActionClient
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from stealth_bringup.ros_domain import reserved_domain_id
    from stealth_nav2.planner_node import PlannerServer

    scene = scene_from_scenario('lgfloor')
    goal_point = scene.scenario.goals['hard']
    request = ComputePathToPose.Goal(use_start=True)
    request.start.header.frame_id = request.goal.header.frame_id = 'map'
    request.start.pose.position.x, request.start.pose.position.y = scene.scenario.start[:2]
    request.goal.pose.position.x, request.goal.pose.position.y = goal_point.x, goal_point.y
    with reserved_domain_id() as domain:
        context = rclpy.Context()
        rclpy.init(context=context, domain_id=domain)
        try:
            server = PlannerServer(
                context=context, parameter_overrides=[Parameter('scenario', value='lgfloor')]
            )
            client_node = rclpy.create_node('bench_planner_client', context=context)
            executor = SingleThreadedExecutor(context=context)
            for node in (server, client_node):
                executor.add_node(node)
            client = ActionClient(client_node, ComputePathToPose, 'compute_path_to_pose')

            def spin_until(future):
                while not future.done():
                    executor.spin_once(timeout_sec=1.0)
                return future.result()

            def round_trip() -> float:
                started = time.perf_counter()
                handle = spin_until(client.send_goal_async(request))
                spin_until(handle.get_result_async())
                return time.perf_counter() - started

            while not client.server_is_ready():
                executor.spin_once(timeout_sec=0.1)
            round_trip()  # the goal's values, cached
            trips = [round_trip() for _ in range(ACTION_TRIPS)]
            core = [
                _request(server.planner, scene, Pose(*scene.scenario.start), Pose(
                    goal_point.x, goal_point.y), 0.0)[0]
                for _ in range(ACTION_TRIPS)
            ]  # fmt: skip
            client.destroy()
            executor.shutdown()
            client_node.destroy_node()
            server.destroy_node()
        finally:
            context.try_shutdown()
    trip, own = statistics.median(trips), statistics.median(core)
    report(
        f'lgfloor hard goal over the action (warm, {ACTION_TRIPS} round trips): median '
        f'{trip * 1e3:.1f} ms, max {max(trips) * 1e3:.1f} ms; the core alone {own * 1e3:.2f} ms '
        f'(the action costs {trip / own:.0f}x the planning)'
    )
    return {
        'action_round_trip_median_ms': round(trip * 1e3, 2),
        'action_round_trip_max_ms': round(max(trips) * 1e3, 2),
        'action_over_core_ratio': round(trip / own, 1),
    }


def run(report=print) -> dict:
    load = os.getloadavg()
    report(f'load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (a shared machine)')
    figures = {'load_average_1min': round(load[0], 2)}
    for name, target in SCENES:
        figures.update(bench_scene(name, target, report))
    try:
        figures.update(bench_action(report))
    except ImportError as error:  # no ROS environment: the core's figures stand alone
        report(f'action round trips skipped: needs {error.name}, which is not importable')
    return figures


def main() -> None:
    run()


if __name__ == '__main__':
    main()
