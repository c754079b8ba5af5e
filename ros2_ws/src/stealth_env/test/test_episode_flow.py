"""The environment node's episode state machine, without ROS."""

import dataclasses
import math

import pytest
from stealth_core.moves import MoveOutcome
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import load_scenario
from stealth_core.task import WAIT, EpisodeSummaryFields, StealthTask
from stealth_env.episode_flow import (
    SLOT_TOLERANCE,
    Endpoint,
    EpisodeFlow,
    EpisodePhase,
    FlowError,
    PlanarPose,
    agent_connected,
    progress_line,
)
from stealth_env.topic_moves import MoveGoal, go_to, hold_goal

DONE, BUMPED, TIMED_OUT = MoveOutcome.DONE, MoveOutcome.BUMPED, MoveOutcome.TIMED_OUT


@pytest.fixture(scope='module')
def map1():
    return load_scenario('map1')


def lit_and_dark_points(task):
    """A lattice point the lights detect the robot at, and one they do not."""
    lit = dark = None
    threshold = task.scenario.detection_threshold
    for node in task.lattice.valid_nodes():
        x, y = task.lattice.node_to_point(node)
        visibility = task.visibility(x, y)
        if lit is None and visibility >= threshold:
            lit = (x, y)
        if dark is None and visibility == 0.0 and task.distance_to_goal(x, y) > 2:
            dark = (x, y)
    return PlanarPose(*lit), PlanarPose(*dark)


def started(task, judge_on='true') -> EpisodeFlow:
    flow = EpisodeFlow(task, judge_on)
    token, _ = flow.begin_reset()
    flow.reset_done(token)
    return flow


def step(flow, action, estimate, truth=None, t=0.0):
    assert flow.accept_action(action) is None
    return flow.finish_move(flow.token, estimate, truth or estimate, t)


def test_an_episode_starts_at_the_scenario_start_with_its_state(map1):
    task = StealthTask(map1)
    flow = EpisodeFlow(task)
    assert flow.phase is EpisodePhase.WAITING and flow.ready_to_start()
    token, pose = flow.begin_reset()
    assert pose == map1.start and flow.phase is EpisodePhase.RESETTING
    assert flow.reset_done(token) == task.state_of(*map1.start[:2]) == (2.5, 2.5)
    assert (flow.phase, flow.episode, flow.steps) == (EpisodePhase.RUNNING, 0, 0)
    assert flow.counts.episodes_started == flow.counts.states_sent == 1


def test_a_failed_or_stale_reset_changes_nothing_it_should_not(map1):
    flow = EpisodeFlow(StealthTask(map1))
    token, _ = flow.begin_reset()
    assert not flow.reset_failed(token + 1)  # stale
    assert flow.reset_failed(token) and flow.phase is EpisodePhase.WAITING
    assert flow.reset_done(token) is None  # a late answer to the failed reset
    assert flow.counts.states_sent == 0
    token, _ = flow.begin_reset()
    assert flow.reset_done(token) is not None
    with pytest.raises(FlowError, match='cannot reset while'):
        flow.begin_reset()


def test_the_state_is_the_estimate_and_the_judgement_the_true_pose(map1):
    task = StealthTask(map1)
    lit, dark = lit_and_dark_points(task)
    flow = started(task)
    estimate = PlanarPose(lit.x + 0.26, lit.y + 0.01, 0.3)
    report = step(flow, 3, estimate, dark, t=4.5)
    assert report.state == task.state_of(estimate.x, estimate.y)
    assert report.judgement == task.judge(dark.x, dark.y, 4.5, 1)
    assert (report.judged, report.truth, report.estimate) == (dark, dark, estimate)
    assert (report.episode, report.step, report.action, report.t) == (0, 1, 3, 4.5)
    assert not report.terminal and report.summary is None and flow.phase is EpisodePhase.RUNNING

    # The original's way: everything on the estimate, which is in the light here.
    flow = started(task, judge_on='estimate')
    report = step(flow, 0, lit, dark)
    assert report.judged == lit and report.judgement.detected and report.terminal
    assert report.summary.outcome == EpisodeOutcome.DETECTED
    # EpisodeSummary's distances stay the true pose's.
    assert report.summary.final_distance_to_goal == pytest.approx(
        task.distance_to_goal(dark.x, dark.y)
    )
    assert report.judgement.distance_to_goal == pytest.approx(task.distance_to_goal(*lit[:2]))


