"""The controller's speed law: the braking curve it solves, and the same numbers compiled (the
kernels call these functions through numba) as in plain Python (the reference and the moves
over topics)."""

import math

import numpy as np
import pytest
from stealth_core.controller import approach_speed, signed_approach_speed
from stealth_core.jit import jit

DT = 0.04
DECEL = 0.8 * 1.0  # braking_share * max_linear_accel (simulator.yaml's)


def test_the_speed_brakes_to_rest_within_the_distance_after_one_period_at_it():
    for distance in (1e-4, 0.01, 0.1, 0.5, 2.0):
        speed = approach_speed(distance, math.inf, DECEL, DT)
        assert speed * DT + speed * speed / (2 * DECEL) == pytest.approx(distance, rel=1e-12)
    assert approach_speed(100.0, 0.5, DECEL, DT) == 0.5  # capped
    assert approach_speed(1e-6, 0.5, DECEL, DT) == pytest.approx(1e-6 / DT, rel=1e-3)  # deadbeat
    assert approach_speed(0.0, 0.5, DECEL, DT) == approach_speed(-1.0, 0.5, DECEL, DT) == 0.0


def test_the_signed_speed_has_the_offsets_sign():
    for offset in (-2.0, -0.3, -1e-3, 1e-3, 0.3, 2.0):
        speed = signed_approach_speed(offset, 1.5, 2.4, DT)
        assert speed == math.copysign(approach_speed(abs(offset), 1.5, 2.4, DT), offset)
    assert math.copysign(1.0, signed_approach_speed(-0.0, 1.5, 2.4, DT)) == -1.0


@jit
def _compiled(offsets, max_speed, decel, dt):
    speeds = np.empty((offsets.size, 2))
    for i in range(offsets.size):
        speeds[i, 0] = approach_speed(offsets[i], max_speed, decel, dt)
        speeds[i, 1] = signed_approach_speed(offsets[i], max_speed, decel, dt)
    return speeds


def test_compiled_and_plain_python_give_the_same_speeds_bit_for_bit():
    offsets = np.concatenate(
        [np.linspace(-4.0, 4.0, 2001), np.geomspace(1e-9, 10.0, 500), [0.0, -0.0, math.pi]]
    )
    for max_speed, decel, dt in (
        (0.5, 0.8, 0.04),
        (1.5, 2.4, 0.04),
        (0.5, 0.8, 0.1),
        (1.0, 3.0, 0.2),
    ):
        compiled = _compiled(offsets, max_speed, decel, dt)
        plain = np.array(
            [
                (
                    approach_speed(o, max_speed, decel, dt),
                    signed_approach_speed(o, max_speed, decel, dt),
                )
                for o in offsets.tolist()
            ]
        )
        assert compiled.tobytes() == plain.tobytes()
