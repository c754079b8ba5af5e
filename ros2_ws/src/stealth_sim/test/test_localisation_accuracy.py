"""The measured claim: over a 200-move random walk the estimate stays within 0.2 m RMS of the
truth while dead reckoning on the odometry alone drifts well beyond, on every map.

Run with ``-s`` to see the figures. The project's maps are used when they are built
(``make maps``); the hand-made maze always runs.
"""

import dataclasses
import math

import numpy as np
import pytest
from sim_test_maps import PROJECT_MAPS, maze_map, project_map_and_start
from stealth_core.kinematics import DiscFootprint, Pose
from stealth_core.moves import GRID_HEADINGS, MoveOutcome, MoveRequest
from stealth_sim.move_executor import execute_move
from stealth_sim.simulator import SimConfig, Simulator

MOVES = 200
STEP = 0.5  # m, the scenarios' move step
SEED = 2024
# Moves are chosen, where possible, so the disc with this extra margin would clear the way from
# the estimate: the walk is about localisation, not bumping (a few bumps are still allowed).
CHOICE_MARGIN = 0.1
ESTIMATE_RMS_LIMIT = 0.2


@dataclasses.dataclass(frozen=True)
class WalkFigures:
    estimate_rms: float  # m, estimate vs truth after each move
    dead_reckoning_rms: float  # m, odometry vs truth after each move
    covariance_ratio: float  # mean squared error / mean trace of the xy covariance
    bumps: int


def random_walk(occupancy_map, start: Pose, seed: int = SEED) -> WalkFigures:
    sim = Simulator(occupancy_map, SimConfig(seed=seed), start)
    radius = sim.config.robot_radius
    # The widest footprint that leaves a way out; in a tight spot, any move (it may bump).
    choosers = [DiscFootprint(occupancy_map, radius + CHOICE_MARGIN), sim.footprint, None]
    rng = np.random.default_rng(seed)
    estimate_sq, odometry_sq, trace, bumps = [], [], [], 0
    for _ in range(MOVES):
        here = sim.estimate
        for chooser in choosers:
            possible = [
                kind
                for kind, heading in GRID_HEADINGS.items()
                if chooser is None
                or chooser.sweep_is_free(
                    here.x,
                    here.y,
                    here.x + STEP * math.cos(heading),
                    here.y + STEP * math.sin(heading),
                )
            ]
            if possible:
                break
        result = execute_move(sim, MoveRequest(rng.choice(possible), STEP))
        bumps += result.outcome == MoveOutcome.BUMPED
        truth, estimate, odometry = sim.ground_truth, sim.estimate, sim.odometry_pose
        estimate_sq.append((estimate.x - truth.x) ** 2 + (estimate.y - truth.y) ** 2)
        odometry_sq.append((odometry.x - truth.x) ** 2 + (odometry.y - truth.y) ** 2)
        trace.append(np.trace(sim.estimate_covariance[:2, :2]))
    return WalkFigures(
        estimate_rms=math.sqrt(np.mean(estimate_sq)),
        dead_reckoning_rms=math.sqrt(np.mean(odometry_sq)),
        covariance_ratio=float(np.mean(estimate_sq) / np.mean(trace)),
        bumps=bumps,
    )


def check_walk(name: str, figures: WalkFigures) -> None:
    print(
        f'\n{name}: {MOVES} moves of {STEP} m, estimate RMS error {figures.estimate_rms:.3f} m, '
        f'dead reckoning RMS error {figures.dead_reckoning_rms:.3f} m, '
        f'squared error / covariance trace {figures.covariance_ratio:.2f}, bumps {figures.bumps}'
    )
    assert figures.estimate_rms < ESTIMATE_RMS_LIMIT
    assert figures.dead_reckoning_rms > 2 * ESTIMATE_RMS_LIMIT
    # Honest covariance: neither overconfident nor uselessly wide.
    assert 0.25 < figures.covariance_ratio < 2.0
    assert figures.bumps <= MOVES // 20


def test_random_walk_on_the_hand_made_maze():
    check_walk('maze', random_walk(maze_map(), Pose(3.0, 2.0, 0.0)))


@pytest.mark.parametrize('name', PROJECT_MAPS)
def test_random_walk_on_the_project_maps(name):
    loaded = project_map_and_start(name)
    if loaded is None:
        pytest.skip(f'maps/{name}.yaml is not built yet (make maps)')
    check_walk(name, random_walk(*loaded))
