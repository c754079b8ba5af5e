"""`stealth train` and `stealth rollout`: the whole system as separate OS processes, without
launch.

    stealth train [--scenario NAME|PATH] [--goal G] [--episodes N] [--eval-every M]
                  [--success-streak K] [--seed S] [--set node.param=value ...] [--watch]
    stealth rollout --run runs/<name> | --policy FILE | --learner generalist --scenario S

(`stealth eval`, rollout's old name, says so on stderr and runs it.)

A run starts the recorder, the simulator, the environment and the agent from the install space
(found through the ament index, as `ros2 run` finds them), each in its own process group with
its output in runs/<name>/logs/<node>.log, in a private ROS_DOMAIN_ID over localhost only, each
with `--ros-args --params-file runs/<name>/params/<node>.yaml` (the effective parameters: the
node's default file or --params-dir's, what the scenario and the run decide, --set). It waits
until every node is on the graph (and the simulator's services are there), then follows the
episodes as a small rclpy node of its own (rl_env/episode_summary, rl_agent/episode_info,
rl_env/step_info) with a progress bar, until the episode budget is spent or the greedy policy
has reached the goal in K evaluations in a row. It then stops the nodes in order (agent,
environment, simulator, and the recorder last, so the MCAP is finished), SIGKILL only after a
timeout, and writes the run's outputs.

Ctrl-C or SIGTERM: the same orderly stop, exit 130 or 143 (a second Ctrl-C kills at once). A
node that dies: everything else stopped, one line naming the node, how it ended and its last
log line, exit 1. Bad input (scenario, goal, parameter file, --set, a missing executable) is
one line and exit 1 before anything starts. A full disk (a file of the run, or a node's policy
or recording, that does not fit): one line naming the file and the space left, the run stopped
as above with what fits written (summary.json lists the complete and incomplete files, the
last policy saved whole is kept), exit 4; the node that hit it is not restarted.

Here: the two commands; their command lines are run_arguments', what they are asked to do is
checked and laid out by run_plan. The run itself: run_lifecycle (the processes, from start to
stop), run_monitor (signals, the orchestrator's rclpy node, the progress bar) and run_report
(the outputs and the closing lines, through run_outputs).
"""

from __future__ import annotations

from collections.abc import Sequence
import sys
import time

from stealth_bringup.run_arguments import (
    check_rollout_source,
    prog_of,
    rollout_parser,
    train_parser,
)
from stealth_bringup.run_config import RunConfigError
from stealth_bringup.run_lifecycle import Run
from stealth_bringup.run_plan import make_plan


def _main(mode: str, argv: Sequence[str] | None) -> int:
    started = time.monotonic()
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = train_parser() if mode == 'train' else rollout_parser()
    args = parser.parse_args(argv)
    if mode != 'train':
        check_rollout_source(parser, args)
    prog = prog_of(mode)
    try:
        plan = make_plan(args, mode, argv)
    except RunConfigError as error:
        print(f'{prog}: {error}', file=sys.stderr)
        return 1
    try:
        return Run(plan, started).execute()
    except KeyboardInterrupt:  # outside the run's own signal handling (e.g. while plotting)
        print(f'{prog}: interrupted', file=sys.stderr)
        return 130


def train_main(argv: Sequence[str] | None = None) -> int:
    """`stealth train`: see the module docstring and --help."""
    return _main('train', argv)


def rollout_main(argv: Sequence[str] | None = None) -> int:
    """`stealth rollout`: see the module docstring and --help."""
    return _main('eval', argv)


def eval_main(argv: Sequence[str] | None = None) -> int:
    """`stealth eval`, the old name of `stealth rollout`: one line saying so, then rollout."""
    print('stealth eval is now stealth rollout', file=sys.stderr)
    return rollout_main(argv)


if __name__ == '__main__':
    sys.exit(train_main())