def test_an_estimate_off_the_map_is_judged_at_the_nearest_point_of_it(map1):
    task = StealthTask(map1)
    flow = started(task, judge_on='estimate')
    x_min, y_min, _, _ = map1.map.bounds
    report = step(flow, 2, PlanarPose(x_min - 0.3, 2.5), PlanarPose(0.6, 2.5))
    on_node = task.judge(*task.move_start(x_min, 2.5), 0.0, 1, task.visibility(x_min, 2.5))
    assert report.judgement == on_node._replace(distance_to_goal=task.distance_to_goal(x_min, 2.5))
    assert report.state == task.state_of(x_min - 0.3, 2.5)


def test_the_goal_is_judged_at_the_lattice_node_not_the_drive_s_error(map1):
    """A drive that stops a few centimetres short of a node on the goal's radius arrives,
    and the goal pays the node's reward, as on the lattice: the continuous pose's few
    centimetres paid up to tens of reward where a route's light costs tenths."""
    task = StealthTask(map1, goal='easy')
    goal = map1.goals['easy']
    node = max(
        (
            task.lattice.node_to_point(n)
            for n in task.lattice.nodes_within(goal.x, goal.y, goal.radius)
        ),
        key=lambda point: task.distance_to_goal(*point),
    )  # the node within the radius farthest from the goal point
    outward = (node[0] - goal.x, node[1] - goal.y)
    scale = 0.04 / math.hypot(*outward)
    short = PlanarPose(node[0] + outward[0] * scale, node[1] + outward[1] * scale)
    assert task.distance_to_goal(short.x, short.y) > task.distance_to_goal(*node)
    report = step(started(task), 0, short)
    assert report.judgement.outcome is EpisodeOutcome.SUCCESS and report.terminal
    lattice = task.judge(*node, 0.0, 1, visibility=report.judgement.visibility)
    assert report.reward == pytest.approx(lattice.reward)
    assert report.judgement.distance_to_goal == pytest.approx(task.distance_to_goal(*short[:2]))
    assert report.summary.final_distance_to_goal == pytest.approx(
        report.judgement.distance_to_goal
    )


@pytest.mark.parametrize('action', [4, -1, True, 1.0, None])
def test_actions_out_of_range_are_dropped(map1, action):
    flow = started(StealthTask(map1))
    problem = flow.accept_action(action)
    assert problem.startswith(f'action {action!r} dropped: expected one of 0 up, 1 down')
    assert flow.phase is EpisodePhase.RUNNING
    assert (flow.counts.actions_received, flow.counts.actions_dropped) == (1, 1)


def test_actions_out_of_turn_are_dropped_not_queued(map1):
    task = StealthTask(map1)
    flow = EpisodeFlow(task)
    assert 'waiting for the simulator and an agent' in flow.accept_action(0)
    token, _ = flow.begin_reset()
    assert 'resetting the robot' in flow.accept_action(0)
    flow.reset_done(token)
    assert flow.accept_action(1) is None and flow.action == 1
    assert flow.accept_action(2) == (
        'action 2 dropped: the environment is executing a move (action 1, step 1)'
    )
    assert flow.action == 1 and flow.phase is EpisodePhase.MOVING
    assert flow.counts.moves == 1 and flow.counts.actions_dropped == 3


def test_answers_with_an_old_token_are_ignored(map1):
    flow = started(StealthTask(map1))
    assert flow.accept_action(0) is None
    old = flow.token
    pose = PlanarPose(2.5, 3.0)
    assert flow.finish_move(old - 1, pose, pose, 1.0) is None
    assert flow.abort(old - 1, 'late') is None
    assert flow.finish_move(old, pose, pose, 1.0) is not None
    assert flow.finish_move(old, pose, pose, 1.0) is None  # answered already


