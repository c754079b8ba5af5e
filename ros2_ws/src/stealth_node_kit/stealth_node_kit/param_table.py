"""A node's parameter table, as plain data: what the node declares (stealth_node_kit.parameters
does, with rclpy) and what an orchestrator can check a parameter file against before any node
starts. No rclpy, no ROS messages.
"""

from __future__ import annotations

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
