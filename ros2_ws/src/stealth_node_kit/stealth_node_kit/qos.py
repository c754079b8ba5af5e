"""The QoS profile the nodes' latched topics and reports share."""

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