def test_goal_ends_the_episode_and_the_experiment_info_starts_the_next(map1):
    task = StealthTask(map1, goal='easy')
    flow = started(task)
    goal = PlanarPose(map1.goals['easy'].x, map1.goals['easy'].y)
    first = step(flow, 3, PlanarPose(3.0, 2.5))
    last = step(flow, 0, goal)
    assert last.terminal and last.judgement.outcome is EpisodeOutcome.SUCCESS
    summary = last.summary
    assert (summary.episode, summary.outcome, summary.steps, summary.goal) == (
        0,
        EpisodeOutcome.SUCCESS,
        2,
        'easy',
    )
    assert summary.total_reward == pytest.approx(first.reward + last.reward)
    assert summary.path_length == pytest.approx(0.5 + math.hypot(15.0 - 3.0, 9.5 - 2.5))
    assert flow.phase is EpisodePhase.ENDED and not flow.in_episode
    assert 'between episodes' in flow.accept_action(0)
    token, _ = flow.begin_reset()
    assert 'resetting the robot' in flow.experiment_info()
    flow.reset_done(token)
    assert 'ignored' in flow.experiment_info()  # mid-episode
    assert flow.episode == 1 and flow.steps == 0


def test_the_step_limit_times_out(map1):
    task = StealthTask(dataclasses.replace(map1, step_limit=3))
    flow = started(task)
    pose = PlanarPose(2.5, 2.5)
    reports = [step(flow, 0, pose) for _ in range(3)]
    assert [r.terminal for r in reports] == [False, False, True]
    assert reports[-1].summary.outcome == EpisodeOutcome.TIMEOUT
    assert flow.experiment_info() is None


def test_a_failed_move_aborts_with_a_terminal_copy_of_the_last_state(map1):
    flow = started(StealthTask(map1))
    report = step(flow, 0, PlanarPose(2.5, 3.0))
    assert flow.accept_action(1) is None
    aborted = flow.abort(flow.token, 'rejected')
    assert aborted.state == report.state and aborted.reason == 'rejected'
    assert (aborted.summary.outcome, aborted.summary.steps) == (EpisodeOutcome.ABORTED, 1)
    assert flow.phase is EpisodePhase.ENDED and flow.experiment_info() is None
    counts = flow.counts
    assert counts.states_sent == 3 and counts.outcomes == {'ABORTED': 1}
    assert counts.describe() == (
        '2 actions received (0 dropped, 2 executed), 3 states sent, 1 episodes started, '
        '1 ended (aborted 1)'
    )


def test_an_agent_that_goes_away_aborts_the_running_episode_only(map1):
    flow = started(StealthTask(map1))
    step(flow, 0, PlanarPose(2.5, 3.0))
    assert flow.accept_action(0) is None
    token = flow.token
    summary = flow.agent_lost()
    assert summary.outcome == EpisodeOutcome.ABORTED and flow.phase is EpisodePhase.WAITING
    pose = PlanarPose(2.5, 3.0)
    assert flow.finish_move(token, pose, pose, 1.0) is None  # the move's answer is stale
    assert flow.agent_lost() is None
    # After a finished episode there is nothing to abort.
    flow = started(StealthTask(dataclasses.replace(map1, step_limit=1)))
    assert step(flow, 0, pose).terminal
    assert flow.agent_lost() is None and flow.phase is EpisodePhase.WAITING
    assert flow.counts.outcomes == {'TIMEOUT': 1}


def test_judge_on_must_be_true_or_estimate(map1):
    with pytest.raises(ValueError, match="judge_on: expected one of true, estimate, got 'x'"):
        EpisodeFlow(StealthTask(map1), 'x')


