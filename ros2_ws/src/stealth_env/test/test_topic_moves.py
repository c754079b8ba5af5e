"""Moves over topics without ROS: stealth_sim's Simulator stands in for the robot, stepped the way
a robot on topics is (a command holds until the next one, decided on odometry up to a period
old), to show the controller meets the service path's tolerances, bumps, times out and keeps
its estimate as AMCL's map -> odom would."""

import math

import numpy as np
import pytest
from stealth_core.kinematics import Limits, relative, wrap_angle
from stealth_core.move_lattice import ACTIONS, MoveLattice
from stealth_core.moves import GRID_HEADINGS, MoveKind
from stealth_core.scenario import load_scenario
from stealth_env.topic_moves import (
    Command,
    ControllerConfig,
    Finished,
    MoveGoal,
    MoveOutcome,
    Odom,
    Pose,
    PoseTracker,
    TopicConfig,
    TopicMove,
    forward_clearance,
    go_to,
    hold_goal,
    pose_problem,
    route_home,
)
from stealth_sim.simulator import SimConfig, Simulator

TOLERANCE = ControllerConfig()


def action_move(action: int, distance: float) -> MoveGoal:
    """A relative grid move (0 up, 1 down, 2 left, 3 right) of `distance` from where the robot
    is: the controller's primitive, as the simulator's UP..RIGHT."""
    return MoveGoal(GRID_HEADINGS[MoveKind[ACTIONS[action][0].upper()]], distance)


LIMITS = Limits(0.5, 1.5, 1.0, 3.0)  # config/simulator.yaml's
PHYSICS_DT = 0.04  # config/simulator.yaml's


@pytest.fixture(scope='module')
def maze():
    return load_scenario('simple-maze')


class TopicRobot:
    """A Simulator driven as over topics: odometry once per ``period`` (published ``phase``
    physics steps into it), each command taking effect at the start of the next period."""

    def __init__(self, scenario, pose, period=0.2, phase=0, respond=True, seed=1, late=()):
        config = SimConfig(
            physics_dt=PHYSICS_DT, limits=LIMITS, robot_radius=scenario.robot_radius, seed=seed
        )
        self.sim = Simulator(scenario.map, config, Pose(*pose))
        self.steps_per_period = round(period / PHYSICS_DT)
        self.phase = phase
        self.respond = respond
        self.late = set(late)  # periods in which the new command arrives too late to act
        self.periods = 0
        self._acting = Command(0.0, 0.0)
        self.scenario = scenario

    def odom(self) -> Odom:
        state = self.sim.state
        return Odom(self.sim.time, self.sim.odometry_pose, state.linear, state.angular)

    def clearance(self) -> float:
        laser = self.sim.config.laser
        return forward_clearance(
            self.sim.scan(), laser.angle_min, laser.angle_increment, self.scenario.robot_radius
        )

    def period(self, command: Command):
        """Run one period under ``command`` (sent on the previous period's odometry); the
        odometry, estimate and clearance published ``phase`` steps into it."""
        sample = None
        if self.periods not in self.late:
            self._acting = command
        self.periods += 1
        for step in range(self.steps_per_period):
            if step == self.phase:
                sample = (self.odom(), self.sim.estimate, self.clearance())
            self.sim.step(*(self._acting if self.respond else (0.0, 0.0)))
        if sample is None:  # phase = steps per period: at its end (a simulator in lockstep)
            sample = (self.odom(), self.sim.estimate, self.clearance())
        return sample


def run_move(robot: TopicRobot, move: MoveGoal, config=None):
    """Drive a move to its end; (Finished, periods, the controller)."""
    odom, estimate, clearance = robot.period(Command(0.0, 0.0))
    controller = TopicMove(move, estimate, odom.t, config or TopicConfig(limits=LIMITS))
    period = robot.steps_per_period * PHYSICS_DT
    for periods in range(1, 2000):
        result = controller.update(odom.t, estimate, odom, clearance, period)
        if isinstance(result, Finished):
            return result, periods, controller
        odom, estimate, clearance = robot.period(result)
    raise AssertionError('the move never finished')


