"""What a run is made of, before anything starts: the nodes, their parameter files, the scenario
and goal and the parameters derived from them, the run-specific parameters, `--set` overrides,
the run directory; and the errors of a run, before it starts (RunConfigError) and after
(RunError). No rclpy.

Parameter files are ROS 2 params files, one per node::

    agent:
      ros__parameters:
        epsilon: 0.1

The defaults live in share/stealth_bringup/config/<node>.yaml; `--params-dir DIR` takes
<node>.yaml from DIR instead where it exists. A run writes the *effective* file of every node
(the file's parameters, then what the orchestrator fills in from the scenario and the run, then
`--set node.param=value`) to runs/<name>/params/<node>.yaml and starts the node with
`--ros-args --params-file` that file (and the `--set` values again as `-p`, so a process list
shows them). Every problem is a RunConfigError whose message is one line naming the file, node
or parameter and what was expected.
"""

from __future__ import annotations

import dataclasses
import datetime
import difflib
import hashlib
import json
import math
import os
from pathlib import Path
import re
from typing import Any

import yaml

# Start order; shutdown goes the other way round except that the recorder stops last. The
# bridge (to Foxglove) runs only with --watch.
NODE_ORDER = ('recorder', 'bridge', 'simulator', 'environment', 'agent')
STOP_ORDER = ('agent', 'environment', 'simulator', 'bridge', 'recorder')


@dataclasses.dataclass(frozen=True)
class NodeSpec:
    """A node of the system: its name on the graph and where its executable is."""

    name: str  # node name, also the params file's stem and the log file's
    package: str
    executable: str
    role: str  # one line for messages and the README


NODES = {
    'recorder': NodeSpec('recorder', 'stealth_tools', 'recorder', 'MCAP recorder of every topic'),
    'bridge': NodeSpec(
        'bridge', 'stealth_tools', 'bridge', 'Foxglove WebSocket bridge of every topic (--watch)'
    ),
    'simulator': NodeSpec(
        'simulator', 'stealth_sim', 'sim_node', 'robot, odometry, laser, localisation'
    ),
    'environment': NodeSpec(
        'environment', 'stealth_env', 'env_node', 'scenario, searchlights, rewards, episodes'
    ),
    'agent': NodeSpec('agent', 'stealth_agent', 'agent_node', 'tabular learner (rl_msgs)'),
}

# Parameters the orchestrator sets itself, and the option that sets them instead of --set.
MANAGED = {
    'simulator.map': '--scenario',
    'simulator.initial_pose': '--scenario',
    'simulator.robot_radius': '--scenario',
    'environment.scenario': '--scenario',
    'environment.goal': '--goal',
    'agent.policy_file': '--name/--runs-dir (train) or --run/--policy (rollout)',
    'agent.evaluate': 'stealth rollout',
    'agent.load_policy': 'stealth train --resume or stealth rollout',
    'agent.eval_every': '--eval-every',
    'agent.first_episode': 'stealth train --resume',
    'agent.grid_sha256': '--scenario',
    'agent.lights_sha256': '--scenario',
    'environment.first_episode': 'stealth train --resume',
    'recorder.output': '--name/--runs-dir',
}
# Of those, the ones that change what a run does: a --params-dir file that sets one to something
# else than the run would is refused (the others say where things are and are replaced, noted).
BEHAVIOUR = ('agent.evaluate', 'agent.load_policy', 'agent.eval_every', 'agent.first_episode',
             'environment.first_episode')  # fmt: skip
ROS_PARAMETERS = 'ros__parameters'
# Parameters every rclpy node declares besides its own.
ROS_OWN_PARAMETERS = frozenset({'use_sim_time', 'start_type_description_service'})
_NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')


class RunConfigError(ValueError):
    """Input that cannot make a run; the message is one line saying which and why."""


class RunError(RuntimeError):
    """The run failed after it started; the message is the one line to print."""


# --- parameter files ----------------------------------------------------------------------------


def _is_parameter_value(value: Any) -> bool:
    """What a ROS parameter can hold: a scalar or a flat list of scalars of one kind."""
    scalar = (bool, int, float, str)
    if isinstance(value, scalar):
        return not (isinstance(value, float) and math.isnan(value))
    if isinstance(value, list):
        kinds = {bool if isinstance(v, bool) else type(v) for v in value}
        if not all(isinstance(v, scalar) for v in value):
            return False
        return len(kinds) <= 1 or kinds == {int, float}
    return False