@pytest.mark.parametrize(
    ('writers', 'readers', 'matched', 'connected'),
    [
        ([], [Endpoint('/agent')], 1, False),  # no agent publishes actions
        ([Endpoint('/agent')], [], 0, False),  # the agent does not read states (yet)
        ([Endpoint('/agent')], [Endpoint('/agent')], 0, False),  # not matched yet
        ([Endpoint('/agent')], [Endpoint('/agent')], 1, True),
        # A recorder's reader matched first must not pass for the agent's.
        ([Endpoint('/agent')], [Endpoint('/agent'), Endpoint('/recorder')], 1, False),
        ([Endpoint('/agent')], [Endpoint('/agent'), Endpoint('/recorder')], 2, True),
        # A reader that can never match (transient local) is not waited for.
        ([Endpoint('/agent')], [Endpoint('/agent'), Endpoint('/viewer', False)], 1, True),
        ([Endpoint('/agent')], [Endpoint('/other')], 1, False),
    ],
)
def test_agent_connected(writers, readers, matched, connected):
    assert agent_connected(writers, readers, matched) is connected


def test_a_true_pose_off_the_map_is_refused_and_changes_nothing(map1):
    flow = started(StealthTask(map1))
    assert flow.accept_action(0) is None
    with pytest.raises(ValueError, match=r'true pose \(25.000, 2.500\) lies outside the map'):
        flow.finish_move(flow.token, PlanarPose(2.5, 3.0), PlanarPose(25.0, 2.5), 1.0)
    assert (flow.phase, flow.steps, flow.counts.states_sent) == (EpisodePhase.MOVING, 0, 1)
    assert flow.abort(flow.token, 'wrong map').summary.steps == 0


def test_an_episode_the_agent_left_before_acting_is_withdrawn(map1):
    flow = started(StealthTask(map1))
    assert flow.agent_lost() is None and flow.phase is EpisodePhase.WAITING
    counts = flow.counts
    assert (flow.episode, counts.episodes_started, counts.episodes_withdrawn) == (-1, 0, 1)
    token, _ = flow.begin_reset()
    flow.reset_done(token)
    assert flow.episode == 0  # the number is used again
    assert counts.describe().endswith(
        '1 episodes started, 0 ended, 1 withdrawn before a first action'
    )


def test_a_restarted_robot_aborts_the_episode_whatever_it_waited_for(map1):
    task = StealthTask(map1)
    # Waiting for the agent's action (no move in flight): still aborted, the robot moved away.
    flow = started(task)
    report = step(flow, 0, PlanarPose(2.5, 3.0))
    aborted = flow.interrupt('the simulator was restarted')
    assert aborted.state == report.state and aborted.reason == 'the simulator was restarted'
    assert (aborted.summary.episode, aborted.summary.outcome) == (0, EpisodeOutcome.ABORTED)
    assert flow.phase is EpisodePhase.ENDED and flow.experiment_info() is None
    # During a move: its answer, if it ever comes, is stale.
    token, _ = flow.begin_reset()
    flow.reset_done(token)
    assert flow.accept_action(1) is None
    token = flow.token
    assert flow.interrupt('again').summary.episode == 1
    pose = PlanarPose(2.5, 3.0)
    assert flow.finish_move(token, pose, pose, 1.0) is None
    # A reset in flight goes back to waiting; with no episode there is nothing to abort.
    token, _ = flow.begin_reset()
    assert flow.interrupt('during the reset') is None and flow.phase is EpisodePhase.WAITING
    assert flow.reset_done(token) is None
    assert flow.interrupt('idle') is None
    assert flow.counts.outcomes == {'ABORTED': 2}


def test_a_continued_run_numbers_its_episodes_from_first_episode(map1):
    flow = EpisodeFlow(StealthTask(map1), first_episode=17)
    token, _ = flow.begin_reset()
    flow.reset_done(token)
    assert flow.episode == 17
    assert flow.interrupt('x').summary.episode == 17


# --- the episode's clock where lights move ------------------------------------------------------


@pytest.fixture(scope='module')
def moving():
    return StealthTask(load_scenario('simple-maze-moving'))


