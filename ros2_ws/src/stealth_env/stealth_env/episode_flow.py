"""The environment node's episode state machine: pure Python, no rclpy.

The node only turns messages and service answers into calls of :class:`EpisodeFlow` and what
the calls return into messages; every decision of the rl_msgs protocol (rl-texplore-ros-pkg's
rl_env) is made here, on top of the shared judging core ``stealth_core.task.StealthTask``::

    flow = EpisodeFlow(task, judge_on='true')
    token, pose = flow.begin_reset()             # WAITING/ENDED -> RESETTING: call sim/reset
    state = flow.reset_done(token)               # -> RUNNING: publish the first state (reward 0)
    problem = flow.accept_action(action)         # None: RUNNING -> MOVING
    move = flow.move_for_action(t)               # the move to run (sim/execute_move or topics)
    then, note = flow.move_ended(token, t, outcome, note)  # a move to run first, or judge:
    report = flow.finish_move(token, estimate, truth, t)   # -> RUNNING or ENDED
    aborted = flow.abort(token, reason)          # the move failed: -> ENDED (ABORTED)
    problem = flow.experiment_info()             # None: the agent closed the episode, reset

Phases (``EpisodePhase``): WAITING (for the simulator and an agent) -> RESETTING -> RUNNING <->
MOVING -> ENDED -> RESETTING ... Every request sent to the simulator carries the ``token``
current when it was sent; an answer with an older token (a move that timed out and was aborted,
a reset overtaken by the agent leaving) is stale and changes nothing.

Decisions:

- **States**: ``task.state_of`` of the localisation estimate after the move, at the move's end
  time (the phase, where lights move) and with its yaw (the heading, where lights are weighed
  by exposure). The first state of an episode is that of the reset pose
  at the reset's time (the simulator re-initialises localisation there, as AMCL does on
  /initialpose), with reward 0 and terminal false.
- **The episode's clock** (where lights move): the lights' time is the simulated time since the
  episode's reset, so an episode starts at phase 0 with the lights where the scenario puts them,
  as in the Gymnasium env. Each step has a *slot* of ``step_seconds``: a move that ends more
  than ``SLOT_TOLERANCE`` early is padded with a hold to the slot's end (``move_ended``; the
  step is judged when the hold ends, with the move's own outcome unless the hold failed), so a
  step ends on its slot's end and the phase advances one step's worth per step, as the
  time-expanded model assumes; a move slower than its slot (any lattice move fits 3 s at
  simulator.yaml's limits; at the node's defaults a half turn and a drive take 4.3 s, and a
  bumped drive's recovery longer) ends late, the next step's slot stays where it was, and a
  step whose phase is not its slot's is counted (``off_schedule``).
- **Steps** are judged on ``task.step_visibility``: the straight way from the pose the previous
  step was judged at (the start, after a reset) to the judged pose, sampled in space and in
  the simulator's time from the previous step's end to this one's, so a beam crossed on the way
  or one sweeping over a waiting robot is seen. Where lights are weighed by exposure, the
  robot's heading is the judged pose's yaw: it turns from the previous judged yaw to the new one
  at the departure, then drives facing the new one (``StealthTask.step_visibility``).
- **Judging**: ``judge_on='true'`` judges visibility and detection on the true pose (the
  lights see the real robot); ``'estimate'`` on the estimate, as the original did. An
  estimate off the map (possible only with very poor localisation) is judged at the nearest
  point of the map. The goal and the reward's distances are judged at the lattice node the
  judged pose stands at (``StealthTask.move_start``), as the lattice model judges them. On
  the continuous pose the few centimetres a drive stops short of its node decided whether a
  node on the goal's radius arrived, and the goal's reward grows by 100 per metre towards the
  goal point: that paid tens where the light of a route costs tenths, and the learners chased
  the controller's error instead of the dark. The judgement's ``distance_to_goal`` stays the
  judged pose's; EpisodeSummary's path length and final distance to the goal are always the
  true pose's.
- **Moves** (``move_for_action``): every action is a drive to a lattice node
  (``StealthTask.move_target``, ``topic_moves.go_to``), so the robot stays on the lattice the
  agent's states and the planners assume. A wait (where lights move) stands still for the rest
  of the step's slot, or a whole slot when nothing is left of it (a wait that comes after a late
  step still takes time). Where lights are weighed by exposure, a turn (and a move the map
  blocks, which turns nothing on the lattice) turns in place to its lattice heading.
- **Bumps** (``move_ended``): a drive between two lattice nodes that ended BUMPED backs off to
  its start node and is retried once on its lattice line moved off the walls
  (:mod:`stealth_core.bump_recovery`); the step is judged where the retry ends, with its outcome.
- **Actions** are accepted only while the flow waits for one (RUNNING) and only when they are
  those of ``task.action_names`` (0-3 the moves, then 4 wait where lights move, then turn left
  and turn right where the scenario has turn actions); anything else is dropped with a
  reason for the log, never queued: an action that arrives during a move or after a terminal
  state would otherwise be applied to a state the agent never saw.
- **Aborts**: a move the simulator rejects, fails or does not answer in time ends the episode
  as ABORTED. The agent still gets a terminal RLStateReward (its last state again, reward 0):
  rl_msgs has no other way to end an episode, and without it a lockstep agent would wait
  forever. An agent that goes away ends the running episode as ABORTED too (nothing is sent:
  there is nobody to send it to); the next agent gets a fresh episode. An episode the agent
  left before its first action (an agent that stops after its last episode) is withdrawn: no
  summary, and its number is used again.
- **Counts**: every action received and every state handed out is counted, so the node can
  log totals that prove nothing was lost.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
import dataclasses
import enum
import math
from typing import NamedTuple

from stealth_core.bump_recovery import BumpRecovery
from stealth_core.exposure import heading_angle
from stealth_core.moves import MoveOutcome
from stealth_core.reward import EpisodeOutcome
from stealth_core.task import (
    WAIT,
    EpisodeStats,
    EpisodeSummaryFields,
    StealthTask,
    StepJudgement,
)

from stealth_env.topic_moves import MoveGoal, go_to, hold_goal

JUDGE_ON = ('true', 'estimate')
_ON_MAP_MARGIN = 1e-6  # m: how far inside the map an off-map estimate is moved to be judged
SLOT_TOLERANCE = 1e-3  # s: a move ending this close to its step's slot end is not padded


class FlowError(RuntimeError):
    """A call that the current phase does not allow (a bug in the caller, not bad input)."""


class EpisodePhase(enum.Enum):
    WAITING = 'waiting for the simulator and an agent'
    RESETTING = 'resetting the robot'
    RUNNING = "waiting for the agent's action"
    MOVING = 'executing a move'
    ENDED = "the episode is over, waiting for the agent's RLExperimentInfo"


class PlanarPose(NamedTuple):
    x: float  # m, map frame
    y: float
    yaw: float = 0.0  # rad


class StepReport(NamedTuple):
    """One executed action: what to publish (RLStateReward, StepInfo, maybe EpisodeSummary)."""

    episode: int
    step: int  # action index within the episode, from 1
    action: int
    state: tuple[float, ...]
    judgement: StepJudgement
    estimate: PlanarPose
    truth: PlanarPose
    judged: PlanarPose  # the pose the judgement is about (truth or estimate)
    t: float  # simulated time of the judgement (s)
    summary: EpisodeSummaryFields | None  # when this step ended the episode

    @property
    def reward(self) -> float:
        return self.judgement.reward

    @property
    def terminal(self) -> bool:
        return self.judgement.terminal


class Aborted(NamedTuple):
    """An episode ended from outside: the terminal state to send and the summary."""

    state: tuple[float, ...]
    summary: EpisodeSummaryFields
    reason: str


@dataclasses.dataclass
class Counts:
    """Totals since the node started."""

    actions_received: int = 0
    actions_dropped: int = 0
    moves: int = 0  # actions executed (sent to the simulator)
    states_sent: int = 0  # RLStateReward handed out: first states, step results, abort states
    episodes_started: int = 0
    episodes_withdrawn: int = 0  # first state sent, but the agent went away before acting
    off_schedule: int = 0  # steps that ended in another phase than their slot's (too slow)
    retried: int = 0  # bumped drives backed off and retried (bump_recovery)
    outcomes: Counter = dataclasses.field(default_factory=Counter)  # by EpisodeOutcome name

    def describe(self) -> str:
        ended = sum(self.outcomes.values())
        names = ', '.join(
            f'{o.name.lower()} {self.outcomes[o.name]}'
            for o in EpisodeOutcome
            if self.outcomes[o.name]
        )
        withdrawn = self.episodes_withdrawn
        return (
            f'{self.actions_received} actions received ({self.actions_dropped} dropped, '
            f'{self.moves} executed), {self.states_sent} states sent, '
            f'{self.episodes_started} episodes started, {ended} ended'
            + (f' ({names})' if names else '')
            + (f', {withdrawn} withdrawn before a first action' if withdrawn else '')
            + (
                f', {self.off_schedule} steps ended past their time slot by a phase bin or more'
                if self.off_schedule
                else ''
            )
            + (f', {self.retried} bumped moves backed off and retried' if self.retried else '')
        )


def progress_line(window: list[EpisodeSummaryFields]) -> str:
    """The log line about the episodes of `window` (the node logs one every ``log_every``)."""
    outcomes = Counter(EpisodeOutcome(s.outcome).name.lower() for s in window)
    names = ', '.join(f'{name} {outcomes[name]}' for name in sorted(outcomes))
    mean_return = sum(s.total_reward for s in window) / len(window)
    mean_steps = sum(s.steps for s in window) / len(window)
    return (
        f'episodes {window[0].episode}-{window[-1].episode}: {names}; mean return '
        f'{mean_return:.2f}, mean steps {mean_steps:.1f}'
    )


class EpisodeFlow:
    """Episodes of one task, driven by the node's messages and the simulator's answers."""

    def __init__(self, task: StealthTask, judge_on: str = 'true', first_episode: int = 0):
        if judge_on not in JUDGE_ON:
            raise ValueError(f'judge_on: expected one of {", ".join(JUDGE_ON)}, got {judge_on!r}')
        self.task = task
        self.judge_on = judge_on
        self.phase = EpisodePhase.WAITING
        self.token = 0
        self.counts = Counts()
        # Number of the current (or last) episode; the first is first_episode (0 unless a
        # restarted or resumed run continues its numbering).
        self.episode = first_episode - 1
        self.steps = 0  # actions executed in the current episode
        self.action: int | None = None  # the action being executed
        self.state: tuple[float, ...] | None = None  # the last state sent
        self.stats: EpisodeStats | None = None
        self.estimate: PlanarPose | None = None  # the robot's last pose estimate
        self._judged_at: tuple[float, ...] | None = None  # x, y, t, yaw of the last judging
        self.origin = 0.0  # simulated time of the episode's reset: its clock's zero (s)
        # (token, note) of a move that ended before its step's slot while the hold padding it runs
        self._padded: tuple[int, object] | None = None
        # The running step's drive between lattice nodes (start, target), when it is one, and
        # (token, retry move or None once it runs) while its bump recovery runs.
        self._drive: tuple[tuple[float, float], tuple[float, float]] | None = None
        self._recovery: tuple[int, MoveGoal | None] | None = None
        self._bump_recovery: BumpRecovery | None = None  # built at the first bump

    # --- episodes -------------------------------------------------------------------------------

    @property
    def in_episode(self) -> bool:
        """True while an episode runs (its last state was not terminal)."""
        return self.phase in (EpisodePhase.RUNNING, EpisodePhase.MOVING)

    def ready_to_start(self) -> bool:
        return self.phase is EpisodePhase.WAITING

    def begin_reset(self) -> tuple[int, tuple[float, float, float]]:
        """Start the next episode: (token, start pose (x, y, yaw)) to reset the robot to."""
        if self.phase not in (EpisodePhase.WAITING, EpisodePhase.ENDED):
            raise FlowError(f'cannot reset while {self.phase.value}')
        self.phase = EpisodePhase.RESETTING
        self.token += 1
        return self.token, tuple(float(v) for v in self.task.scenario.start)

    def reset_done(self, token: int, t: float = 0.0) -> tuple[float, ...] | None:
        """The robot is at the start at simulated time t (s): the episode's first state, or None
        when stale."""
        if token != self.token or self.phase is not EpisodePhase.RESETTING:
            return None
        x, y, yaw = self.task.scenario.start
        self.episode += 1
        self.steps = 0
        self.origin = float(t)
        self.stats = self.task.start_episode(x, y, self.episode)
        self.state = self.task.state_of(x, y, 0.0, yaw)
        self.estimate = PlanarPose(x, y, yaw)
        self._judged_at = (x, y, 0.0, yaw)
        self.phase = EpisodePhase.RUNNING
        self.counts.episodes_started += 1
        self.counts.states_sent += 1
        return self.state

    def reset_failed(self, token: int) -> bool:
        """The reset did not happen: back to WAITING (True), unless the answer is stale."""
        if token != self.token or self.phase is not EpisodePhase.RESETTING:
            return False
        self.phase = EpisodePhase.WAITING
        return True

    def experiment_info(self) -> str | None:
        """The agent's RLExperimentInfo: None when it closes the episode (reset next), else why
        it is ignored."""
        if self.phase is EpisodePhase.ENDED:
            return None
        return (
            f'RLExperimentInfo ignored: it closes an episode, but the environment is {self._now}'
        )

    def agent_lost(self) -> EpisodeSummaryFields | None:
        """No agent any more: back to WAITING; the summary of the episode this cut short.

        An episode the agent never acted in (it stopped after its last episode, say) is
        withdrawn instead: no summary, and the next episode takes its number.
        """
        if self.phase is EpisodePhase.WAITING:
            return None
        summary = None
        if self.phase is EpisodePhase.RUNNING and self.steps == 0:
            self.episode -= 1
            self.counts.episodes_started -= 1
            self.counts.episodes_withdrawn += 1
        elif self.in_episode:
            summary = self._end(EpisodeOutcome.ABORTED)
        self.phase = EpisodePhase.WAITING
        self.token += 1  # an answer still on its way is stale now
        return summary

    # --- steps ----------------------------------------------------------------------------------

    def accept_action(self, action) -> str | None:
        """Count an RLAction; None when it is to be executed (-> MOVING), else why it is
        dropped."""
        self.counts.actions_received += 1
        problem = self._action_problem(action)
        if problem is not None:
            self.counts.actions_dropped += 1
            return problem
        self.phase = EpisodePhase.MOVING
        self.token += 1
        self.action = int(action)
        self.counts.moves += 1
        return None

    def _action_problem(self, action) -> str | None:
        if (
            isinstance(action, bool)
            or not isinstance(action, int)
            or not (0 <= action < self.task.num_actions)
        ):
            names = ', '.join(f'{i} {name}' for i, name in enumerate(self.task.action_names))
            return f'action {action!r} dropped: expected one of {names}'
        if self.phase is not EpisodePhase.RUNNING:
            return f'action {action} dropped: the environment is {self._now}'
        return None

    @property
    def _now(self) -> str:
        if self.phase is EpisodePhase.MOVING:
            return f'{self.phase.value} (action {self.action}, step {self.steps + 1})'
        if self.phase is EpisodePhase.ENDED:
            return f'between episodes ({self.phase.value})'
        return self.phase.value

    def finish_move(
        self, token: int, estimate: PlanarPose, truth: PlanarPose, t: float
    ) -> StepReport | None:
        """The move ended with these poses at simulated time t: judge it (None when stale).

        ValueError (and nothing changes) for a true pose off the scenario's map: the simulator
        runs another map than the scenario's, and the caller should abort the episode.
        """
        if token != self.token or self.phase is not EpisodePhase.MOVING:
            return None
        task = self.task
        action = self.action
        judged = estimate if self.judge_on == 'estimate' else truth
        if not task.scenario.map.contains_point(truth.x, truth.y):
            raise ValueError(
                f'the true pose ({truth.x:.3f}, {truth.y:.3f}) lies outside the map of scenario '
                f'{task.scenario.name!r} ({task.scenario.map_path})'
            )
        x, y = self._on_map(judged.x, judged.y)
        x0, y0, t0, yaw0 = self._judged_at
        te = self.episode_time(t)
        visibility = task.step_visibility(x0, y0, min(t0, te), x, y, te, yaw0, judged.yaw)
        node_x, node_y = task.move_start(x, y)  # the lattice node the robot stands at
        judgement = task.judge(node_x, node_y, te, self.steps + 1, visibility=visibility)
        judgement = judgement._replace(distance_to_goal=task.distance_to_goal(x, y))
        self._judged_at = (x, y, te, judged.yaw)
        timing = task.timing
        if timing is not None and timing.bin_of(te) != timing.bin_of(self._slot_end()):
            self.counts.off_schedule += 1
        self.estimate = PlanarPose(*estimate)
        self.steps += 1
        counted = judgement
        if judged is not truth:  # EpisodeSummary's distances are the true pose's
            counted = judgement._replace(distance_to_goal=task.distance_to_goal(truth.x, truth.y))
        self.stats.add(truth.x, truth.y, counted)
        self.state = task.state_of(estimate.x, estimate.y, te, estimate.yaw)
        self.counts.states_sent += 1
        summary = None
        if judgement.terminal:
            summary = self._end(judgement.outcome)
        else:
            self.phase = EpisodePhase.RUNNING
        return StepReport(
            self.episode,
            self.steps,
            action,
            self.state,
            judgement,
            PlanarPose(*estimate),
            PlanarPose(*truth),
            PlanarPose(*judged),
            float(t),
            summary,
        )

    def move_for_action(self, t: float) -> MoveGoal:
        """The move that executes the action just accepted, decided at simulated time t (s):
        a hold for a wait, a turn in place, or a drive to a lattice node."""
        if self.phase is not EpisodePhase.MOVING:
            raise FlowError(f'no action to execute while {self.phase.value}')
        task, state, action = self.task, self.state, self.action
        self._drive = None
        if action == WAIT and task.action_names[action] == 'wait':
            return self.hold_move(self.step_time_left(t))
        x, y = task.move_target(*state[:2], action) if action < WAIT else state[:2]
        blocked = task.lattice.point_to_node(x, y) == task.lattice.point_to_node(*state[:2])
        if task.footprint is not None and blocked:
            return MoveGoal(
                heading_angle(task.heading_after(task.heading_in(state), action, False))
            )
        if not blocked:
            self._drive = (task.move_start(*state[:2]), (x, y))
        return go_to(x, y)

    def hold_move(self, seconds: float) -> MoveGoal:
        """Standing still for `seconds`, or a whole step's slot when nothing is left of it."""
        if seconds < SLOT_TOLERANCE:
            seconds = self.task.step_seconds
        return hold_goal(seconds)

    def move_ended(self, token: int, t: float, outcome: int, note):
        """A move (or the hold padding it) ended at simulated time t (s) with ``outcome`` (an
        ExecuteMove outcome, ``stealth_core.moves.MoveOutcome``): (move, None) when another is to
        run first under the same token (then call again): the back-off and then the retry of a
        drive that bumped, a hold while its step's slot has time left; else (None, note) to judge
        the step now. `note` is what to report about the move (the node's outcome and message): a
        padded move's own note, unless the hold after it was not DONE."""
        padded, self._padded = self._padded, None
        if padded is not None and padded[0] == token:  # the hold after the move: judge it now
            return None, padded[1] if outcome == MoveOutcome.DONE else note
        recovery = self._recovery_move(token, outcome == MoveOutcome.BUMPED)
        if recovery is not None:
            return recovery, None
        left = self.step_time_left(t) if token == self.token else 0.0
        if left >= SLOT_TOLERANCE:
            self._padded = (token, note)  # early: stand still to the slot's end
            return self.hold_move(left), None
        return None, note

    def _recovery_move(self, token: int, bumped: bool) -> MoveGoal | None:
        """The next move of a bumped drive's recovery (the back-off, then the retry), or None
        when the step is to be judged (no bump, not a drive, or the retry has run)."""
        recovery = self._recovery
        if recovery is not None and recovery[0] == token:
            self._recovery = (token, None)
            return recovery[1]  # the back-off ended: the retry (None: the retry ended)
        if not bumped or token != self.token or self._drive is None:
            return None
        if self._bump_recovery is None:
            scenario = self.task.scenario
            self._bump_recovery = BumpRecovery(
                scenario.map, scenario.robot_radius, scenario.step_distance
            )
        back, retry = self._bump_recovery.points(*self._drive)
        self._recovery = (token, go_to(*retry))
        self.counts.retried += 1
        return go_to(*back)

    def episode_time(self, t: float) -> float:
        """The episode's clock at simulated time t (s): the lights' time."""
        return float(t) - self.origin

    def step_time_left(self, t: float) -> float:
        """Seconds from simulated time t to the end of the running step's slot: what a move
        that ended at t is to be padded with (0 without moving lights, or when it is late)."""
        if self.task.timing is None or self.phase is not EpisodePhase.MOVING:
            return 0.0
        return max(0.0, self._slot_end() - self.episode_time(t))

    def _slot_end(self) -> float:
        """The episode's clock at the end of the running step's slot (s)."""
        return (self.steps + 1) * self.task.step_seconds

    def abort(self, token: int, reason: str) -> Aborted | None:
        """The move in flight failed (rejected, no answer, ...): end the episode as ABORTED.
        None when stale."""
        if token != self.token or self.phase is not EpisodePhase.MOVING:
            return None
        return self._aborted(reason)

    def interrupt(self, reason: str) -> Aborted | None:
        """The robot was restarted under the episode (it is no longer where the episode left
        it): a running episode ends ABORTED, whatever it was waiting for; a reset in flight
        goes back to WAITING. None when no episode was running. Answers still on their way are
        stale from now on."""
        self.token += 1
        if self.phase is EpisodePhase.RESETTING:
            self.phase = EpisodePhase.WAITING
            return None
        if not self.in_episode:
            return None
        return self._aborted(reason)

    def unanswered(self, reason: str) -> Aborted | None:
        """The first state got no action in time (it can be lost to an agent that DDS matched
        late): the episode ends ABORTED before its first step. None unless the episode waits
        for its first action."""
        if self.phase is not EpisodePhase.RUNNING or self.steps != 0:
            return None
        self.token += 1
        return self._aborted(reason)

    def _aborted(self, reason: str) -> Aborted:
        """End the episode ABORTED: its terminal state (a copy of the last) counts as sent."""
        self.counts.states_sent += 1
        return Aborted(self.state, self._end(EpisodeOutcome.ABORTED), reason)

    def _end(self, outcome: EpisodeOutcome) -> EpisodeSummaryFields:
        self.phase = EpisodePhase.ENDED
        self.action = None
        self.counts.outcomes[EpisodeOutcome(outcome).name] += 1
        return self.stats.summary(outcome)

    def _on_map(self, x: float, y: float) -> tuple[float, float]:
        occupancy = self.task.scenario.map
        if occupancy.contains_point(x, y):
            return x, y
        x_min, y_min, x_max, y_max = occupancy.bounds
        margin = min(_ON_MAP_MARGIN, occupancy.resolution / 2)
        return (
            min(max(x, x_min), x_max - margin),
            min(max(y, y_min), y_max - margin),
        )


# --- who is there -------------------------------------------------------------------------------


class Endpoint(NamedTuple):
    """One endpoint on the ROS graph: its node's fully qualified name, and whether a reader
    matches the environment's writer (reliable or best effort, volatile)."""

    node: str
    compatible: bool = True


def agent_connected(
    action_writers: Iterable[Endpoint], state_readers: Iterable[Endpoint], matched: int
) -> bool:
    """Whether an agent can be sent the first state without losing it.

    action_writers: the publishers of rl_agent/rl_action on the graph (the agents);
    state_readers: the subscriptions of rl_env/rl_state_reward on the graph; matched: how many
    readers the state writer is matched with. True when some agent also reads the states and
    the writer is matched with at least as many readers as can match: a volatile message
    published before the agent's reader is matched is lost, and a recorder's reader must not
    pass for the agent's.
    """
    agents = {writer.node for writer in action_writers}
    readers = list(state_readers)
    if not agents or not any(reader.node in agents for reader in readers):
        return False
    return matched >= sum(1 for reader in readers if reader.compatible)


def is_finite_pose(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)