def read_params_file(path: Path, node: str) -> dict[str, Any]:
    """The ros__parameters of `node` in a params file; RunConfigError when unusable."""
    try:
        text = Path(path).read_text(encoding='utf-8')
    except OSError as error:
        raise RunConfigError(f'parameter file {path}: cannot read it ({error.strerror})') from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        where = getattr(error, 'problem_mark', None)
        line = f' (line {where.line + 1})' if where is not None else ''
        problem = getattr(error, 'problem', None) or str(error).splitlines()[0]
        raise RunConfigError(f'parameter file {path}: not valid YAML{line}: {problem}') from None
    expected = f'a mapping "{node}: {{{ROS_PARAMETERS}: {{name: value, ...}}}}"'
    if not isinstance(data, dict):
        raise RunConfigError(f'parameter file {path}: expected {expected}, got {_kind(data)}')
    section = None
    for key in (node, f'/{node}', '/**'):
        if key in data:
            section = data[key]
            break
    if section is None:
        found = ', '.join(str(k) for k in data) or 'nothing'
        raise RunConfigError(
            f'parameter file {path}: no section for node {node!r} (it has: {found})'
        )
    if not isinstance(section, dict) or set(section) != {ROS_PARAMETERS}:
        raise RunConfigError(f'parameter file {path}: expected {expected}')
    parameters = section[ROS_PARAMETERS] or {}
    if not isinstance(parameters, dict):
        raise RunConfigError(f'parameter file {path}: expected {expected}')
    for name, value in parameters.items():
        if not isinstance(name, str) or not _NAME.match(name):
            raise RunConfigError(f'parameter file {path}: {name!r} is not a parameter name')
        if isinstance(value, dict):
            raise RunConfigError(
                f'parameter file {path}: {node}.{name}: nested parameters are not used by '
                'stealth-nav nodes'
            )
        if not _is_parameter_value(value):
            raise RunConfigError(
                f'parameter file {path}: {node}.{name}: {value!r} is not a parameter value '
                '(a number, string, bool or a list of one of them)'
            )
    return dict(parameters)


def _kind(value: Any) -> str:
    return 'an empty file' if value is None else f'a {type(value).__name__}'


def params_sources(defaults_dir: Path, params_dir: Path | None, nodes) -> dict[str, Path]:
    """{node: params file}: <params_dir>/<node>.yaml where it exists, else the default."""
    if params_dir is not None and not Path(params_dir).is_dir():
        raise RunConfigError(f'--params-dir {params_dir}: no such directory')
    sources = {}
    for node in nodes:
        own = Path(params_dir) / f'{node}.yaml' if params_dir is not None else None
        sources[node] = (
            own if own is not None and own.exists() else Path(defaults_dir) / f'{node}.yaml'
        )
    return sources


# --- --set ---------------------------------------------------------------------------------------


def parse_value(text: str) -> Any:
    """A parameter value as ROS reads `-p name:=value`: YAML (1.0 float, 1 int, true, [1, 2])."""
    try:
        value = yaml.safe_load(text) if text.strip() else ''
    except yaml.YAMLError:
        return text
    if value is None:
        return text
    return value


def parse_set(items: list[str], nodes) -> dict[str, dict[str, Any]]:
    """{node: {param: value}} from `node.param=value` items; RunConfigError naming a bad one."""
    result: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, text = item.partition('=')
        node, dot, name = key.strip().partition('.')
        if not sep or not dot or not name:
            raise RunConfigError(f'--set {item!r}: expected node.parameter=value')
        if node not in nodes:
            raise RunConfigError(f'--set {item!r}: no node {node!r} (nodes: {", ".join(nodes)})')
        if not _NAME.match(name):
            raise RunConfigError(f'--set {item!r}: {name!r} is not a parameter name')
        if f'{node}.{name}' in MANAGED:
            raise RunConfigError(
                f'--set {item!r}: {node}.{name} is set by the run itself; use '
                f'{MANAGED[f"{node}.{name}"]}'
            )
        value = parse_value(text)
        if not _is_parameter_value(value):
            raise RunConfigError(f'--set {item!r}: {text!r} is not a parameter value')
        result.setdefault(node, {})[name] = value
    return result