@pytest.mark.parametrize('period', [0.04, 0.2, 0.4])
@pytest.mark.parametrize('phase', [0, 'last'])
def test_grid_moves_end_within_the_service_paths_tolerances(maze, period, phase):
    """Every action from the start and on: done, at rest, heading within tolerance, the
    estimate within tolerance of the target along the drive (and not far past it)."""
    steps = round(period / PHYSICS_DT)
    robot = TopicRobot(maze, maze.start, period, phase=steps - 1 if phase == 'last' else 0)
    periods_used = []
    for action in (3, 3, 0, 2, 1, 3, 0):  # right, right, up, left, down, right, up: all free
        move = action_move(action, 0.5)
        result, periods, controller = run_move(robot, move)
        periods_used.append(periods)
        assert result.outcome == MoveOutcome.DONE, result
        assert result.moved
        assert robot.sim.state.linear == robot.sim.state.angular == 0.0
        # Where the estimate ended against the target the drive fixed from it: not short of
        # the tolerance, and not more than a few cm past (the drive steers, so the heading
        # only roughly holds).
        estimate = robot.sim.estimate
        target_x, target_y = controller._target
        past = (estimate.x - target_x) * math.cos(move.heading) + (
            estimate.y - target_y
        ) * math.sin(move.heading)
        assert -TOLERANCE.position_tolerance <= past <= 0.04, past
        assert abs(wrap_angle(estimate.yaw - move.heading)) < 0.1
    print(
        f'period {period} s, odometry at step {phase}: {np.mean(periods_used):.1f} periods '
        f'per move ({np.mean(periods_used) * period:.2f} s of robot time)'
    )


@pytest.mark.parametrize('period', [0.2, 0.4])
def test_in_lockstep_a_command_latency_of_0_ends_within_tolerance_in_fewer_periods(maze, period):
    """A simulator in lockstep (odometry at the end of a period, the command answering it
    acting from then on): told so (command_latency 0), the controller no longer brakes for a
    period of latency that is not there, so its moves end within tolerance in fewer periods
    (assuming the latency, a move at 0.4 s even times out: it oscillates)."""
    steps = round(period / PHYSICS_DT)
    used = {}
    for latency in (1.0, 0.0):
        robot = TopicRobot(maze, maze.start, period, phase=steps)
        config = TopicConfig(limits=LIMITS, command_latency=latency)
        used[latency] = 0
        for action in (3, 3, 0, 2, 1, 3, 0):
            move = action_move(action, 0.5)
            result, periods, controller = run_move(robot, move, config)
            used[latency] += periods
            if latency:
                continue
            assert result.outcome == MoveOutcome.DONE, result
            estimate = robot.sim.estimate
            target_x, target_y = controller._target
            past = (estimate.x - target_x) * math.cos(move.heading) + (
                estimate.y - target_y
            ) * math.sin(move.heading)
            assert -TOLERANCE.position_tolerance <= past <= 0.04, (latency, past)
            assert abs(wrap_angle(estimate.yaw - move.heading)) < 0.1
    assert used[0.0] < 0.85 * used[1.0], used


def test_moves_to_lattice_nodes_take_an_offset_robot_back_onto_the_lattice(maze):
    """go_to, as the environment sends every action: from a start 0.2 m off the lattice
    (a grid move carries such an offset along), each move ends on its target node."""
    from stealth_core.task import StealthTask

    task = StealthTask(maze)
    robot = TopicRobot(maze, maze.start, 0.2)
    run_move(robot, go_to(maze.start[0] + 0.2, maze.start[1] - 0.15))
    for action in (3, 0, 2, 1):  # right, up, left, down
        estimate = robot.sim.estimate
        target = task.move_target(estimate.x, estimate.y, action)
        result, _, _ = run_move(robot, go_to(*target))
        assert result.outcome == MoveOutcome.DONE, result
        estimate = robot.sim.estimate
        assert math.dist((estimate.x, estimate.y), target) < 0.05
        assert robot.sim.state.linear == robot.sim.state.angular == 0.0


