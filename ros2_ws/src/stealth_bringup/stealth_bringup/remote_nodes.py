"""Nodes of a run that run on another host (`--remote NODE`): the command that starts one there,
and what the orchestrator knows of it. Such a node has no process here, so all the orchestrator
sees of it is the ROS graph: it has joined once its name is there, and leaving the graph later
is its exit (RemoteNodes, which run_lifecycle asks with the graph's node names). No rclpy.

The command carries every parameter inline (`-p name:=value`), so nothing but the command has to
reach the other host; that host needs the same workspace (`source scripts/ros_env.sh`).
"""

from __future__ import annotations

import dataclasses
import shlex
import time
from typing import Any

from stealth_bringup.ros_domain import DISCOVERY_RANGES
from stealth_bringup.run_config import NODES, RunError, ros_arg_value

# Where multicast discovery does not reach the other host, both sides name each other.
STATIC_PEERS_HINT = (
    'no multicast between the hosts? add ROS_STATIC_PEERS=<the other host> on both sides '
    '(here: before `stealth train`)'
)


def join_command(node: str, values: dict[str, Any], domain_id: int, discovery: str) -> list[str]:
    """The command that starts `node` with parameters `values` on another host, in the run's
    domain and discovery range (ROS_LOCALHOST_ONLY, which would override the range, unset)."""
    spec = NODES[node]
    parameters = []
    for name, value in values.items():
        parameters += ['-p', f'{name}:={ros_arg_value(value)}']
    return [
        'env', '-u', 'ROS_LOCALHOST_ONLY', f'ROS_DOMAIN_ID={domain_id}',
        f'ROS_AUTOMATIC_DISCOVERY_RANGE={DISCOVERY_RANGES[discovery]}',
        'stealth', 'run', spec.package, spec.executable, '--ros-args', *parameters,
    ]  # fmt: skip


@dataclasses.dataclass
class RemoteNode:
    """A node on another host, as far as the graph tells: joined when, left when."""

    name: str
    command: list[str]
    since: float = dataclasses.field(default_factory=time.monotonic)  # its command was printed
    joined: float | None = None
    left: float | None = None

    @property
    def shell_command(self) -> str:
        return shlex.join(self.command)

    def seen(self, on_graph: bool, now: float | None = None) -> str:
        """Note whether it is on the graph now: 'joined' or 'left' when that changed, else ''."""
        now = time.monotonic() if now is None else now
        if on_graph and self.joined is None:
            self.joined = now
            return 'joined'
        if not on_graph and self.joined is not None and self.left is None:
            self.left = now
            return 'left'
        return ''

    @property
    def state(self) -> str:
        if self.joined is None:
            return 'never joined'
        return 'left' if self.left is not None else 'on the graph'

    def summary(self) -> dict:
        """For summary.json: the command, when it joined and whether it is still there."""
        return {
            'command': self.shell_command,
            'state': self.state,
            'joined_after_s': None if self.joined is None else round(self.joined - self.since, 2),
            'on_graph_s': None
            if self.joined is None
            else round((self.left or time.monotonic()) - self.joined, 2),
        }


class RemoteNodes(dict):
    """The run's remote nodes, {name: RemoteNode}, each once its command is printed: announced,
    followed on the graph, and reminded of when the run ends. `say` prints a line of the run,
    `prog` is the command's name (stealth train / rollout)."""

    def __init__(self, say, prog: str):
        super().__init__()
        self.say = say
        self.prog = prog

    def announce(
        self, name: str, values: dict[str, Any], domain_id: int, discovery: str, timeout: float
    ) -> None:
        """Print the exact command for the other host; from now on the node may join."""
        node = RemoteNode(name, join_command(name, values, domain_id, discovery))
        self[name] = node
        where = 'another host' if discovery == 'subnet' else 'another terminal of this host'
        self.say(
            f'waiting up to {timeout:g} s for {name} to join ROS domain '
            f'{domain_id} from {where}; run there (workspace sourced: '
            'source scripts/ros_env.sh):'
        )
        self.say(f'  {node.shell_command}')
        if discovery == 'subnet':
            self.say(f'  ({STATIC_PEERS_HINT})')
        else:
            self.say('  (--discovery localhost: only this host can join; --discovery subnet for '
                     'another host)')  # fmt: skip

    def check(self, on_graph, during: str) -> None:
        """Remote nodes are supervised through the graph (`on_graph`: its node names): there
        once, gone means ended (RunError)."""
        for name, node in self.items():
            change = node.seen(name in on_graph)
            if change == 'joined':
                self.say(f'{name} (remote) joined the run after {node.joined - node.since:.1f} s')
            elif change == 'left':
                raise RunError(
                    f'{name} (remote) left the ROS graph {during} after '
                    f'{node.left - node.joined:.1f} s on it: it stopped, crashed or lost the '
                    'network; see its output on its host'
                )

    def not_joined(self) -> str:
        """The remote nodes not on the graph yet ('' once all joined)."""
        return ', '.join(name for name, node in self.items() if node.joined is None)

    def join_timeout(self, missing: str, domain_id: int, timeout: float) -> str:
        """What to say when `missing` (not_joined's answer) did not join within `timeout` s."""
        node = self[missing.split(', ')[0]]
        return (
            f'{node.name} did not join ROS domain {domain_id} within '
            f'{timeout:g} s; start it on its host with: {node.shell_command}'
        )

    def remind(self, mode: str, policy_path) -> None:
        """The orchestrator cannot stop a remote node: say so, and where its policy goes."""
        for name, node in self.items():
            if node.state != 'on the graph':
                continue
            saving = ''
            if name == 'agent' and mode == 'train':
                saving = f'; it saves the policy to {policy_path} (on its host) on exit'
            self.say(f'{self.prog}: {name} runs on another host: stop it there (Ctrl-C){saving}')
