"""Benchmark: what watching a run in Foxglove costs: the bridge's CPU per RL step and its
message rate, and the loop's steps per second with and without it.

The RL loop of bench_ros_loop (sim_node at its cheapest settings, env_node, a random agent
answering at once), with the simulator's topics at WATCH_RATE Hz of simulated time as under
`stealth train --watch`, in three modes, one after the other in private ROS domains, each
REPEATS times interleaved (the fastest counts, with its CPU figures): without a bridge; with
the bridge node and no client (it then subscribes to nothing but /clock); with the bridge and
a Foxglove WebSocket client (tools/foxglove-ws-check, decoding every message) subscribed to
every topic of the run. CPU times (utime + stime from /proc) of every process are read when
the agent starts and when it has done its steps; the client counts what it received. A
publisher that builds its messages only for subscribers (sim_node's periodic topics, the
environment's StepInfo) works for the viewer too: that is part of the cost. Needs the
workspace built and `npm ci --prefix tools/foxglove-ws-check`.
Run: ``source scripts/ros_env.sh && python bench/bench_bridge.py``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import shutil
import signal
import socket
import subprocess
import time

from bench_ros_loop import (
    AGENT,
    ENV_NODE,
    FAST_SIM,
    REPO_ROOT,
    SCENARIO,
    SIM_NODE,
    WARMUP,
    _result,
    _ros_args,
    _Run,
)

STEPS = 800
REPEATS = 2  # each mode, interleaved; the best counts (other load on the machine only slows)
MODES = ('none', 'idle', 'watched')
WATCH_RATE = 10.0  # Hz of simulated time: the simulator's topics under --watch
BRIDGE = REPO_ROOT / 'ros2_ws' / 'install' / 'stealth_tools' / 'lib' / 'stealth_tools' / 'bridge'
CLIENT = REPO_ROOT / 'tools' / 'foxglove-ws-check'
TOPICS = (
    '/rl_env/step_info', '/rl_env/rl_state_reward', '/rl_env/episode_summary',
    '/rl_agent/rl_action', '/rl_agent/rl_experiment_info', '/amcl_pose', '/odom',
    '/ground_truth', '/scan', '/tf', '/clock', '/map', '/searchlight_markers',
    '/visibility_grid', '/rosout',
)  # fmt: skip
TICK = os.sysconf('SC_CLK_TCK')


def _cpu_seconds(pid: int) -> float:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK  # utime, stime


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def _wait_for(process, text: str, what: str, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while text not in process.log_path.read_text():
        if process.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(
                f'{what}: {text!r} never came; log:\n{process.log_path.read_text()}'
            )
        time.sleep(0.1)


def loop(bridge_mode: str) -> dict:
    """Steps/s of the loop and each process's CPU per step; bridge_mode 'none', 'idle' (no
    client) or 'watched' (a client on TOPICS: its message counts too)."""
    from stealth_core.scenario import load_scenario

    with_bridge, watched = bridge_mode != 'none', bridge_mode == 'watched'
    scenario = load_scenario(SCENARIO)
    x, y, yaw = scenario.start
    sim = {
        'map': scenario.map_path,
        'initial_pose': f'[{x}, {y}, {yaw}]',
        'publish_rate': WATCH_RATE,
        **FAST_SIM,
    }
    figures = {}
    with _Run() as processes:
        processes.start([str(SIM_NODE), *_ros_args(sim)], 'sim_node')
        env = {'scenario': SCENARIO, 'marker_period': 0.0, 'log_every': 0}
        processes.start([str(ENV_NODE), *_ros_args(env)], 'env_node')
        if with_bridge:
            port = _free_port()
            bridge = processes.start([str(BRIDGE), *_ros_args({'port': port})], 'bridge')
            _wait_for(bridge, "Advertising '/visibility_grid'", 'bridge')
        if watched:
            node = shutil.which('node') or 'node'
            wanted = ','.join(f'{t}=1000000000' for t in TOPICS)
            client = processes.start(
                [node, str(CLIENT / 'client.mjs'), f'ws://localhost:{port}', '--topics', wanted,
                 '--timeout', '3600'],
                'client', stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            )  # fmt: skip
            time.sleep(2.0)  # connected and subscribed
        nodes = {p.log_path.stem: p.pid for p in processes.processes}
        cpu_start = {name: _cpu_seconds(pid) for name, pid in nodes.items()}
        started = time.perf_counter()
        agent = processes.start_python(AGENT, 'agent', str(WARMUP), str(STEPS), '7')
        steps, seconds, _ = _result(agent, f'RL loop, bridge {bridge_mode}')
        figures['steps_per_second'] = steps / seconds
        all_steps = WARMUP + steps  # the agent's steps while the window was open
        figures['cpu_ms_per_step'] = {
            name: (_cpu_seconds(pid) - cpu_start[name]) / all_steps * 1e3
            for name, pid in nodes.items()
        }
        if watched:
            window = time.perf_counter() - started
            cpu = figures['cpu_ms_per_step']['bridge'] * all_steps / 1e3
            client.send_signal(signal.SIGTERM)
            output, errors = client.communicate(timeout=60)
            report = json.loads(output)
            received = sum(t['count'] for t in report['topics'].values())
            decode_errors = sum(t['decode_errors'] for t in report['topics'].values())
            figures.update(
                cpu_share=cpu / window,
                messages_per_second=received / window,
                messages_per_step=received / all_steps,
                decode_errors=decode_errors,
            )
    return figures


def _rounded(values: dict) -> dict:
    return {name: round(value, 3) for name, value in values.items()}


def run(report=print) -> dict:
    for path in (SIM_NODE, ENV_NODE, BRIDGE):
        if not path.exists():
            raise RuntimeError(f'{path} is missing: build the workspace first (make setup)')
    if not (CLIENT / 'node_modules' / 'ws').is_dir():
        raise RuntimeError(f'{CLIENT}/node_modules is missing: npm ci --prefix {CLIENT}')
    runs = {mode: [] for mode in MODES}
    for _ in range(REPEATS):
        for mode in MODES:
            runs[mode].append(loop(mode))
    bare, idle, watched = (max(runs[m], key=lambda r: r['steps_per_second']) for m in MODES)
    ratio = watched['steps_per_second'] / bare['steps_per_second']
    idle_ratio = idle['steps_per_second'] / bare['steps_per_second']
    report(
        f'Foxglove bridge, {SCENARIO} RL loop (sim_node cheapest, topics at {WATCH_RATE:g} Hz '
        f'simulated), {STEPS} steps, same run, each the fastest of {REPEATS}:'
    )
    report(f'  without the bridge: {bare["steps_per_second"]:.0f} steps/s')
    report(
        f'  with the bridge, no client: {idle["steps_per_second"]:.0f} steps/s, '
        f'{idle_ratio:.2f} of without; the bridge {idle["cpu_ms_per_step"]["bridge"]:.2f} ms '
        'CPU per step'
    )
    report(
        f'  with the bridge and a Foxglove client on {len(TOPICS)} topics: '
        f'{watched["steps_per_second"]:.0f} steps/s, {ratio:.2f} of without'
    )
    report(
        f'  the bridge: {watched["cpu_ms_per_step"]["bridge"]:.2f} ms CPU per step '
        f'({watched["cpu_share"]:.0%} of a core), {watched["messages_per_second"]:.0f} msg/s '
        f'to the client ({watched["messages_per_step"]:.1f} per step), '
        f'{watched["decode_errors"]} decode errors'
    )
    for name in ('sim_node', 'env_node', 'client'):
        before = bare['cpu_ms_per_step'].get(name)
        report(
            f'  {name}: {watched["cpu_ms_per_step"][name]:.2f} ms CPU per step with the bridge'
            + (f', {before:.2f} without' if before is not None else ' (decodes every message)')
        )
    return {
        'bridge_loop_steps_per_second_without': round(bare['steps_per_second'], 1),
        'bridge_loop_steps_per_second_with': round(watched['steps_per_second'], 1),
        'bridge_loop_ratio_with_to_without': round(ratio, 3),
        'bridge_loop_steps_per_second_idle': round(idle['steps_per_second'], 1),
        'bridge_loop_ratio_idle_to_without': round(idle_ratio, 3),
        'bridge_idle_cpu_ms_per_step': round(idle['cpu_ms_per_step']['bridge'], 3),
        'bridge_cpu_ms_per_step': round(watched['cpu_ms_per_step']['bridge'], 3),
        'bridge_node_cpu_ms_per_step_with': _rounded(watched['cpu_ms_per_step']),
        'bridge_node_cpu_ms_per_step_without': _rounded(bare['cpu_ms_per_step']),
        'bridge_cpu_share_of_a_core': round(watched['cpu_share'], 3),
        'bridge_messages_per_second': round(watched['messages_per_second'], 1),
        'bridge_messages_per_step': round(watched['messages_per_step'], 2),
        'bridge_client_decode_errors': watched['decode_errors'],
    }


if __name__ == '__main__':
    run()
