"""The experiment engine: trials on Ray Tune, on a local Ray (every core) or an existing cluster
(`ray start`), for `stealth sweep`, `make compare` and `stealth benchmark` alike. No rclpy.

    engine = Engine(address=None, num_cpus=None, say=print)   # ray.init: local or the cluster
    engine.run_fixed(trials, on_records, storage)             # laid-out trials (grid, random)
    engine.run_fixed(trials, on_records, storage, runner=f)   # trials run by f(trial) -> records
    engine.run_search(group_trial, space, budget, seen, on_records, storage)   # optuna

Each Tune trial is one ``sweep_trials`` trial, given ``cpus_per_trial`` CPUs (1: one trial per
core). A trial whose worker process or node dies is retried by Tune (``FailureConfig``,
``max_failures`` times) from the start; a trial that raises is not retried: its record says
failed, with the error, and the sweep goes on. Records come back to the driver in the trial's
result (policies included), so no storage shared between hosts is needed for the results; Tune's
own bookkeeping goes to ``storage`` (on a real cluster a path every node can write: its default
is under the sweep's directory, and each node writes its trials' bookkeeping there locally).

Progress: a line whenever a trial starts, ends or is retried: done / running / failed of the
total, the best objective so far and an ETA from the mean trial time and the concurrency.
SIGINT and SIGTERM (sweep_stop): Tune stops the running trials and the run raises Interrupted;
a trial stopped so is not recorded (it is not done: --resume runs it).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import contextlib
import logging
import os
from pathlib import Path
import signal
import socket
import tempfile
import time

from tqdm import tqdm

from stealth_experiments import sweep_stop
from stealth_experiments.harness import DEFAULT_EVAL_EVERY, RunResult, RunSpec, default_budget, run
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
}
DEFAULT_MAX_FAILURES = 2
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

    def run_fixed(
        self,
        trials: Sequence[dict],
        on_records: Callable[[list[dict]], None],
        storage: Path,
        *,
        cpus_per_trial: float = 1.0,
        max_failures: int = DEFAULT_MAX_FAILURES,
        max_concurrent: int | None = None,
        progress: bool = True,
        runner: Callable[[dict], list[dict]] | None = None,
        label: str = 'sweep',
    ) -> None:
        """Every trial once (retried on a lost worker); records to ``on_records`` as they end.
        runner: what runs a trial where Tune placed it (a module-level function of the trial
        dict, returning records with 'trial' and 'status'); None: ``sweep_trials.run_trial``,
        scored by its objective. label: the progress lines' first word."""
        if not trials:
            return
        from ray import tune

        trainable = _fixed_trainable
        if runner is not None:
            trainable = tune.with_parameters(_runner_trainable, runner=runner)
        self._fit(
            tune.with_resources(trainable, {'cpu': cpus_per_trial}),
            {'trial': tune.grid_search(list(trials))},
            tune.TuneConfig(
                num_samples=1,
                max_concurrent_trials=max_concurrent,
                reuse_actors=True,  # a new worker per trial costs seconds on a busy host
                trial_dirname_creator=_dirname,
            ),
            len(trials),
            on_records,
            storage,
            cpus_per_trial,
            max_failures,
            progress,
            label,
        )

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
        OptunaSearch) suggests from ``space``, told the (params, objective) already ``seen``."""
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
        self._fit(
            tune.with_resources(
                tune.with_parameters(_search_trainable, base=base), {'cpu': cpus_per_trial}
            ),
            space,
            tune.TuneConfig(
                search_alg=searcher,
                num_samples=budget,
                max_concurrent_trials=concurrent,
                reuse_actors=True,
                trial_dirname_creator=_dirname,
            ),
            budget,
            on_records,
            storage,
            cpus_per_trial,
            max_failures,
            progress,
        )

    def _fit(self, trainable, space, tune_config, total, on_records, storage, cpus_per_trial,
             max_failures, progress, label='sweep') -> None:  # fmt: skip
        from ray import tune

        watcher = _Progress(
            total, on_records, self.say if progress else None, self.cpus / cpus_per_trial, label
        )
        tuner = tune.Tuner(
            trainable,
            param_space=space,
            tune_config=tune_config,
            run_config=tune.RunConfig(
                name=f'trials-{time.strftime("%Y%m%d-%H%M%S")}',
                storage_path=str(Path(storage).resolve()),
                failure_config=tune.FailureConfig(max_failures=max_failures),
                callbacks=[watcher],
                verbose=0,
            ),
        )
        with sweep_stop.tune_run():
            try:
                tuner.fit()
            finally:
                watcher.finish()


def _dirname(trial) -> str:
    return trial.trial_id


def _where() -> dict:
    import ray
    from ray import tune

    return {
        'node': ray.get_runtime_context().get_node_id(),
        'tune_trial': tune.get_context().get_trial_id(),
    }


def _fixed_trainable(config: dict) -> None:
    from ray import tune

    records = run_trial(config['trial'], _where())
    tune.report({'objective': objective(records), 'records': records})


def _runner_trainable(config: dict, runner) -> None:
    from ray import tune

    tune.report({'records': runner(config['trial'])})


def _search_trainable(config: dict, base: dict) -> None:
    from ray import tune

    from stealth_experiments.sweep_plan import make_trial

    params = {name: _plain(value) for name, value in config.items()}
    trial = make_trial(
        base['mode'], base['scenario'], base['goal'], base['learner'], base['seeds'],
        base['episodes'], base['eval_every'], base['slip'], {**base['params'], **params},
    )  # fmt: skip
    records = run_trial(trial, _where())
    tune.report({'objective': objective(records), 'records': records})


def _plain(value):
    """numpy scalars Optuna may hand out, as Python numbers (for JSON and --set), floats to 6
    decimals (as random search's samples: tables stay readable, ids stable)."""
    value = value.item() if hasattr(value, 'item') else value
    return round(value, 6) if isinstance(value, float) else value


class _Progress:
    """Tune callback: records to the sink as trials end, and a progress line on each event."""

    def __new__(cls, *args, **kwargs):
        from ray import tune

        class Progress(tune.Callback):
            def __init__(self, total, sink, say, slots, label='sweep'):
                self.total, self.sink, self.say, self.slots = total, sink, say, max(slots, 1)
                self.label = label
                self.started = time.monotonic()
                self.done = self.failed = self.retries = 0
                self.running: set[str] = set()
                self.best: tuple[float, str] | None = None
                self.durations: list[float] = []
                self.began: dict[str, float] = {}
                self.recorded: set[str] = set()

            def on_trial_start(self, iteration, trials, trial, **info):
                self.began.setdefault(trial.trial_id, time.monotonic())
                self.running.add(trial.trial_id)
                self._line('started')

            def on_trial_result(self, iteration, trials, trial, result, **info):
                records = result.get('records')
                if records is None or trial.trial_id in self.recorded:
                    return
                self.recorded.add(trial.trial_id)
                self.sink(records)
                self.done += 1
                self.failed += any(r['status'] != 'ok' for r in records)
                value = result.get('objective')
                label = records[0]['trial']
                if value is not None and (self.best is None or value > self.best[0]):
                    self.best = (value, label)
                self.durations.append(time.monotonic() - self.began.get(trial.trial_id, 0.0))

            def on_trial_complete(self, iteration, trials, trial, **info):
                self.running.discard(trial.trial_id)
                stopped = trial.trial_id not in self.recorded and sweep_stop.requested()
                self._line('stopped' if stopped else 'finished')

            def on_trial_recover(self, iteration, trials, trial, **info):
                self.retries += 1
                self.running.discard(trial.trial_id)
                self._line('lost its worker process, retried from the start')

            def on_trial_error(self, iteration, trials, trial, **info):
                self.running.discard(trial.trial_id)
                if trial.trial_id not in self.recorded and not sweep_stop.requested():
                    self.recorded.add(trial.trial_id)
                    self.sink(_lost_records(trial.config, _first_line(trial.get_error())))
                    self.done += 1
                    self.failed += 1
                self._line('failed')

            def _line(self, event: str) -> None:
                if self.say is None:
                    return
                running = len(self.running)
                best = f', best {self.best[0]:.3f} ({self.best[1]})' if self.best else ''
                retried = f', {self.retries} retried' if self.retries else ''
                self.say(
                    f'{self.label}: trial {event}: {self.done}/{self.total} done, {running} '
                    f'running, {self.failed} failed{retried}{best}, ETA {self.eta()}'
                )

            def eta(self) -> str:
                if not self.durations:
                    return 'after the first trial'
                mean = sum(self.durations) / len(self.durations)
                waves = (self.total - self.done) / self.slots
                return _duration(max(waves * mean, 0.0))

            def finish(self) -> None:
                signum = sweep_stop.requested()
                stopped = f'interrupted by {signal.Signals(signum).name}: ' if signum else ''
                if self.say is not None:
                    self.say(
                        f'{self.label}: {stopped}{self.done}/{self.total} trials done, '
                        f'{self.failed} failed, '
                        f'{self.retries} retried, in {_duration(time.monotonic() - self.started)}'
                    )

        return Progress(*args, **kwargs)


def _lost_records(config: dict, error: str) -> list[dict]:
    """Failed records of a trial whose every attempt was lost (no record came back)."""
    trial = config.get('trial')
    if trial is None:
        return []  # a search trial: its parameters are in the Tune config only
    return [
        {
            'trial': trial['id'],
            'settings': {k: v for k, v in trial.items() if k not in ('id', 'seeds')},
            'seed': seed,
            'status': 'failed',
            'error': f'worker lost: {error}',
            'wall_seconds': None,
            'host': '',
            'node': '',
        }
        for seed in trial.get('seeds', [None])
    ]


def _first_line(error) -> str:
    lines = [line for line in str(error or 'no error text').splitlines() if line.strip()]
    return lines[-1][:300] if lines else 'no error text'


def _duration(seconds: float) -> str:
    minutes, seconds = divmod(int(round(seconds)), 60)
    return f'{minutes}m{seconds:02d}s' if minutes else f'{seconds}s'


# --- the harness's grid (`make compare`) ---------------------------------------------------------


def run_grid(
    scenarios: Sequence[str],
    learners: Sequence[str],
    seeds: Sequence[int],
    *,
    episodes: int | None = None,
    eval_every: int = DEFAULT_EVAL_EVERY,
    slip: float = 0.0,
    goal: str | None = None,
    jobs: int = 1,
    policy_dir: str | None = None,
    progress: bool = True,
) -> list[RunResult]:
    """The harness's grid (`make compare`): every scenario x learner x seed, on ``jobs`` CPUs of a
    local Ray (the engine of `stealth sweep` too) or, with ``jobs`` 1, one after another in this
    process without Ray; results in grid order.
    episodes: per run, None for each learner's DEFAULT_EPISODES."""
    specs = [
        RunSpec(
            scenario,
            learner,
            seed,
            episodes or default_budget(learner, scenario),
            eval_every,
            slip,
            goal,
            policy_dir,
        )
        for scenario in scenarios
        for learner in learners
        for seed in seeds
    ]
    if jobs <= 1:  # one after another in this process: no engine to start
        bar = tqdm(total=len(specs), desc='runs', unit='run', disable=not progress)
        results = []
        for spec in specs:
            results.append(run(spec))
            bar.update()
        bar.close()
        return results
    return run_specs(specs, jobs=jobs, progress=progress)


def run_specs(specs, *, jobs: int, progress: bool = True):
    """harness.run_grid's engine: each RunSpec a trial on a local Ray with ``jobs`` CPUs;
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
    with (
        sweep_stop.signals_stop(),
        tempfile.TemporaryDirectory(prefix='stealth-eval-') as storage,
        Engine(None, jobs, say) as engine,
    ):
        engine.run_fixed(trials, keep, Path(storage), progress=progress)
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
