"""The environment node's ``service`` robot interface: moves are the simulator's
``sim/execute_move``, resets its ``sim/reset`` (:class:`Teleport`, which the ``topics`` robot
uses too under ``reset_mode teleport``).

Calls are asynchronous: the answer comes through the future's callback, and a request with no
answer by its deadline is given up in the node's housekeeping ``tick`` (the request is removed,
so a late answer changes nothing). A service served by a node of this process (the composed
``sim_env``) is called directly (:mod:`stealth_node_kit.in_process`): its answer comes before
``call_async`` returns.
"""

from __future__ import annotations

from collections.abc import Callable
import functools
import math
import time
from typing import Any, NamedTuple

from rclpy.task import Future
from stealth_interfaces.srv import ExecuteMove, ResetRobot
from stealth_node_kit import rl_contract
from stealth_node_kit.conversions import seconds
from stealth_node_kit.in_process import InProcessClient, InProcessServices

from stealth_env.env_messages import move_request, pose_of
from stealth_env.robot import MoveEnd, OnMoveEnd, OnReset, failed
from stealth_env.topic_moves import MoveGoal, Pose

MOVE_SERVICE = rl_contract.EXECUTE_MOVE
# s of wall time a teleport (sim/reset, answered in milliseconds) is waited for before it is sent
# again: just after the simulator restarts the request or its answer can be lost (DDS still
# matches the dead server's endpoints), and the run should not wait a whole move_timeout.
RESET_ANSWER_TIMEOUT = 5.0


class Pending(NamedTuple):
    """A request to the simulator on its way."""

    future: Future
    client: Any
    deadline: float  # time.monotonic()
    what: str
    timeout: str  # what the deadline is, for the message when it passes
    on_timeout: Callable[[str], None]


class ServiceCalls:
    """One request at a time to the simulator's services, with a deadline of wall time."""

    def __init__(self, move_timeout: Callable[[], float]):
        self._move_timeout = move_timeout  # the node's parameter (it can change)
        self._pending: Pending | None = None

    def send(self, client, request, what: str, on_answer, on_timeout, timeout=None) -> None:
        """``on_answer(response, '')`` with the answer, ``on_answer(None, why)`` when the call
        failed; ``on_timeout(why)`` when there is none within `timeout` (move_timeout at most)."""
        future = client.call_async(request)
        move_timeout = self._move_timeout()
        if timeout is None or timeout >= move_timeout:
            timeout, name = move_timeout, f'move_timeout {move_timeout:g} s'
        else:
            name = f'{timeout:g} s'
        deadline = time.monotonic() + timeout
        self._pending = Pending(future, client, deadline, what, name, on_timeout)
        future.add_done_callback(functools.partial(self._answered, on_answer))

    def _answered(self, on_answer, future: Future) -> None:
        if self._pending is not None and self._pending.future is future:
            self._pending = None
        if future.cancelled():
            on_answer(None, 'the request was cancelled')
            return
        error = future.exception()
        if error is not None:
            on_answer(None, f'the call failed: {error!r}')
            return
        on_answer(future.result(), '')

    def tick(self) -> None:
        pending = self._pending
        if pending is not None and time.monotonic() > pending.deadline:
            self._pending = None
            pending.client.remove_pending_request(pending.future)
            pending.on_timeout(
                f'no answer from {pending.what} within {pending.timeout} '
                '(is the simulator running?)'
            )

    def cancel(self) -> None:
        if self._pending is not None:
            self._pending.client.remove_pending_request(self._pending.future)
            self._pending = None


class Teleport:
    """``reset_mode teleport``: the ResetRobot service (``reset_service``) places the robot."""

    def __init__(self, node, services: InProcessServices, name: str, move_timeout):
        self.node = node
        self.name = name
        self._move_timeout = move_timeout
        self._client = services.client(node, ResetRobot, name)
        self._calls = ServiceCalls(move_timeout)

    def ready(self) -> bool:
        return self._client.service_is_ready()

    def describe(self) -> str:
        return self.node.resolve_service_name(self.name)

    def place(self, pose: Pose, on_done: Callable[[str], None]) -> None:
        """``on_done('')`` once the robot is at `pose`, else ``on_done(why not)``."""

        def answered(response, problem: str) -> None:
            if response is None or not response.success:
                on_done(problem or response.message)
            else:
                on_done('')

        x, y, yaw = pose
        request = ResetRobot.Request(x=x, y=y, yaw=yaw)  # zero covariance: the node's default
        timeout = min(self._move_timeout(), RESET_ANSWER_TIMEOUT)
        self._calls.send(self._client, request, self.name, answered, on_done, timeout)

    def tick(self) -> None:
        self._calls.tick()

    def cancel(self) -> None:
        self._calls.cancel()


class ServiceRobot:
    """The simulator's robot over ``sim/execute_move`` and the teleport (the default)."""

    def __init__(self, node, services: InProcessServices, teleport: Teleport, move_timeout):
        self._calls = ServiceCalls(move_timeout)
        self._client = services.client(node, ExecuteMove, MOVE_SERVICE)
        self._teleport = teleport

    def ready(self) -> bool:
        return self._teleport.ready() and self._client.service_is_ready()

    def describe(self) -> str:
        if isinstance(self._client, InProcessClient):
            moves = f'the simulator in this process (called directly: {MOVE_SERVICE}'
        else:
            moves = f'the simulator ({MOVE_SERVICE}'
        return f'{moves}, {self._teleport.describe()})'

    def run(self, move: MoveGoal, on_end: OnMoveEnd) -> None:
        if not self._client.service_is_ready():
            on_end(failed(f'{MOVE_SERVICE} is not available'))
            return
        answered = functools.partial(self._answered, on_end)
        self._calls.send(self._client, move_request(move), MOVE_SERVICE, answered,
                         lambda reason: on_end(failed(reason)))  # fmt: skip

    @staticmethod
    def _answered(on_end: OnMoveEnd, response, problem: str) -> None:
        if response is None:
            on_end(failed(f'{MOVE_SERVICE}: {problem}'))
        elif response.outcome == ExecuteMove.Response.REJECTED:
            on_end(failed(f'the simulator rejected the move: {response.message}'))
        else:
            estimate, truth = pose_of(response.estimate.pose), pose_of(response.true_pose)
            t = seconds(response.stamp)  # time_msg(t) gives the stamp back to the nanosecond
            on_end(MoveEnd(response.outcome, response.message, estimate, truth, t, True))

    def reset(self, pose: Pose, on_done: OnReset) -> None:
        self._teleport.place(pose, lambda problem: on_done(problem, -math.inf))

    def not_responding(self) -> str:
        """The simulator answers for its robot: a move that times out is its outcome."""
        return ''

    def cancel(self) -> None:
        self._calls.cancel()
        self._teleport.cancel()

    def tick(self) -> None:
        self._calls.tick()
        self._teleport.tick()