def check_managed(parameters: NodeParameters, file_values: dict[str, Any]) -> list[str]:
    """A --params-dir file's values of parameters the run sets itself: RunConfigError for one
    that changes what the run does (agent.load_policy: true in a new run, say), else one note
    per value the run replaces (a path of another run, say)."""
    notes = []
    for name, value in file_values.items():
        key = f'{parameters.node}.{name}'
        if key not in MANAGED or parameters.values.get(name) == value:
            continue
        if key in BEHAVIOUR:
            raise RunConfigError(
                f'parameter file {parameters.source}: {key}: {_yaml_text(value)} is set by the '
                f'run itself (here to {_yaml_text(parameters.values.get(name))}); use '
                f'{MANAGED[key]}, and remove the line from the file'
            )
        notes.append(
            f"{parameters.source}: {key} {_yaml_text(value)} replaced by the run's "
            f'{_yaml_text(parameters.values.get(name))} (set by {MANAGED[key]})'
        )
    return notes


def _yaml_text(value: Any) -> str:
    return (
        yaml.safe_dump(value, default_flow_style=True, width=10_000)
        .strip()
        .removesuffix('...')
        .strip()
    )


def check_parameter_names(parameters: NodeParameters, declared: frozenset[str]) -> None:
    """Every parameter given to a node must be one it declares: a typo in --set or a file for
    another version would be ignored without a word. RunConfigError naming where it came from."""
    unknown = sorted(set(parameters.values) - declared)
    if not unknown:
        return
    name = unknown[0]
    close = difflib.get_close_matches(name, sorted(declared), n=1)
    hint = f'did you mean {close[0]!r}? ' if close else ''
    known = f'its parameters: {", ".join(sorted(declared))}'
    node = parameters.node
    if name in parameters.overrides:
        raise RunConfigError(
            f'--set {node}.{name}: {node} has no parameter {name!r}; {hint}{known}'
        )
    if name in read_params_file(parameters.source, node):
        raise RunConfigError(
            f'parameter file {parameters.source}: {node} has no parameter {name!r}; {hint}{known}'
        )
    raise RunConfigError(
        f'the installed {node} has no parameter {name!r}, which the run sets: the workspace is '
        'older than this command; rebuild it (make setup)'
    )


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes (a scenario or map a run used), hex."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def scenario_hashes(scenario) -> dict[str, str]:
    """SHA-256 of the scenario file and of its map, for a continued run to compare."""
    hashes = {}
    for key, path in (('sha256', scenario.path), ('map_sha256', scenario.map_path)):
        try:
            hashes[key] = file_sha256(Path(path))
        except OSError as error:
            raise RunConfigError(f'{path}: cannot read it ({error.strerror})') from None
    return hashes


def load_run_scenario(name: str):
    """The scenario a run is asked for (name or path); RunConfigError where it cannot be read."""
    from stealth_core.scenario import ScenarioError, load_scenario

    try:
        return load_scenario(name)
    except ScenarioError as error:
        raise RunConfigError(str(error)) from None
    except OSError as error:
        raise RunConfigError(f'scenario {name!r}: {error}') from None


def check_goal(scenario, goal: str | None, default: str | None = None) -> str:
    """The goal given, else `default`, else the scenario's own; RunConfigError if it has none
    of that name."""
    goal = goal or default or scenario.default_goal
    if goal not in scenario.goals:
        raise RunConfigError(
            f'--goal {goal!r}: scenario {scenario.name!r} has no such goal '
            f'(it has: {", ".join(scenario.goals)})'
        )
    return goal


def coerce_like(value: Any, default: Any) -> Any:
    """An int given for a float parameter becomes a float (rclpy would refuse the int)."""
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if (
        isinstance(default, list)
        and default
        and all(isinstance(v, float) for v in default)
        and isinstance(value, list)
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    ):
        return [float(v) for v in value]
    return value


