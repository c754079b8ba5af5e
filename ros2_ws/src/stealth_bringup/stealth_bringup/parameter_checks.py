"""Every node's effective parameters checked against the node's own table before anything of a
run exists: the names it declares, each value's type and range (its table's Param, as rclpy
would check them when the node declares it: stealth_node_kit.param_table), and the node's own
checks of a value where it has them (a learner, a schedule, a choice). A value out of range
would otherwise pass the orchestrator and stop the run once its nodes are up, or, as the agent's
gamma did for the floor-plan prior, fail in the orchestrator itself. No rclpy.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

from stealth_node_kit.param_table import Param, as_declared, value_problem

from stealth_bringup.run_config import (
    ROS_OWN_PARAMETERS,
    NodeParameters,
    RunConfigError,
    check_parameter_names,
    read_params_file,
)


class _Change(NamedTuple):
    """A parameter change as the nodes' on-set checks read one (rclpy's Parameter's fields)."""

    name: str
    value: object


def node_table(node: str) -> Mapping[str, Param]:
    """The parameter table the installed node declares."""
    from stealth_agent import agent_parameters
    from stealth_env import env_parameters
    from stealth_sim import sim_parameters
    from stealth_tools import bridge_parameters, recorder_parameters

    tables = {
        'recorder': recorder_parameters,
        'bridge': bridge_parameters,
        'simulator': sim_parameters,
        'environment': env_parameters,
        'agent': agent_parameters,
    }
    return tables[node].PARAMETERS


def declared_parameters(node: str) -> frozenset[str]:
    """The parameters the installed node declares: its table, and those of every ROS node."""
    return frozenset(node_table(node)) | ROS_OWN_PARAMETERS


def check_parameters(parameters: dict[str, NodeParameters], replaced: set[str]) -> None:
    """Every node's names and values (a node replaced with --executable is checked once it
    runs); a whole number for a double becomes a float, as the node declares it.
    RunConfigError naming the first bad one and where it came from."""
    for node, values in parameters.items():
        if node in replaced:
            continue
        check_parameter_names(values, declared_parameters(node))
        check_parameter_values(values, node_table(node))


def check_parameter_values(parameters: NodeParameters, table: Mapping[str, Param]) -> None:
    """Each value against its Param (type, range), then the node's own check of it; then the
    agent's check of its whole set (a learner's settings together)."""
    node = parameters.node
    for name, value in list(parameters.values.items()):
        if name not in table:  # a ROS node's own (use_sim_time)
            continue
        problem = value_problem(table[name], value) or _own_problem(node, name, value)
        if problem is not None:
            raise RunConfigError(f'{_origin(parameters, name)}: {problem}')
        value = as_declared(table[name], value)
        parameters.values[name] = value
        if name in parameters.overrides:  # passed again as -p, where rclpy types it by its text
            parameters.overrides[name] = value
    if node == 'agent':
        from stealth_agent.agent_parameters import startup_problem

        defaults = {name: param.default for name, param in table.items()}
        problem = startup_problem({**defaults, **parameters.values})
        if problem is not None:
            raise RunConfigError(f'agent parameters: {problem}')


def _own_problem(node: str, name: str, value) -> str | None:
    """What the node's own on-set check says of one value (its learner names, schedules and
    choices), None where it takes it or has none."""
    if node == 'agent':
        from stealth_agent.agent_parameters import change_problem

        return change_problem([(name, value)], None)
    if node == 'environment':
        from stealth_env.env_parameters import not_a_choice

        return not_a_choice([_Change(name, value)])
    return None


def _origin(parameters: NodeParameters, name: str) -> str:
    """Where a value came from, as a message starts: --set, its parameter file, or the run."""
    key = f'{parameters.node}.{name}'
    if name in parameters.overrides:
        return f'--set {key}'
    file_values = read_params_file(parameters.source, parameters.node)
    if name in file_values and file_values[name] == parameters.values[name]:
        return f'parameter file {parameters.source}: {key}'
    return f'{key} (set by the run)'
