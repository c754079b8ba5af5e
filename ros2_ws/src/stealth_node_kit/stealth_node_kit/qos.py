"""The QoS profiles the nodes' latched topics, reports and request services share."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def kept_qos(depth: int) -> QoSProfile:
    """Reliable and transient local with the last `depth` messages (1: latched, as nav2's maps):
    a reader that joins late, or again after a restart, gets what it missed."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def every_request_qos() -> QoSProfile:
    """Reliable, volatile, keep all: for a service (an action's goal, cancel and result services
    too) that must answer every request of a burst, on the server's side and on a bursting
    client's. rclpy's default (``qos_profile_services_default``) keeps the last 10 not yet
    taken: the 11th request pushes out the oldest, which is never answered (measured on the
    planner server: 10 of 20 goals sent at once answered, the rest left waiting forever)."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )
