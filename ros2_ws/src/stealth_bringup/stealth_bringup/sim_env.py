"""The simulator and the environment composed in one process (`ros2 run stealth_bringup sim_env`).

The same two nodes as `sim_node` and `env_node`, with the same names, topics, services and
parameters, spun by one single-threaded executor. What changes is the environment's lockstep
call to the simulator: `sim/execute_move` and the reset service, when the simulator of this
process serves them under the names the environment calls (remappings included), are called
directly instead of over the middleware (:mod:`stealth_node_kit.in_process`), which roughly
doubles the RL loop's steps per second (`bench/bench_ros_loop.py`). Everyone else still reaches
both services and every topic over ROS, so a recording, `stealth topic` or Foxglove sees the
same system.

Parameters as for any process with several nodes: a params file's section names the node
(`simulator:` and `environment:`, as the files `stealth train` writes), while `-p name:=value` goes
to every node that declares `name` (both declare `seed` and the speed limits). It suits
training: a simulator paced to real time (`real_time_factor` > 0, `stealth train --watch`)
would hold the environment's timers (the searchlights' scene) for each move's duration.

Usage: ``ros2 run stealth_bringup sim_env --ros-args --params-file simulator.yaml
--params-file environment.yaml``.
"""

from __future__ import annotations

import sys

from stealth_env.env_node import NODE_NAME as ENV_NODE_NAME
from stealth_env.env_node import EnvironmentNode
from stealth_node_kit.in_process import InProcessServices
from stealth_node_kit.running import run_nodes
from stealth_sim.sim_node import SimulatorNode, keep_freed_memory_for_reuse

USAGE = __doc__.split('\n\n')[0] + '\n\n' + __doc__.split('\n\n')[-1]


def build_nodes() -> list:
    """The simulator, then the environment calling it directly; nothing left if either fails."""
    services = InProcessServices()
    simulator = SimulatorNode(services=services)
    try:
        environment = EnvironmentNode(services=services)
    except BaseException:
        simulator.destroy_node()
        raise
    return [simulator, environment]


def _wants_help(argv: list[str]) -> bool:
    ours = argv[1 : argv.index('--ros-args')] if '--ros-args' in argv else argv[1:]
    return any(arg in ('-h', '--help') for arg in ours)


def main(args=None) -> int:
    if _wants_help(sys.argv if args is None else args):
        print(USAGE)
        return 0
    keep_freed_memory_for_reuse()
    environments = []

    def make_nodes() -> list:
        nodes = build_nodes()
        environments.append(nodes[1])
        return nodes

    def on_exit(nodes) -> None:
        EnvironmentNode.log_totals(nodes[1])

    code = run_nodes(make_nodes, ENV_NODE_NAME, args=args, on_exit=on_exit)
    return code or (environments[0].exit_code if environments else 0)


if __name__ == '__main__':
    raise SystemExit(main())