def test_commands_that_come_late_at_speed_are_made_up_for(maze):
    """A loaded machine: the commands of two periods near the end of the drive act a period
    late, at full speed; the robot overshoots, then backs up into the tolerance."""
    robot = TopicRobot(maze, maze.start, period=0.2, late=(9, 10))
    move = action_move(0, 0.5)  # up: no turn, the drive starts at once
    result, _, controller = run_move(robot, move)
    assert result.outcome == MoveOutcome.DONE
    assert abs(controller._remaining(robot.sim.estimate)) <= TOLERANCE.position_tolerance


def test_a_move_into_a_wall_is_bumped_short_of_it(maze):
    robot = TopicRobot(maze, maze.start)
    left = action_move(2, 0.5)
    result, _, _ = run_move(robot, left)  # to the last node before the west wall
    assert result.outcome == MoveOutcome.DONE
    result, _, _ = run_move(robot, left)
    assert result.outcome == MoveOutcome.BUMPED and result.moved
    assert robot.sim.bumps == 0  # it stopped before touching
    assert robot.clearance() < TopicConfig().bump_distance + 0.03
    # Again into the same wall: bumped at once, at most creeping the scan's noise closer.
    here = robot.sim.ground_truth
    result, periods, _ = run_move(robot, left)
    assert result.outcome == MoveOutcome.BUMPED and periods <= 8
    assert math.dist(robot.sim.ground_truth[:2], here[:2]) < TopicConfig().bump_distance
    assert robot.sim.bumps == 0


def test_a_robot_that_moves_then_stalls_is_bumped(maze):
    x, y, yaw = maze.start
    robot = TopicRobot(maze, (x - 0.5, y, math.pi))  # facing the west wall
    blind = TopicConfig(limits=LIMITS)
    odom, estimate, _ = robot.period(Command(0.0, 0.0))
    controller = TopicMove(action_move(2, 0.5), estimate, odom.t, blind)
    for _ in range(500):
        result = controller.update(odom.t, estimate, odom, math.inf, 0.2)  # a scan sees nothing
        if isinstance(result, Finished):
            break
        odom, estimate, _ = robot.period(result)
    assert result.outcome == MoveOutcome.BUMPED and result.moved
    assert robot.sim.bumps >= 1  # the simulator's contact stopped it; no progress said so


def test_a_robot_that_ignores_cmd_vel_times_out_without_moving(maze):
    robot = TopicRobot(maze, maze.start, respond=False)
    result, _, controller = run_move(robot, action_move(3, 0.5))
    assert (result.outcome, result.moved) == (MoveOutcome.TIMED_OUT, False)
    # The service path's limit: 4 x (a quarter turn at 1.5 rad/s + 0.5 m at 0.5 m/s) + 5 s.
    assert controller.time_limit == pytest.approx(4 * (math.pi / 2 / 1.5 + 1.0) + 5, abs=0.05)
    assert result.message == f'the move did not finish within {controller.time_limit:.1f} s'
    assert controller.time_limit < result.duration < controller.time_limit + 0.5


def test_a_hold_stops_the_robot_and_ends_when_its_time_is_up(maze):
    robot = TopicRobot(maze, maze.start)
    run_move(robot, action_move(3, 0.5))
    before = robot.sim.ground_truth
    result, periods, _ = run_move(robot, hold_goal(3.0))
    assert (result.outcome, result.message) == (MoveOutcome.DONE, '')
    assert 3.0 <= result.duration < 3.0 + 0.2  # the first odometry past the time
    assert periods == 16  # 0.2 s odometry periods: 3 s after the start, then the Finished
    assert math.dist(robot.sim.ground_truth[:2], before[:2]) < 1e-3


