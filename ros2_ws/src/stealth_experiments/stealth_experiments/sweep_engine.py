"""The experiment engine: trials on Ray, on a local Ray (every core) or an existing cluster
(`ray start`), for `stealth sweep`, `make compare` and `stealth benchmark` alike. No rclpy.

    engine = Engine(address=None, num_cpus=None, say=print)   # ray.init: local or the cluster
    engine.run_fixed(trials, on_records)                      # laid-out trials (grid, random)
    engine.run_fixed(trials, on_records, runner=f)            # trials run by f(trial) -> records
    with engine.pool(trials) as pool: pool.ready(); engine.run_fixed(trials, sink, pool=pool)
    engine.run_search(group_trial, space, budget, seen, on_records, storage)   # optuna, on Tune

Laid-out trials run on sweep_pool's workers: Ray actors of ``cpus_per_trial`` CPUs each (1: one
trial per core), started once, importing and building the trials' scenario models once, then
reused for trial after trial. A trial whose worker process or node dies runs again on another
worker from the start (``max_failures`` times); a trial that raises is not retried: its record
says failed, with the error, and the sweep goes on. Records come back to the driver as the
trial's result (policies included), so no storage shared between hosts is needed. An optuna
search runs on Ray Tune (its OptunaSearch), whose own bookkeeping goes to ``storage``.

Start-up, said apart from the trials: Ray's own (``ray.init``: a local Ray starts its GCS, raylet
and their agents, without the dashboard), then the workers' (``Pool.ready``).

Progress (sweep_pool.Progress): a line whenever a trial starts, ends or is retried: done /
running / failed of the total, the best objective so far and an ETA from the mean trial time
and the concurrency; at the end, which trials were retried. SIGINT and SIGTERM (sweep_stop):
the running trials are stopped (their workers killed) and Interrupted raised; a trial stopped so
is not recorded (it is not done: --resume runs it).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import contextlib
import functools
import logging
import os
from pathlib import Path
import socket
import time

from stealth_experiments import sweep_stop
from stealth_experiments.sweep_pool import DEFAULT_MAX_FAILURES, Pool, Progress, scenarios_of
from stealth_experiments.sweep_trials import objective, run_trial

# Ray's node startup waits for its agents (Python processes) to write their ports; under load
# on a small machine that takes longer than Ray's defaults allow.
RAY_ENVIRONMENT = {
    'RAY_raylet_start_wait_time_s': '180',
    'RAY_agent_register_timeout_ms': '180000',
    'TUNE_DISABLE_AUTO_CALLBACK_LOGGERS': '1',  # results stay in the records, not CSV/TBX
    'RAY_DEDUP_LOGS': '0',
    'RAY_USAGE_STATS_ENABLED': '0',
    'RAY_AIR_NEW_OUTPUT': '0',  # no experiment box: the progress lines below say what runs
    # A worker's end would SIGKILL its children: a ROS trial's `stealth train` gets SIGTERM
    # instead (sweep_trials._stop_with_parent) and stops its nodes in order.
    'RAY_kill_child_processes_on_worker_exit': '0',
    # Ray runs its workers at niceness 15, under everything else on the host: on cores that
    # other work shares, two trials side by side then got less CPU than one alone in the driver.
    # A sweep's trials are the work itself; they run at the niceness of the sweep.
    'RAY_worker_niceness': '0',
}
# Ray gives a node 30 s (fixed) to register; on a busy host its agents' start-up can miss that.
START_ATTEMPTS = 3
# The HTTP/2 connection preface and an empty SETTINGS frame: a gRPC server (a Ray head's GCS)
# answers with a SETTINGS frame (type 4) of its own; anything else is not a Ray head.
HTTP2_HELLO = b'PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n' + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])


class EngineError(RuntimeError):
    """The engine cannot start: the message is one line naming what and what to do."""


def check_address(address: str, timeout: float = 5.0) -> None:
    """One line (EngineError), within about ``timeout`` s, when no Ray head answers at HOST:PORT:
    nothing listens, or what does is not a gRPC server (Ray would retry it for minutes)."""
    host, _, port = address.rpartition(':')
    if address == 'auto':
        return
    if not host or not port.isdigit():
        raise EngineError(f'--address {address}: expected HOST:PORT of a Ray head (ray start)')
    hint = 'start one with `ray start --head --port PORT` or leave --address out'
    try:
        connection = socket.create_connection((host, int(port)), timeout=timeout)
    except OSError as error:
        raise EngineError(
            f'--address {address}: no Ray head answers there ({error.strerror or error}); {hint}'
        ) from None
    answer = b''
    with connection, contextlib.suppress(OSError):  # a timeout or a reset: what came so far
        connection.sendall(HTTP2_HELLO)
        while len(answer) < 9:
            chunk = connection.recv(64)
            if not chunk:
                break
            answer += chunk
    if len(answer) < 9 or answer[3] != 4:
        first = answer.splitlines()[0][:40].decode(errors='replace') if answer.strip() else ''
        said = (
            f'answered {first!r} to a gRPC hello' if first else f'no gRPC answer in {timeout:g} s'
        )
        raise EngineError(
            f'--address {address}: something listens there but it is not a Ray head ({said}); '
            f'{hint}'
        )


class Engine:
    """A connection to Ray: started locally (``address`` None) or joined; closed by close()."""

    def __init__(self, address: str | None = None, num_cpus: int | None = None, say=print):
        for key, value in RAY_ENVIRONMENT.items():
            os.environ.setdefault(key, value)
        if address:
            check_address(address)
        self.say = say
        started = time.monotonic()
        where = f'the Ray cluster at {address}' if address else 'a local Ray'
        say(f'engine: starting {where} (its processes take a while to start on a busy host)')
        import ray

        # The progress lines and the records say what failed; Tune's tracebacks would bury them.
        logging.getLogger('ray.tune').setLevel(logging.CRITICAL)
        for attempt in range(1, START_ATTEMPTS + 1):
            try:
                ray.init(
                    address=address,
                    num_cpus=None if address else num_cpus,
                    include_dashboard=False,
                    log_to_driver=False,
                    logging_level=logging.WARNING,
                    ignore_reinit_error=True,
                )
                sweep_stop.claim_signals()  # ray.init took SIGTERM
                break
            except sweep_stop.Interrupted:
                ray.shutdown()
                raise
            except Exception as error:  # Ray raises a bare Exception when a node is slow
                ray.shutdown()  # what this attempt started goes
                first = str(error).splitlines()[0] if str(error) else type(error).__name__
                if attempt == START_ATTEMPTS:
                    raise EngineError(
                        f'{where} did not start in {START_ATTEMPTS} attempts ({first}); '
                        'try again when the host is less busy, or start a cluster with '
                        '`ray start --head` and give its address'
                    ) from None
                say(f'engine: {where} did not come up ({first}); trying again')
        self.ray = ray
        nodes = [n for n in ray.nodes() if n.get('Alive')]
        self.cpus = int(ray.cluster_resources().get('CPU', 1))
        say(
            f'engine: {where} is up in {time.monotonic() - started:.0f} s: '
            f'{len(nodes)} node(s), {self.cpus} CPU(s)'
        )

    def close(self) -> None:
        self.ray.shutdown()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # --- running ---------------------------------------------------------------------------

    def pool(
        self,
        trials: Sequence[dict],
        *,
        cpus_per_trial: float = 1.0,
        max_concurrent: int | None = None,
        runner: Callable | None = None,
    ) -> Pool:
        """Workers for these trials (sweep_pool): one per ``cpus_per_trial`` CPUs of the cluster
        (at most ``max_concurrent``, and no more than there are trials), each importing and
        building the trials' scenario models once. runner: what runs a trial (a module-level
        function of the trial dict, returning records with 'trial' and 'status'); None:
        ``sweep_trials.run_trial``."""
        slots = max(1, int(self.cpus // cpus_per_trial))
        slots = min(slots, max_concurrent or slots, max(len(trials), 1))
        work = run_trial if runner is None else functools.partial(_trial_only, runner)
        return Pool(slots, cpus_per_trial, work, scenarios_of(trials), self.say)

    def run_fixed(
        self,
        trials: Sequence[dict],
        on_records: Callable[[list[dict]], None],
        *,
        cpus_per_trial: float = 1.0,
        max_failures: int = DEFAULT_MAX_FAILURES,
        max_concurrent: int | None = None,
        progress: bool = True,
        runner: Callable[[dict], list[dict]] | None = None,
        label: str = 'sweep',
        pool: Pool | None = None,
    ) -> None:
        """Every trial once (again on another worker when its worker was lost); records to
        ``on_records`` as they end. runner: as for pool(); None: ``sweep_trials.run_trial``,
        scored by its objective. label: the progress lines' first word. pool: workers already
        started (``pool()``), kept open; None: a pool of its own for these trials."""
        if not trials:
            return
        own = pool is None
        if own:
            pool = self.pool(trials, cpus_per_trial=cpus_per_trial,
                             max_concurrent=max_concurrent, runner=runner)  # fmt: skip
        try:
            watcher = Progress(
                len(trials), self.say if progress else None, pool.slots, label,
                objective if runner is None else None,
            )  # fmt: skip
            pool.run(trials, on_records, watcher, max_failures)
        finally:
            if own:
                pool.close()

    def run_search(
        self,
        base: dict,
        space: dict,
        budget: int,
        seen: Sequence[tuple[dict, float]],
        on_records: Callable[[list[dict]], None],
        storage: Path,
        *,
        seed: int = 0,
        cpus_per_trial: float = 1.0,
        max_failures: int = DEFAULT_MAX_FAILURES,
        progress: bool = True,
    ) -> None:
        """``budget`` more trials of ``base`` with parameters Optuna (TPE, through Ray Tune's
        OptunaSearch) suggests from ``space``, told the (params, objective) already ``seen``.
        Tune's own bookkeeping goes to ``storage``."""
        if budget <= 0:
            return
        import optuna
        from ray import tune
        from ray.tune.search.optuna import OptunaSearch

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        searcher = OptunaSearch(
            metric='objective',
            mode='max',
            # Seeded past the known points: a resumed search must not draw its first ones again.
            sampler=optuna.samplers.TPESampler(seed=seed + len(seen)),
            points_to_evaluate=[dict(params) for params, _ in seen] or None,
            evaluated_rewards=[value for _, value in seen] or None,
        )
        concurrent = max(1, int(self.cpus // cpus_per_trial))
        watcher = Progress(budget, self.say if progress else None, concurrent, 'sweep', objective)
        tuner = tune.Tuner(
            tune.with_resources(
                tune.with_parameters(_search_trainable, base=base), {'cpu': cpus_per_trial}
            ),
            param_space=space,
            tune_config=tune.TuneConfig(
                search_alg=searcher,
                num_samples=budget,
                max_concurrent_trials=concurrent,
                reuse_actors=True,
                trial_dirname_creator=_dirname,
            ),
            run_config=tune.RunConfig(
                name=f'trials-{time.strftime("%Y%m%d-%H%M%S")}',
                storage_path=str(Path(storage).resolve()),
                failure_config=tune.FailureConfig(max_failures=max_failures),
                callbacks=[_TuneProgress(watcher, on_records)],
                verbose=0,
            ),
        )
        with sweep_stop.tune_run():
            try:
                tuner.fit()
            finally:
                watcher.finish()


def _trial_only(runner: Callable[[dict], list[dict]], trial: dict, where: dict) -> list[dict]:
    """A runner of the trial alone (stealth benchmark's), as the pool calls it."""
    del where
    return runner(trial)


def _dirname(trial) -> str:
    return trial.trial_id


def _search_trainable(config: dict, base: dict) -> None:
    import ray
    from ray import tune

    from stealth_experiments.sweep_plan import make_trial

    params = {name: _plain(value) for name, value in config.items()}
    trial = make_trial(
        base['mode'], base['scenario'], base['goal'], base['learner'], base['seeds'],
        base['episodes'], base['eval_every'], base['slip'], {**base['params'], **params},
    )  # fmt: skip
    records = run_trial(trial, {'node': ray.get_runtime_context().get_node_id()})
    tune.report({'objective': objective(records), 'records': records})


def _plain(value):
    """numpy scalars Optuna may hand out, as Python numbers (for JSON and --set), floats to 6
    decimals (as random search's samples: tables stay readable, ids stable)."""
    value = value.item() if hasattr(value, 'item') else value
    return round(value, 6) if isinstance(value, float) else value


class _TuneProgress:
    """Tune callback of an optuna search: records to the sink as trials end, progress lines."""

    def __new__(cls, progress: Progress, sink):
        from ray import tune

        class TuneProgress(tune.Callback):
            def __init__(self):
                self.recorded: set[str] = set()

            def on_trial_start(self, iteration, trials, trial, **info):
                progress.started(trial.trial_id)

            def on_trial_result(self, iteration, trials, trial, result, **info):
                records = result.get('records')
                if records is None or trial.trial_id in self.recorded:
                    return
                self.recorded.add(trial.trial_id)
                sink(records)
                progress.finished(trial.trial_id, records)

            def on_trial_recover(self, iteration, trials, trial, **info):
                progress.retried(trial.trial_id, 'its worker process died', 0, 0)

            def on_trial_error(self, iteration, trials, trial, **info):
                if trial.trial_id not in self.recorded and not sweep_stop.requested():
                    self.recorded.add(trial.trial_id)  # its parameters are Tune's alone
                    progress.finished(trial.trial_id, [])

        return TuneProgress()


# --- the harness's grid (`make compare`) ---------------------------------------------------------


def run_specs(specs, *, jobs: int, progress: bool = True):
    """experiments.run_grid's engine: each RunSpec a trial on a local Ray with ``jobs`` CPUs;
    RunResults in the order of ``specs``, policies written where their spec says."""
    import base64

    from stealth_experiments.harness import policy_path
    from stealth_experiments.sweep_plan import make_trial
    from stealth_experiments.sweep_trials import record_result

    trials = [
        make_trial('gym', s.scenario, s.goal, s.learner, [s.seed], s.episodes, s.eval_every,
                   s.slip, dict(s.params))
        for s in specs
    ]  # fmt: skip
    records: dict[str, dict] = {}

    def keep(found: list[dict]) -> None:
        for record in found:
            records[record['trial']] = record

    say = print if progress else (lambda line: None)
    with sweep_stop.signals_stop(), Engine(None, jobs, say) as engine:
        engine.run_fixed(trials, keep, progress=progress)
    results = []
    for spec, trial in zip(specs, trials, strict=True):
        record = records.get(trial['id'])
        if record is None or record['status'] != 'ok':
            error = record['error'] if record else 'no result came back'
            raise RuntimeError(f'run {trial["id"]} failed: {error}')
        if spec.policy_dir and record.get('policy'):
            path = policy_path(spec)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(base64.b64decode(record['policy']))
        results.append(record_result(record))
    return results
