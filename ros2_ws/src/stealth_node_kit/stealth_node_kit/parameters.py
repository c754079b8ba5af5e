"""A node's parameters as one table, declared in one call.

Every entry becomes a declared parameter with its ROS descriptor (description, range,
read-only), so `ros2 param describe` shows the limits the node enforces and rclpy rejects an
out-of-range value with the parameter's name before the node's own checks run.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
import math
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from stealth_node_kit.param_table import Param, Unset

__all__ = ['Param', 'StartupError', 'Unset', 'declare_parameters', 'descriptor', 'non_finite']


class StartupError(RuntimeError):
    """Parameters (or what they name) that make it impossible to start; says which and why."""


def descriptor(param: Param) -> ParameterDescriptor:
    result = ParameterDescriptor(description=param.description, read_only=param.read_only)
    if param.bounds is None:
        return result
    low, high = param.bounds
    if isinstance(low, int) and isinstance(high, int):
        result.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
    else:
        result.floating_point_range = [
            FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)
        ]
    return result


def declare_parameters(node, table: Mapping[str, Param]) -> dict[str, Any]:
    """Declare every parameter of the table on the node; their values by name.

    StartupError names the parameter when rclpy refuses a value (type, range, or the node's
    on-set callback).
    """
    from rclpy.parameter import Parameter

    values = {}
    for name, param in table.items():
        default = param.default
        if isinstance(default, Unset):  # declared with a type, without a value
            default = Parameter.Type[default.type]
        try:
            parameter = node.declare_parameter(name, default, descriptor(param))
        except Exception as error:  # rclpy's type, range and validation errors
            raise StartupError(f'parameter {name}: {error}') from None
        values[name] = parameter.value
    return values


def non_finite(changes: Iterable) -> str | None:
    """Why a change is refused when it sets a double to nan or inf (a range does not catch it
    on a parameter that has none), else None."""
    for change in changes:
        if isinstance(change.value, float) and not math.isfinite(change.value):
            return f'{change.name} must be finite, got {change.value}'
    return None
