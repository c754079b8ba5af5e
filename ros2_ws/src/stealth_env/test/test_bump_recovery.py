"""A bumped lattice drive's back-off and retry points: moved off the jambs of a tight door,
within the cells of its two nodes; and the episode flow's back-off, retry and judging."""

import numpy as np
import pytest
from stealth_core.bump_recovery import BumpRecovery
from stealth_core.clearance import LEVELS, Clearance, ClearanceSettings
from stealth_core.moves import MoveOutcome
from stealth_core.occupancy_map import OccupancyMap
from stealth_core.scenario import load_scenario
from stealth_core.task import StealthTask
from stealth_env.episode_flow import EpisodeFlow, PlanarPose
from stealth_env.topic_moves import go_to

RES = 0.1

DONE, BUMPED = MoveOutcome.DONE, MoveOutcome.BUMPED


def doorway() -> OccupancyMap:
    """A generated building's door: a 0.2 m wall at x 4.9..5.1 with a 1.0 m gap at y 3..4."""
    data = np.zeros((70, 100), np.int8)
    data[:30, 49:51] = 100
    data[40:, 49:51] = 100
    return OccupancyMap(data, RES, (0.0, 0.0, 0.0))


def test_a_drive_through_a_tight_door_is_retried_on_a_line_off_its_jamb():
    # The lattice line y = 3.25 passes 0.25 m from the jamb at y = 3.0: 0.05 m for the disc.
    recovery = BumpRecovery(doorway(), 0.2, 0.5)
    back, retry = recovery.points((4.75, 3.25), (5.25, 3.25))
    assert back == pytest.approx((4.75, 3.35)) and retry == pytest.approx((5.25, 3.35))
    clearance = Clearance(doorway(), ClearanceSettings(0.2, 0.15, 0.15))
    assert clearance.level(4.75, 3.25, 5.25, 3.25) < clearance.level(*back, *retry) == LEVELS
    # The other line, towards the other jamb: shifted the other way; coming back: the same line.
    assert recovery.points((4.75, 3.75), (5.25, 3.75))[1] == pytest.approx((5.25, 3.65))
    assert recovery.points((5.25, 3.25), (4.75, 3.25))[1] == pytest.approx((4.75, 3.35))


def test_the_retry_line_stays_within_the_cells_of_its_nodes():
    # A drive beside a wall (the disc grazes it) on a 0.4 m lattice: the full margin would take
    # a shift of 0.15 m, but it moves at most 0.3 of the step, 0.12 m (in 0.025 m steps).
    data = np.zeros((40, 40), np.int8)
    data[:, :20] = 100  # a wall up to x = 2.0
    recovery = BumpRecovery(OccupancyMap(data, RES, (0.0, 0.0, 0.0)), 0.2, 0.4)
    back, retry = recovery.points((2.2, 1.0), (2.2, 1.4))
    assert 2.2 < back[0] == retry[0] <= 2.2 + 0.3 * 0.4 + 1e-9
    assert (back[1], retry[1]) == (1.0, 1.4)
    assert recovery.points((2.0, 1.0), (2.0, 1.0)) == ((2.0, 1.0), (2.0, 1.0))


def test_a_bumped_drive_backs_off_retries_once_and_is_judged_where_the_retry_ends():
    task = StealthTask(load_scenario('map1'))
    flow = EpisodeFlow(task)
    token, _ = flow.begin_reset()
    flow.reset_done(token)
    assert flow.accept_action(3) is None
    token = flow.token
    assert flow.move_for_action(0.0) == go_to(3.0, 2.5)  # right from (2.5, 2.5)
    back, retry = BumpRecovery(
        task.scenario.map, task.scenario.robot_radius, task.scenario.step_distance
    ).points((2.5, 2.5), (3.0, 2.5))
    assert flow.move_ended(token, 1.0, BUMPED, 'bumped') == (go_to(*back), None)
    assert flow.move_ended(token, 4.0, DONE, 'backed off') == (go_to(*retry), None)
    # The retry's end is the step's, with its note: bumped again or not, no second recovery.
    assert flow.move_ended(token, 6.0, BUMPED, 'bumped again') == (
        None,
        'bumped again',
    )
    assert flow.counts.retried == 1 and 'backed off and retried' in flow.counts.describe()
    report = flow.finish_move(token, PlanarPose(*retry), PlanarPose(*retry), 6.0)
    assert report.step == 1 and report.state == task.state_of(3.0, 2.5)
    # A bump of the next step gets its own recovery; a stale answer none.
    assert flow.accept_action(2) is None
    assert flow.move_for_action(6.0) == go_to(2.5, 2.5)
    assert flow.move_ended(flow.token, 7.0, BUMPED, 'bumped')[0] is not None
    assert flow.move_ended(flow.token - 1, 7.0, BUMPED, 'stale') == (None, 'stale')
    assert flow.counts.retried == 2
