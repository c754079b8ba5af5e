"""A node's parameter table, as plain data: what the node declares (stealth_node_kit.parameters
does, with rclpy) and what an orchestrator can check a parameter file against before any node
starts. No rclpy, no ROS messages.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple


class Unset(NamedTuple):
    """The default of a parameter declared without a value: its type, a rclpy
    ``Parameter.Type`` name such as 'DOUBLE_ARRAY'."""

    type: str


class Param(NamedTuple):
    """One parameter: default, description, inclusive (low, high) range, fixed after startup.

    Integer bounds give an integer range, float bounds a floating-point one; a default of
    Unset('DOUBLE_ARRAY') (a ``Parameter.Type`` name) declares it without a value (it may stay
    unset).
    """

    default: Any
    description: str
    bounds: tuple | None = None
    read_only: bool = False


# What a value of each rclpy ``Parameter.Type`` is, for a message.
EXPECTED = {
    'BOOL': 'true or false',
    'INTEGER': 'a whole number',
    'DOUBLE': 'a number',
    'STRING': 'a string',
    'BYTE_ARRAY': 'a list of bytes',
    'BOOL_ARRAY': 'a list of true/false',
    'INTEGER_ARRAY': 'a list of whole numbers',
    'DOUBLE_ARRAY': 'a list of numbers',
    'STRING_ARRAY': 'a list of strings',
}


def value_type(value: Any) -> str | None:
    """The ``Parameter.Type`` name of a value as rclpy types it (a list of numbers with a float
    in it: DOUBLE_ARRAY); None for an empty or mixed list or anything else."""
    if isinstance(value, bool):
        return 'BOOL'
    if isinstance(value, int):
        return 'INTEGER'
    if isinstance(value, float):
        return 'DOUBLE'
    if isinstance(value, str):
        return 'STRING'
    if isinstance(value, list | tuple):
        kinds = {value_type(item) for item in value}
        if kinds == {'INTEGER', 'DOUBLE'}:
            return 'DOUBLE_ARRAY'
        if len(kinds) == 1 and next(iter(kinds)) in ('BOOL', 'INTEGER', 'DOUBLE', 'STRING'):
            return f'{next(iter(kinds))}_ARRAY'
    return None


def declared_type(param: Param) -> str | None:
    """The ``Parameter.Type`` name the node declares the parameter with (its default's)."""
    if isinstance(param.default, Unset):
        return param.default.type
    return value_type(param.default)


def as_declared(param: Param, value: Any) -> Any:
    """A value as the node declares it: a whole number for a double becomes a float, a list of
    numbers for a double array a list of floats (rclpy refuses an integer for a double)."""
    wanted = declared_type(param)
    if wanted == 'DOUBLE' and value_type(value) == 'INTEGER':
        return float(value)
    if wanted == 'DOUBLE_ARRAY' and value_type(value) in ('INTEGER_ARRAY', 'DOUBLE_ARRAY'):
        return [float(item) for item in value]
    return value


def value_problem(param: Param, value: Any) -> str | None:
    """Why a node that declares ``param`` refuses ``value`` at startup (its type, its range, a
    double that is not finite: our nodes refuse one), as 'expected ..., got ...'; None when it
    takes it. A whole number for a double is taken (as_declared)."""
    wanted = declared_type(param)
    typed = as_declared(param, value)
    got = value_type(typed)
    numeric = wanted in ('INTEGER', 'DOUBLE')
    expected = EXPECTED.get(wanted, 'a parameter value')
    if numeric and param.bounds is not None:
        low, high = (f'{end:g}' if isinstance(end, float) else str(end) for end in param.bounds)
        expected += f' from {low} to {high}'
    empty_list = isinstance(typed, list | tuple) and not typed
    if wanted is not None and got != wanted and not (empty_list and wanted.endswith('_ARRAY')):
        return f'expected {expected}, got {value!r}'
    if numeric and param.bounds is not None:
        if not param.bounds[0] <= typed <= param.bounds[1]:  # nan is in no range
            return f'expected {expected}, got {value!r}'
    elif got == 'DOUBLE' and not math.isfinite(typed):
        return f'expected a finite number, got {value!r}'
    return None
