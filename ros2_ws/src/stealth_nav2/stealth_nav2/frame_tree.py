"""Planar poses from another frame into the map, over the latest transforms heard on /tf (no
rclpy): what Nav2's planner server asks of tf2 for a start or goal not in its global frame.

Only the latest transform of each parent -> child pair is kept (the simulator's ``map -> odom``
and ``odom -> base_link``); a pose is carried along the chain of known transforms between its
frame and the target, whichever way each one points (``stealth_core.frames`` math).
"""

from __future__ import annotations

from collections import deque

from stealth_core.frames import inverse, multiply
from stealth_core.kinematics import Pose


class FrameError(LookupError):
    """No chain of known transforms joins the frames; the message names them."""


class FrameTree:
    def __init__(self):
        self._edges: dict[str, dict[str, Pose]] = {}  # frame -> {neighbour: neighbour in frame}

    def update(self, parent: str, child: str, pose: Pose) -> None:
        """The pose of ``child`` in ``parent`` (a TransformStamped), replacing the last."""
        parent, child = parent.lstrip('/'), child.lstrip('/')
        self._edges.setdefault(parent, {})[child] = Pose(*pose)
        self._edges.setdefault(child, {})[parent] = inverse(Pose(*pose))

    @property
    def frames(self) -> list[str]:
        return sorted(self._edges)

    def transform(self, pose: Pose, source: str, target: str) -> Pose:
        """The pose given in ``source``, expressed in ``target``; FrameError when no chain of
        known transforms joins them."""
        source, target = source.lstrip('/'), target.lstrip('/')
        if source == target:
            return Pose(*pose)
        chain = self._chain(target, source)  # source's pose in target
        if chain is None:
            known = ', '.join(self.frames) or 'none'
            raise FrameError(
                f'no transform from frame {source!r} to {target!r} has arrived on /tf (frames '
                f'heard: {known})'
            )
        return multiply(chain, Pose(*pose))

    def _chain(self, start: str, end: str) -> Pose | None:
        """The pose of frame ``end`` in frame ``start`` (breadth first over known edges)."""
        if start not in self._edges:
            return None
        found = {start: Pose(0.0, 0.0, 0.0)}
        frontier = deque([start])
        while frontier:
            frame = frontier.popleft()
            if frame == end:
                return found[frame]
            for neighbour, pose in self._edges[frame].items():
                if neighbour not in found:
                    found[neighbour] = multiply(found[frame], pose)
                    frontier.append(neighbour)
        return None
