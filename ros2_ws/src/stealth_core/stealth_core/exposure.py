"""Exposure by orientation: how much of the robot a light sees, from the way the robot faces.

The robot's footprint is a rectangle of ``length`` (along its heading) by ``width`` (across).
Seen from a lamp, it shows its projected width: the length of its shadow on a line at right
angles to the ray from the lamp. A light's contribution at a point is multiplied by

    exposure(theta) = (L * |sin(theta)| + W * |cos(theta)|) / sqrt(L^2 + W^2)

where theta is the angle between the robot's heading and the ray from the lamp to the robot, L
the length and W the width. The numerator is the rectangle's projected width (the half-sides'
projections add up); the denominator is its largest, sqrt(L^2 + W^2) (the diagonal, reached at
tan(theta) = L / W), so a light sees all of the robot at most (factor 1, a corner towards the
lamp) and at least min(L, W) / sqrt(L^2 + W^2) of it (a narrow end straight towards the lamp).
Going straight towards or away from a light (theta 0 or pi) shows the width, crossing its beam
(theta pi/2) the length. The factor is applied to each light's direct contribution before the
lights are added (``visibility.PointVisibility``), so it never makes the robot brighter than
the light at its point.

Headings on the move lattice are quarter turns: heading k faces ``k * pi/2`` counter-clockwise
from +x (0 east, 1 north, 2 west, 3 south), the direction of the robot's last move. A move
turns the robot to its direction (in place, at the departure), then drives; a turn action
(where the scenario enables them) turns a quarter in place and takes a step. While the robot
turns it shows every heading in between, so a step's visibility includes the turn, sampled
every ``TURN_SAMPLE`` (``StealthTask.step_samples_of``).

A scenario enables the option with an ``exposure`` mapping (``stealth_core.scenario``); the
footprint defaults to the simulator's robot, a disc of ``robot_radius``: a square of
2 * robot_radius.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

HEADINGS = 4  # quarter turns on the lattice
# The heading each move action (0 up, 1 down, 2 left, 3 right) leaves the robot facing.
MOVE_HEADINGS = (1, 3, 2, 0)
HEADING_NAMES = ('east', 'north', 'west', 'south')
TURN_SAMPLE = math.radians(5.0)  # rad between samples of a turn


class Footprint(NamedTuple):
    """The robot's rectangle (m) and whether the task has turn-in-place actions."""

    length: float  # along the heading
    width: float  # across it
    turn_actions: bool = False

    @property
    def largest(self) -> float:
        """The largest projected width: the diagonal."""
        return math.hypot(self.length, self.width)


def valid_length(value) -> bool:
    """Whether a footprint's length or width is usable: a finite number > 0 (m)."""
    return (
        not isinstance(value, bool)
        and isinstance(value, int | float)
        and math.isfinite(value)
        and value > 0
    )


def factor(footprint: Footprint, heading, dx, dy):
    """The share of the robot a lamp at offset (-dx, -dy) sees (the point is (dx, dy) from the
    lamp), the robot facing ``heading`` (rad); arrays broadcast."""
    theta = np.asarray(heading, dtype=np.float64) - np.arctan2(dy, dx)
    projected = footprint.length * np.abs(np.sin(theta)) + footprint.width * np.abs(np.cos(theta))
    return projected / footprint.largest


def heading_angle(heading: int) -> float:
    """The yaw (rad) of a lattice heading (quarter turns from +x)."""
    return (int(heading) % HEADINGS) * (math.pi / 2)


def heading_of(yaw: float) -> int:
    """The lattice heading nearest to a yaw (rad): 0 east, 1 north, 2 west, 3 south."""
    return round(float(yaw) / (math.pi / 2)) % HEADINGS


def wrap(angle):
    """An angle (rad, arrays too) in [-pi, pi)."""
    return (np.asarray(angle, dtype=np.float64) + math.pi) % (2 * math.pi) - math.pi
