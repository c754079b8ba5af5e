"""Subscriptions that the executor does not wake for: their messages wait in the reader's
queue (its QoS history) until the node takes them, when it chooses, with
:meth:`OnDemand.drain`; and QoS event handlers it does not wait on, polled with
:meth:`OnDemand.poll_events`.

Why: rclpy's executor rebuilds its wait set and wakes the node's thread for every message. A
node that only needs the latest of some topics when something else happens (the environment's
controller, which decides once per odometry message, needs the scan, the estimate and the clock
only then; the agent reads its clock once per episode) pays that wake-up for each message of
each topic: measured in a topics training run, the agent's ``/clock`` subscription alone cost
it ~5 ms of CPU per RL step, and the environment woke ~4 times per control period instead of
once. Draining runs each subscription's own callback on every pending message, oldest first,
as the executor would have: only when changes, never what is received (a queue of depth N keeps
the latest N, as it does while a busy executor falls behind).
"""

from __future__ import annotations

from rclpy.callback_groups import CallbackGroup
from rclpy.event_handler import EventHandler
from rclpy.exceptions import InvalidHandle
from rclpy.subscription import Subscription
from rclpy.time_source import TimeSource


class OnDemand(CallbackGroup):
    """A callback group whose subscriptions the executor never waits on; :meth:`drain` runs
    their callbacks for the messages that came, in the order the subscriptions were added.

    Nor their QoS event handlers (a warning about incompatible QoS): under Fast DDS a reader
    with messages not taken keeps its status condition raised, so a wait set holding one of
    its events returns at once, for ever (measured: a node busy-waiting at ~85 % of a core).
    Give its subscriptions no event callbacks (``QUIET_SUBSCRIPTION``), or poll the handlers
    moved here (:func:`events_on_demand`, :meth:`poll_events`)."""

    def __init__(self):
        super().__init__()
        self._subscriptions: list[Subscription] = []
        self._events: list[EventHandler] = []

    def add_entity(self, entity) -> None:
        super().add_entity(entity)
        if isinstance(entity, Subscription):
            self._subscriptions.append(entity)
        elif isinstance(entity, EventHandler):
            self._events.append(entity)

    def can_execute(self, entity) -> bool:
        return False  # never in the executor's wait set

    def beginning_execution(self, entity) -> bool:
        return False

    def ending_execution(self, entity) -> None:
        pass

    def drain(self) -> int:
        """Run the callbacks of every pending message (oldest first); how many there were."""
        taken = 0
        for subscription in list(self._subscriptions):
            while True:
                try:
                    with subscription.handle:
                        message = subscription.handle.take_message(
                            subscription.msg_type, subscription.raw
                        )
                except InvalidHandle:  # destroyed (the node is going down, or use_sim_time off)
                    self._subscriptions.remove(subscription)
                    break
                if message is None:
                    break
                taken += 1
                if subscription._callback_type is Subscription.CallbackType.MessageOnly:
                    subscription.callback(message[0])
                else:
                    subscription.callback(*message)
        return taken

    def poll_events(self) -> int:
        """Run the callback of each QoS event handler (moved here by :func:`events_on_demand`)
        whose status changed since it was last taken, as the executor would have once the
        event woke it; how many ran."""
        ran = 0
        for handler in list(self._events):
            handler._ready_to_take_data = True  # rclpy's flag for "the wait set said so"
            try:
                status = handler.take_data()
            except InvalidHandle:  # destroyed with its endpoint
                self._events.remove(handler)
                continue
            if status is not None and getattr(status, 'total_count_change', 0) > 0:
                handler.callback(status)
                ran += 1
        return ran


def events_on_demand(node, group: OnDemand) -> OnDemand:
    """Move the QoS event handlers of every publisher and subscription ``node`` has now
    (incompatible QoS or type: warnings) into ``group``, to be polled with
    :meth:`OnDemand.poll_events` from a timer the node has anyway, rather than waited on at
    every wake-up: measured, each cost the executor ~10 us per wake-up (more with a cold
    cache), and a node driven every control period has six. Returns ``group``."""
    for endpoint in (*node.publishers, *node.subscriptions):
        for handler in endpoint.event_handlers:
            if handler.callback_group is not group:
                handler.callback_group = group
                group.add_entity(handler)
    return group


def clock_on_demand(node, group: OnDemand) -> bool:
    """Move the node's ``/clock`` subscription (rclpy's TimeSource makes one under
    ``use_sim_time``) into ``group``: the node's ROS clock then moves when the group is drained,
    not at every ``/clock`` message. Whether there was one to move (none without
    ``use_sim_time``; one that use_sim_time creates later stays with the executor). Its QoS
    event handlers go too (see :class:`OnDemand`): rclpy's warning about a ``/clock`` publisher
    with incompatible QoS is not logged."""
    moved = False
    for subscription in node.subscriptions:
        owner = getattr(subscription.callback, '__self__', None)
        if isinstance(owner, TimeSource) and subscription.callback_group is not group:
            for entity in (subscription, *subscription.event_handlers):
                entity.callback_group = group
                group.add_entity(entity)
            moved = True
    return moved