def test_the_estimate_is_amcl_pose_carried_by_the_odometry(maze):
    """As AMCL's map -> odom: the tracker, fed odometry once a period and amcl_pose when the
    filter updates (stamped between odometry messages), follows the simulator's estimate."""
    robot = TopicRobot(maze, maze.start, period=0.2, phase=2)
    tracker = PoseTracker()
    sim = robot.sim
    tracker.add_estimate(sim.time, sim.estimate)  # before any odometry: waits for it
    assert tracker.estimate is None
    tracker.add_odom(Odom(sim.time, sim.odometry_pose))
    assert tracker.estimate == sim.estimate
    updates = sim.localisation_updates
    command = Command(0.3, 0.4)
    worst = 0.0
    for _ in range(40):
        for step in range(robot.steps_per_period):
            sim.step(*command)
            if sim.localisation_updates != updates:  # an amcl_pose, stamped now
                updates = sim.localisation_updates
                tracker.add_estimate(sim.time, sim.estimate)
            if step == robot.phase:
                state = sim.state
                tracker.add_odom(Odom(sim.time, sim.odometry_pose, state.linear, state.angular))
                if tracker.estimate is not None:
                    forward, left, turn = relative(sim.estimate, tracker.estimate)
                    worst = max(worst, math.hypot(forward, left))
                    assert abs(turn) < 0.01
        if robot.clearance() < 0.3:
            command = Command(0.0, 0.8)
        else:
            command = Command(0.3, 0.0)
    assert sim.localisation_updates > 5
    assert tracker.period == pytest.approx(0.2, abs=0.03)  # 0.12 s to the first period's
    assert worst < 0.005  # interpolating the odometry at the filter's stamps


def test_a_teleport_counts_only_odometry_after_it():
    tracker = PoseTracker()
    tracker.add_odom(Odom(1.0, Pose(5.0, 5.0, 0.0)))
    tracker.add_estimate(1.0, Pose(6.0, 6.0, 0.0))
    assert tracker.estimate == Pose(6.0, 6.0, 0.0)
    tracker.restart(Pose(1.0, 1.0, 0.5), after=1.0)
    tracker.add_odom(Odom(1.0, Pose(5.0, 5.0, 0.0)))  # from before the teleport, same stamp
    tracker.add_estimate(1.0, Pose(6.0, 6.0, 0.0))
    assert tracker.estimate is None
    tracker.add_odom(Odom(1.1, Pose(0.0, 0.0, 0.0)))  # the odometry restarted
    assert tracker.estimate == Pose(1.0, 1.0, 0.5)
    tracker.add_odom(Odom(1.2, Pose(1.0, 0.0, 0.0)))
    assert tracker.estimate.x == pytest.approx(1.0 + math.cos(0.5))


def test_bad_poses_are_named():
    assert pose_problem(1.0, 2.0, 0.0, 'map', 'map') == ''
    assert pose_problem(1.0, 2.0, 0.0, 'odom', 'map') == "frame 'odom', expected 'map'"
    assert 'not finite' in pose_problem(math.nan, 2.0, 0.0)
    assert 'not finite' in pose_problem(1.0, 2.0, math.inf, 'map', 'map')


def test_forward_clearance_is_where_the_disc_touches():
    ranges = [1.0, 0.5, 2.0, math.inf, 0.05]
    increment = math.pi / 2
    # bearings 0, 90, 180, 270 (-90), 360 (=0): 0.05 is under range_min, 1.0 straight ahead.
    assert forward_clearance(ranges, 0.0, increment, 0.2, range_min=0.1) == pytest.approx(0.8)
    # A point beside the path, 0.1 m off the line at 1 m: the disc touches it earlier.
    side = math.atan2(0.1, 1.0)
    expected = 1.0 - math.sqrt(0.2**2 - 0.1**2)
    assert forward_clearance([math.hypot(1.0, 0.1)], side, 0.0, 0.2) == pytest.approx(expected)
    assert forward_clearance([0.3], math.pi / 2, 0.0, 0.2) == math.inf  # beside, not ahead


