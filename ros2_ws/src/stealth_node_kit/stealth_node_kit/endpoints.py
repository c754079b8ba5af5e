"""The QoS event callbacks every node's publishers and subscriptions take.

QoS event handlers: rclpy gives every endpoint several by default, and each is one more entity
in every wait of the executor (measured: about 10 % of the steps per second of the RL loop). The
nodes keep none, except the incompatible-QoS warning on the endpoints where a mismatch would
make the system silently stall.
"""

from __future__ import annotations

from collections.abc import Callable

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import qos_policy_name_from_kind

QUIET_PUBLISHER = PublisherEventCallbacks(use_default_callbacks=False)
QUIET_SUBSCRIPTION = SubscriptionEventCallbacks(use_default_callbacks=False)


def _warning(logger: Callable[[], object], text: str) -> Callable:
    def warn(event) -> None:
        policy = qos_policy_name_from_kind(event.last_policy_kind)
        logger().warning(text.format(policy=policy))

    return warn


def warn_publisher(logger: Callable[[], object], text: str) -> PublisherEventCallbacks:
    """Only the incompatible-QoS warning: `text` with ``{policy}`` for the policy's name;
    `logger` is called when it fires (e.g. ``node.get_logger``)."""
    return PublisherEventCallbacks(
        incompatible_qos=_warning(logger, text), use_default_callbacks=False
    )


def warn_subscription(logger: Callable[[], object], text: str) -> SubscriptionEventCallbacks:
    """As :func:`warn_publisher`, for a subscription."""
    return SubscriptionEventCallbacks(
        incompatible_qos=_warning(logger, text), use_default_callbacks=False
    )