def ros_arg_value(value: Any) -> str:
    """A value as `-p name:=<text>` text that ROS reads back as the same type."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, list):
        return '[' + ', '.join(ros_arg_value(v) for v in value) + ']'
    if isinstance(value, str):
        return json.dumps(value)
    return str(value)


# --- effective parameters -----------------------------------------------------------------------


@dataclasses.dataclass
class NodeParameters:
    """One node's effective parameters and where they came from."""

    node: str
    source: Path  # the params file they started from
    values: dict[str, Any]
    overrides: dict[str, Any]  # from --set (also passed as -p)

    def ros_args(self, params_file: Path) -> list[str]:
        args = ['--ros-args', '--params-file', str(params_file)]
        for name, value in self.overrides.items():
            args += ['-p', f'{name}:={ros_arg_value(value)}']
        return args


def effective_parameters(
    node: str,
    source: Path,
    run_values: dict[str, Any],
    overrides: dict[str, Any],
) -> NodeParameters:
    """The file's parameters, then the run's (scenario, paths, seeds), then --set's."""
    values = read_params_file(source, node)
    for name, value in run_values.items():
        values[name] = value
    coerced = {}
    for name, value in overrides.items():
        coerced[name] = coerce_like(value, values.get(name))
        values[name] = coerced[name]
    return NodeParameters(node, Path(source), values, coerced)


def write_params_file(parameters: NodeParameters, path: Path, header: str) -> Path:
    """The effective parameters as a ROS 2 params file (what the node is started with)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [f'{parameters.node}:', f'  {ROS_PARAMETERS}:']
    for name, value in parameters.values.items():
        text = yaml.safe_dump(value, default_flow_style=True, width=10_000).strip()
        text = text.removesuffix('...').strip()
        lines.append(f'    {name}: {text}')
    body = '\n'.join(lines) + '\n'
    if yaml.safe_load(body) != {parameters.node: {ROS_PARAMETERS: parameters.values}}:
        raise RunConfigError(f'{path}: the parameters of {parameters.node} do not survive YAML')
    comments = ''.join(f'# {line}\n' for line in header.splitlines())
    path.write_text(comments + body, encoding='utf-8')
    return path


def scenario_parameters(scenario, goal: str) -> dict[str, dict[str, Any]]:
    """What the nodes must agree on, filled in from the scenario so users only name it."""
    from stealth_core.scenario import content_identity

    x, y, yaw = scenario.start
    return {
        'simulator': {
            'map': str(Path(scenario.map_path).resolve()),
            'initial_pose': [float(x), float(y), float(yaw)],
            'robot_radius': float(scenario.robot_radius),
        },
        'environment': {'scenario': str(Path(scenario.path).resolve()), 'goal': goal},
        'agent': content_identity(scenario),  # saved with the policy: what rollout checks
    }


# --- names and directories ----------------------------------------------------------------------


def utc_stamp(now: datetime.datetime | None = None) -> str:
    now = now or datetime.datetime.now(datetime.UTC)
    return now.strftime('%Y%m%dT%H%M%SZ')


def choose_run_directory(runs_dir: Path, name: str | None, default_name: str) -> Path:
    """Where a new run goes, not created yet (so that a refused run leaves nothing behind):
    runs_dir/name (must not exist) or runs_dir/default_name[-2, -3...]."""
    if name is not None:
        if not name or '/' in name or name in ('.', '..'):
            raise RunConfigError(f'--name {name!r}: expected a plain directory name')
        path = Path(runs_dir) / name
        if path.exists():
            raise RunConfigError(f'run directory {path} exists already; choose another --name')
        return path
    path = Path(runs_dir) / default_name
    number = 2
    while path.exists():
        path = Path(runs_dir) / f'{default_name}-{number}'
        number += 1
    return path


def create_run_directory(path: Path) -> Path:
    """Make the directory choose_run_directory chose (RunConfigError where it cannot)."""
    try:
        path.mkdir(parents=True)
    except OSError as error:
        raise RunConfigError(
            f'run directory {path}: cannot create it ({error.strerror})'
        ) from None
    return path


def relative_to_cwd(path: Path) -> str:
    """A path as the user would type it from here (relative when below the working directory)."""
    try:
        return (
            os.path.relpath(path) if Path(path).resolve().is_relative_to(Path.cwd()) else str(path)
        )
    except ValueError:
        return str(path)
