"""The planner server's accepted goals, served one at a time in the order they came (no rclpy).

rclpy's action server runs every accepted goal as soon as it is accepted; the planner plans one
goal at a time (its caches are not shared between threads), so the node keeps the others here
(rclpy's example server_queue_goals does the same). A goal is anything hashable by identity:
the node's rclpy goal handles, plain objects in the tests.
"""

from __future__ import annotations

from collections import deque


class GoalQueue:
    """The goal running and those waiting behind it, at most ``capacity`` of them."""

    def __init__(self, capacity: int):
        self.capacity = int(capacity)
        self.running = None
        self._waiting: deque = deque()

    def __len__(self) -> int:
        """The goals waiting (not the one running)."""
        return len(self._waiting)

    @property
    def full(self) -> bool:
        """True when a goal that came now would have to wait and there is no room for it."""
        return self.running is not None and len(self._waiting) >= self.capacity

    def arrive(self, goal) -> bool:
        """Take a goal; True when it is to run now (nothing else is), else it waits its turn.
        ValueError when it is full (check ``full`` first)."""
        if self.running is None:
            self.running = goal
            return True
        if self.full:
            raise ValueError(f'goal queue full: {len(self._waiting)} waiting')
        self._waiting.append(goal)
        return False

    def finish(self, goal):
        """The goal that runs next once ``goal`` has ended (None: none waits), or None when
        ``goal`` was not the one running (a withdrawn goal ending)."""
        if goal is not self.running:
            return None
        self.running = self._waiting.popleft() if self._waiting else None
        return self.running

    def withdraw(self, goal) -> bool:
        """Take a waiting goal out of the queue (it was cancelled); False when it is not
        waiting (it runs, or has ended)."""
        for k, waiting in enumerate(self._waiting):
            if waiting is goal:
                del self._waiting[k]
                return True
        return False