def test_an_episode_starts_at_phase_zero_whatever_the_simulators_clock_says(moving):
    flow = EpisodeFlow(moving)
    token, _ = flow.begin_reset()
    bin_seconds = moving.timing.bin_seconds
    state = flow.reset_done(token, 1000.0 + 5 * bin_seconds + 0.3)  # mid-bin of phase 5
    assert state[2] == 0.0 and flow.episode_time(1000.0 + 5 * bin_seconds + 0.3) == 0.0
    x, y = moving.scenario.start[:2]
    report = step(flow, WAIT, PlanarPose(x, y), t=flow.origin + moving.step_seconds)
    assert report.state[2] == moving.timing.bin_of(moving.step_seconds)
    assert report.t == flow.origin + moving.step_seconds  # stamps stay the simulator's


def test_a_step_is_padded_to_its_slot_and_a_late_one_counted(moving):
    flow = EpisodeFlow(moving)
    token, _ = flow.begin_reset()
    flow.reset_done(token, 50.0)
    slot = moving.step_seconds
    assert flow.step_time_left(51.0) == 0.0  # no move under way
    x, y = moving.scenario.start[:2]
    assert flow.accept_action(WAIT) is None
    assert flow.step_time_left(51.2) == pytest.approx(50.0 + slot - 51.2)
    flow.finish_move(flow.token, PlanarPose(x, y), PlanarPose(x, y), 50.0 + slot)
    assert flow.counts.off_schedule == 0
    # The next slot ends at 2 slots whatever the last step took: 0.5 s late is the same phase...
    assert flow.accept_action(WAIT) is None
    assert flow.step_time_left(50.0 + 2 * slot + 0.5) == 0.0
    flow.finish_move(flow.token, PlanarPose(x, y), PlanarPose(x, y), 50.0 + 2 * slot + 0.5)
    assert flow.counts.off_schedule == 0 and flow.state[2] == moving.timing.bin_of(2 * slot)
    # ... a phase bin late is not, and is counted.
    assert flow.accept_action(WAIT) is None
    late = 50.0 + 3 * slot + moving.timing.bin_seconds
    flow.finish_move(flow.token, PlanarPose(x, y), PlanarPose(x, y), late)
    assert flow.counts.off_schedule == 1
    assert 'steps ended past their time slot' in flow.counts.describe()


def test_without_moving_lights_nothing_is_padded(map1):
    flow = started(StealthTask(map1))
    assert flow.accept_action(0) is None
    assert flow.step_time_left(0.0) == 0.0


def test_a_first_state_left_unanswered_ends_aborted_before_its_first_step(map1):
    flow = started(StealthTask(map1))
    first, token = flow.state, flow.token
    aborted = flow.unanswered('no first action')
    assert aborted.state == first and aborted.reason == 'no first action'
    assert (aborted.summary.outcome, aborted.summary.steps) == (EpisodeOutcome.ABORTED, 0)
    assert flow.phase is EpisodePhase.ENDED and flow.experiment_info() is None
    assert flow.accept_action(0) is not None  # the late answer is dropped, not executed
    assert flow.token != token and flow.counts.states_sent == 2
    # Only an episode still waiting for its first action is ended that way.
    assert flow.unanswered('again') is None
    flow = started(StealthTask(map1))
    step(flow, 0, PlanarPose(2.5, 3.0))
    assert flow.unanswered('after a step') is None and flow.phase is EpisodePhase.RUNNING
    assert flow.accept_action(0) is None
    assert flow.unanswered('moving') is None and flow.phase is EpisodePhase.MOVING


# --- the move of an action, and slot padding ----------------------------------------------------


def test_an_action_is_a_drive_to_its_lattice_node(map1):
    task = StealthTask(map1)
    flow = started(task)
    with pytest.raises(FlowError):
        flow.move_for_action(0.0)  # no action accepted
    for action in range(4):
        flow = started(task)
        assert flow.accept_action(action) is None
        target = task.move_target(*map1.start[:2], action)
        assert flow.move_for_action(0.0) == go_to(*target)
    assert flow.move_for_action(0.0).target == (3.0, 2.5)  # right from (2.5, 2.5)


@pytest.fixture(scope='module')
def exposure_task():
    return StealthTask(load_scenario('simple-maze-exposure'))