def test_route_home_follows_the_lattice_and_ends_at_the_start_heading(maze):
    lattice = MoveLattice.from_scenario(maze)
    start = Pose(*maze.start)
    away = Pose(start.x + 2.0 + 0.03, start.y - 0.5 - 0.02, 1.0)  # a bit off a node
    moves = route_home(lattice, away, start)
    assert moves[-1] == MoveGoal(start.yaw, 0.0)
    x, y = away.x, away.y
    for move in moves[:-1]:
        x += move.distance * math.cos(move.heading)
        y += move.distance * math.sin(move.heading)
    assert (x, y) == pytest.approx(start[:2], abs=1e-9)
    assert len(moves) < 6  # straight runs merged
    assert route_home(lattice, Pose(-50.0, -50.0, 0.0), start) is None


def test_a_robot_drives_home_along_the_route(maze):
    lattice = MoveLattice.from_scenario(maze)
    start = Pose(*maze.start)
    robot = TopicRobot(maze, (start.x + 2.0, start.y - 0.5, 2.0), period=0.2)
    for move in route_home(lattice, robot.sim.estimate, start):
        result, _, _ = run_move(robot, move)
        assert result.outcome == MoveOutcome.DONE, (move, result)
    truth = robot.sim.ground_truth
    assert math.dist(truth[:2], start[:2]) < 0.15
    assert abs(wrap_angle(truth.yaw - start.yaw)) < 0.1


def drive_kinematic(move: MoveGoal, start: Pose, period=0.1):
    """A perfect diff-drive robot (estimate = odometry = truth) under the controller: its
    Finished and the poses it passed."""
    from stealth_core.kinematics import integrate, limited_velocity

    pose, linear, angular, t = start, 0.0, 0.0, 0.0
    controller = TopicMove(move, pose, t, TopicConfig(limits=LIMITS))
    poses = [pose]
    for _ in range(5000):
        result = controller.update(t, pose, Odom(t, pose, linear, angular), math.inf, period)
        if isinstance(result, Finished):
            return result, poses
        linear = limited_velocity(linear, result.linear, LIMITS.max_linear_speed,
                                  LIMITS.max_linear_accel, period)  # fmt: skip
        angular = limited_velocity(angular, result.angular, LIMITS.max_angular_speed,
                                   LIMITS.max_angular_accel, period)  # fmt: skip
        pose = integrate(pose, linear, angular, period)
        t += period
        poses.append(pose)
    raise AssertionError('the move never finished')


def test_a_drive_along_a_line_steers_back_onto_it_within_the_lookahead():
    """A path's leg from (0, 0) to (8, 0), the estimate 0.15 m to its left (a localisation
    update moved it): following the line, the robot is back on it (within 3 cm) 2 m on; aiming
    at the far end, as a move without a line does, it is still 0.1 m off there."""
    start = Pose(0.0, 0.15, 0.0)
    along, plain = (drive_kinematic(m, start) for m in (go_to(8.0, 0.0, (0.0, 0.0)),
                                                        go_to(8.0, 0.0)))  # fmt: skip
    for (result, poses), back_on in ((along, True), (plain, False)):
        assert result.outcome == MoveOutcome.DONE
        assert math.dist(poses[-1][:2], (8.0, 0.0)) <= 0.02
        beyond = [abs(p.y) for p in poses if p.x >= 2.0]
        assert (max(beyond) < 0.03) is back_on, max(beyond)
    assert go_to(1.0, 2.0).line_from is None  # the environment's moves: no line
