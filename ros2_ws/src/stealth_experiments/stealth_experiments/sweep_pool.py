"""The engine's workers: a pool of Ray actors that run a sweep's trials, started once and reused
for trial after trial, and the progress lines of a run. No rclpy.

    pool = Pool(slots, cpus_per_trial, runner, warm, say)   # the actors start (in parallel)
    pool.ready()                                            # s until every one has started
    pool.run(trials, on_records, progress)                  # records to on_records as trials end
    pool.close()                                            # the actors go

Why actors and not a Ray task or a Tune trial per trial: a new worker process pays Python's
imports (numpy, gymnasium, the stealth packages, numba's cached kernels) and each scenario its
lattice model (every node judged by the lighting model), seconds each on a busy host, and Tune
adds its controller's bookkeeping to every trial. A worker here imports once, builds the
models of the sweep's scenarios once (``warm``), then takes the next trial as soon as it is
free.

A worker whose process or node dies (Ray's RayActorError, or its result lost with its node) has
its trial put back at the front of the queue, to run on another worker from the start, at most
``max_failures`` times (then the trial's runs are recorded failed: "worker lost: ..."); a
replacement worker is asked for, which starts wherever the cluster has room (never, on a node
that is gone: the pool carries on with the workers it has). A trial whose runner raises is not
retried: its records say failed, with the error's last line. SIGINT and SIGTERM (sweep_stop)
raise Interrupted out of ``run``; close() then kills the workers (a ROS trial's `stealth train`
gets SIGTERM from its dying worker: sweep_trials._stop_with_parent).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
import contextlib
import os
import re
import signal
import socket
import time

from stealth_experiments import sweep_stop

DEFAULT_MAX_FAILURES = 2
WORKER_WAIT = 600.0  # s without a single worker able to run a trial before the pool gives up
POLL = 0.5  # s between looks at the workers (signals are handled in between)


class PoolError(RuntimeError):
    """No worker could start; the message is one line saying why and what to do."""


class TrialWorker:
    """One worker of the pool (a Ray actor): imports and scenario models once, then trials."""

    def __init__(self, runner: Callable, warm: Sequence[tuple[str, str | None]]):
        self.runner = runner
        if warm:
            from stealth_core.gym_env import lattice_model

            for scenario, goal in warm:
                # A scenario that cannot be built fails in its own trials, with their error.
                with contextlib.suppress(Exception):
                    lattice_model(scenario, goal)  # cached in this process (lru_cache)

    def where(self) -> dict:
        import ray

        return {
            'node': ray.get_runtime_context().get_node_id(),
            'host': socket.gethostname(),
            'pid': os.getpid(),
        }

    def run(self, trial: dict, attempt: int) -> list[dict]:
        return self.runner(trial, {**self.where(), 'attempt': attempt})


def scenarios_of(trials: Sequence[dict]) -> list[tuple[str, str | None]]:
    """The (scenario, goal) pairs of sweep trials (gym and ros modes), each once: what every
    worker builds the lattice model of before its first trial."""
    pairs = (
        (t['scenario'], t.get('goal'))
        for t in trials
        if t.get('mode') in ('gym', 'ros') and isinstance(t.get('scenario'), str)
    )
    return list(dict.fromkeys(pairs))[:16]  # gym_env's model cache holds 16


class Pool:
    """``slots`` workers of ``cpus_per_trial`` CPUs each, running ``runner(trial, where)``."""

    def __init__(self, slots: int, cpus_per_trial: float, runner: Callable,
                 warm: Sequence[tuple[str, str | None]] = (), say=print):  # fmt: skip
        import ray

        self.ray, self.say, self.slots = ray, say, max(1, int(slots))
        self.started = time.monotonic()
        self.ready_seconds: float | None = None
        self._remote = ray.remote(num_cpus=cpus_per_trial, max_restarts=0, max_task_retries=0)(
            TrialWorker
        )
        self.warm = list(warm)
        self._args = (runner, self.warm)
        self.idle: list = []
        self.places: dict = {}  # actor -> where it runs (TrialWorker.where)
        self.starting: dict = {}  # ready ref -> actor
        self.actors: list = []  # every worker started, for close()
        self.start_failures: list[str] = []
        self.workers_started = 0
        for _ in range(self.slots):
            self._start_one()

    def _start_one(self) -> None:
        actor = self._remote.remote(*self._args)
        self.actors.append(actor)
        self.starting[actor.where.remote()] = actor

    def _started(self, ref) -> None:
        actor = self.starting.pop(ref)
        try:
            self.places[actor] = self.ray.get(ref)
        except self.ray.exceptions.RayError as error:
            self.start_failures.append(_last_line(error))
            self.say(f'engine: a worker could not start ({self.start_failures[-1]})')
            self._kill(actor)
            return
        self.idle.append(actor)
        self.workers_started += 1
        if self.ready_seconds is None and not self.starting:
            self.ready_seconds = time.monotonic() - self.started
            built = f', {len(self.warm)} scenario model(s) built' if self.warm else ''
            self.say(
                f'engine: start-up: {self.workers_started} worker(s) ready in '
                f'{self.ready_seconds:.1f} s (imports{built} once per worker, reused for every '
                'trial)'
            )

    @sweep_stop.ray_calls()
    def ready(self) -> float:
        """Wait until every worker has started (imports and scenario models done): its s."""
        while self.starting:
            done, _ = self.ray.wait(list(self.starting), num_returns=1, timeout=POLL)
            for ref in done:
                self._started(ref)
        if not self.idle:
            raise PoolError(_no_worker(self.start_failures))
        return self.ready_seconds

    @sweep_stop.ray_calls()
    def run(self, trials: Sequence[dict], on_records: Callable[[list[dict]], None],
            progress: Progress, max_failures: int = DEFAULT_MAX_FAILURES) -> None:  # fmt: skip
        """Every trial once (again on another worker when its worker was lost)."""
        queue = deque((trial, 1) for trial in trials)
        running: dict = {}  # result ref -> (actor, trial, attempt)
        waiting_since = time.monotonic()
        try:
            while queue or running:
                while queue and self.idle:
                    trial, attempt = queue.popleft()
                    actor = self.idle.pop()
                    running[actor.run.remote(trial, attempt)] = (actor, trial, attempt)
                    progress.started(trial['id'])
                if not running and not self.starting:
                    raise PoolError(_no_worker(self.start_failures))
                if running:
                    waiting_since = time.monotonic()
                elif time.monotonic() - waiting_since > WORKER_WAIT:
                    raise PoolError(
                        f'no Ray worker could run a trial for {WORKER_WAIT:g} s (the cluster has '
                        'no free CPU for one: add a node, or lower cpus_per_trial)'
                    )
                refs = [*running, *self.starting]
                done, _ = self.ray.wait(refs, num_returns=1, timeout=POLL)
                for ref in done:
                    if ref in self.starting:
                        self._started(ref)
                        continue
                    actor, trial, attempt = running.pop(ref)
                    records, lost = self._result(ref, trial, self.places.get(actor, {}))
                    if lost is None:
                        self.idle.append(actor)
                        on_records(records)
                        progress.finished(trial['id'], records)
                        continue
                    self._kill(actor)
                    self._start_one()  # a replacement, wherever the cluster has room
                    if attempt <= max_failures:
                        queue.appendleft((trial, attempt + 1))
                        progress.retried(trial['id'], lost, attempt + 1, max_failures + 1)
                    else:
                        records = lost_records(trial, f'{lost} ({attempt} attempts)')
                        on_records(records)
                        progress.finished(trial['id'], records)
        finally:
            progress.finish()

    def _result(self, ref, trial: dict, place: dict) -> tuple[list[dict], str | None]:
        """(records, None), or ([], why) when the worker or its node was lost."""
        exceptions = self.ray.exceptions
        try:
            return self.ray.get(ref), None
        except exceptions.RayTaskError as error:  # the runner raised: failed, not retried
            return lost_records(trial, _last_line(error), prefix=''), None
        except exceptions.RayError as error:  # its worker, its node or its result lost
            addresses = {n['NodeID']: n['NodeManagerAddress'] for n in self.ray.nodes()}
            return [], _lost_why(error, {**place, 'ip': addresses.get(place.get('node'), '?')})

    def _kill(self, actor) -> None:
        with contextlib.suppress(Exception):  # already dead, or Ray shutting down
            self.ray.kill(actor, no_restart=True)

    def close(self) -> None:
        """Every worker goes, those running a trial too (interrupted: a ROS trial's `stealth
        train` then gets SIGTERM from its dying worker and stops its nodes)."""
        for actor in self.actors:
            self._kill(actor)
        self.actors, self.idle, self.starting = [], [], {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def lost_records(trial: dict, error: str, prefix: str = 'worker lost: ') -> list[dict]:
    """Failed records of a trial that brought none back (its worker lost, or its runner raised),
    one per seed, with the error."""
    return [
        {
            'trial': trial['id'],
            'settings': {k: v for k, v in trial.items() if k not in ('id', 'seeds')},
            'seed': seed,
            'status': 'failed',
            'error': f'{prefix}{error}',
            'wall_seconds': None,
            'host': '',
            'node': '',
        }
        for seed in trial.get('seeds', [None])
    ]


def _lost_why(error, place: dict) -> str:
    """Where the lost worker ran and what Ray said of it, short: its "because ..." line, or the
    RPC error of a worker that stopped answering."""
    where = ''
    if place.get('node'):
        where = f'pid {place["pid"]} on node {place["node"][:8]} at {place["ip"]}: '
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    said = next((line for line in lines if 'because' in line), lines[0] if lines else '')
    rpc = re.search(r'RPC error: (.*?)(?: rpc_code.*)?$', said)
    said = f'unreachable, {rpc.group(1)}' if rpc else said.split('. ')[0]
    return f'{where}{said[:120] or type(error).__name__}'


def _last_line(error) -> str:
    lines = [line.strip() for line in str(error or 'no error text').splitlines() if line.strip()]
    return lines[-1][:300] if lines else 'no error text'


def _no_worker(failures: list[str]) -> str:
    why = f' ({failures[-1]})' if failures else ''
    return (
        f'no Ray worker could start{why}; check that the nodes run in the environment of '
        '`source scripts/ros_env.sh`'
    )


class Progress:
    """The progress lines of a run: one whenever a trial starts, ends or is retried (done /
    running / failed of the total, retries, the best objective so far, an ETA from the mean
    trial time and the concurrency), and a last one with which trials were retried."""

    def __init__(self, total: int, say, slots: float, label: str = 'sweep',
                 objective: Callable[[list[dict]], float] | None = None):  # fmt: skip
        self.total, self.say, self.slots, self.label = total, say, max(slots, 1), label
        self.objective = objective
        self.began_run = time.monotonic()
        self.done = self.failed = self.retries = 0
        self.running: set[str] = set()
        self.best: tuple[float, str] | None = None
        self.durations: list[float] = []
        self.began: dict[str, float] = {}
        self.retried_ids: dict[str, str] = {}

    def started(self, trial_id: str) -> None:
        self.began[trial_id] = time.monotonic()
        self.running.add(trial_id)
        self._line('trial started')

    def finished(self, trial_id: str, records: list[dict]) -> None:
        """A trial ended with these records (none: it brought nothing back, a failure)."""
        self.running.discard(trial_id)
        self.done += 1
        failed = not records or any(r['status'] != 'ok' for r in records)
        self.failed += failed
        if self.objective is not None and not failed:
            value = self.objective(records)
            if self.best is None or value > self.best[0]:
                self.best = (value, records[0]['trial'])
        self.durations.append(time.monotonic() - self.began.get(trial_id, self.began_run))
        self._line('trial failed' if failed else 'trial finished')

    def retried(self, trial_id: str, why: str, attempt: int, attempts: int) -> None:
        self.running.discard(trial_id)
        self.retries += 1
        self.retried_ids[trial_id] = why
        which = f' (attempt {attempt} of {attempts})' if attempt else ''
        self._line(f'trial {trial_id} lost its worker ({why}), retried from the start{which}')

    def _line(self, event: str) -> None:
        if self.say is None:
            return
        best = f', best {self.best[0]:.3f} ({self.best[1]})' if self.best else ''
        retried = f', {self.retries} retried' if self.retries else ''
        self.say(
            f'{self.label}: {event}: {self.done}/{self.total} done, {len(self.running)} '
            f'running, {self.failed} failed{retried}{best}, ETA {self.eta()}'
        )

    def eta(self) -> str:
        if not self.durations:
            return 'after the first trial'
        mean = sum(self.durations) / len(self.durations)
        return duration(max((self.total - self.done) / self.slots * mean, 0.0))

    def finish(self) -> None:
        if self.say is None:
            return
        signum = sweep_stop.requested()
        stopped = f'interrupted by {signal.Signals(signum).name}: ' if signum else ''
        self.say(
            f'{self.label}: {stopped}{self.done}/{self.total} trials done, {self.failed} failed, '
            f'{self.retries} retried, in {duration(time.monotonic() - self.began_run)}'
        )
        if self.retried_ids:
            self.say(
                f'{self.label}: retried after a lost worker: '
                + ', '.join(f'{t} ({why})' for t, why in self.retried_ids.items())
            )


def duration(seconds: float) -> str:
    minutes, seconds = divmod(int(round(seconds)), 60)
    return f'{minutes}m{seconds:02d}s' if minutes else f'{seconds}s'