def test_where_lights_weigh_exposure_a_turn_or_a_blocked_move_turns_in_place(exposure_task):
    task = exposure_task
    turn_left, turn_right = (
        task.action_names.index('turn_left'),
        task.action_names.index('turn_right'),
    )
    flow = started(task)  # facing west (heading 2)
    assert flow.accept_action(turn_left) is None
    assert flow.move_for_action(0.0) == MoveGoal(1.5 * math.pi)  # left of west: south
    flow = started(task)
    assert flow.accept_action(turn_right) is None
    assert flow.move_for_action(0.0) == MoveGoal(math.pi / 2)  # right of west: north
    # Down from (1.0, 1.0) meets the map's edge: no drive, the robot keeps its heading (a turn
    # in place to where it faces, west).
    flow = started(task)
    flow.state = task.state_of(1.0, 1.0, 0.0, math.pi)
    assert flow.accept_action(1) is None
    assert flow.move_for_action(0.0) == MoveGoal(math.pi)
    # An open move is still a drive to its node.
    flow = started(task)
    assert flow.accept_action(3) is None
    assert flow.move_for_action(0.0) == go_to(3.5, 1.5)


def test_a_wait_holds_for_the_rest_of_its_slot_or_a_whole_one(moving):
    flow = EpisodeFlow(moving)
    token, _ = flow.begin_reset()
    flow.reset_done(token, 50.0)
    slot = moving.step_seconds
    assert flow.accept_action(WAIT) is None
    assert flow.move_for_action(50.4).hold == pytest.approx(slot - 0.4)
    assert flow.move_for_action(50.0 + slot) == hold_goal(slot)  # nothing left: a whole slot
    assert flow.move_for_action(50.0 + slot - SLOT_TOLERANCE / 2) == hold_goal(slot)
    assert flow.hold_move(0.25) == hold_goal(0.25)


def test_a_move_that_ends_early_is_padded_and_judged_with_its_own_note(moving):
    flow = EpisodeFlow(moving)
    token, _ = flow.begin_reset()
    flow.reset_done(token, 50.0)
    slot = moving.step_seconds
    assert flow.accept_action(3) is None
    token = flow.token
    pad, note = flow.move_ended(token, 51.0, BUMPED, 'bumped')
    assert pad == hold_goal(slot - 1.0) and note is None
    # The hold ends on the slot's end: the step is judged with the move's note ...
    assert flow.move_ended(token, 50.0 + slot, DONE, 'held') == (None, 'bumped')
    # ... unless the hold itself went wrong.
    flow.move_ended(token, 51.0, BUMPED, 'bumped')
    assert flow.move_ended(token, 50.0 + slot, TIMED_OUT, 'hold timed out') == (
        None,
        'hold timed out',
    )
    # A move that ends on its slot (or within the tolerance) is judged at once.
    assert flow.move_ended(token, 50.0 + slot - SLOT_TOLERANCE / 2, DONE, 'done') == (
        None,
        'done',
    )
    # So is a stale one (another token): nothing pads it.
    assert flow.move_ended(token - 1, 51.0, DONE, 'stale') == (None, 'stale')
    report = flow.finish_move(token, PlanarPose(2.0, 1.5), PlanarPose(2.0, 1.5), 50.0 + slot)
    assert report.step == 1 and flow.counts.off_schedule == 0


def test_without_moving_lights_a_move_is_judged_when_it_ends(map1):
    flow = started(StealthTask(map1))
    assert flow.accept_action(0) is None
    assert flow.move_ended(flow.token, 0.1, DONE, 'done') == (None, 'done')


def test_the_progress_line_sums_up_its_episodes():
    def summary(episode, outcome, total_reward, steps):
        return EpisodeSummaryFields(episode, outcome, steps, total_reward, 0.0, 0.0, 0.0, 0.0, '')

    window = [
        summary(4, EpisodeOutcome.SUCCESS, 10.0, 20),
        summary(5, EpisodeOutcome.DETECTED, -5.0, 7),
        summary(6, EpisodeOutcome.SUCCESS, 4.0, 30),
    ]
    assert progress_line(window) == (
        'episodes 4-6: detected 1, success 2; mean return 3.00, mean steps 19.0'
    )
