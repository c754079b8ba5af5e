"""`stealth sweep`: scenarios x learners x seeds x hyperparameters, on Ray.

    stealth sweep docs/sweeps/example.yaml                 # a local Ray on every core
    stealth sweep SWEEP.yaml --address HOST:6379           # an existing cluster (`ray start`)
    stealth sweep --resume runs/sweeps/example-<time>      # only the trials not finished yet

The sweep file (sweep_plan) is checked completely before Ray starts; each problem is one line
naming the field. Trials run on sweep_engine (Ray Tune), each through sweep_trials (in-process,
or `stealth train` in its own ROS domain); their records land in the sweep's directory as they
end (sweep_report), so a sweep stopped half-way and given to --resume reruns only the rest, and
the table, best configurations and curves are written at the end.

Ctrl-C or SIGTERM (sweep_stop): the running trials are stopped (a ROS trial's processes waited
for and their shared memory cleaned), the report written from the finished ones and marked
interrupted, exit 130 or 143; --resume runs the rest. Exit 1 when every run failed; 3 when
some did and the rest finished (the failed runs listed, one line each, with their own error).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import datetime
from pathlib import Path
import shutil
import sys

from stealth_experiments.sweep_plan import MAX_TRIALS, SweepError, SweepPlan, load_plan
from stealth_experiments.sweep_stop import Interrupted

SAVED_FILE = 'sweep.yaml'
# The sweep file's directory (its relative scenario paths' base), then the sweep's name (the
# copy's stem, sweep, is not: a resumed sweep said 'sweep: sweep: ...').
BASE_FILE = 'sweep_base.txt'
SOME_FAILED = 3  # exit code: the sweep finished, but some of its runs failed (1: every run did)
MAX_FAILED_LINES = 10


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='stealth sweep',
        description='Train learners over scenarios, seeds and hyperparameters (grid, random or '
        'Optuna search) on Ray: a local Ray on every core, or a cluster with --address. '
        'Writes results.csv, results.md (best configuration per scenario), curves and policies.',
        epilog='Scenarios in the sweep file are names (looked up on the scenario search path) or '
        "YAML paths; a relative path is relative to the sweep file's directory. A sweep has at "
        f'most {MAX_TRIALS:,} trials (counted before anything starts). Ctrl-C or SIGTERM stops '
        'the running trials and marks the results interrupted (exit 130 or 143); --resume runs '
        f'the rest. Exit 1 when every run failed, {SOME_FAILED} when some did (the rest '
        'finished; each failed run is a line saying why).',
    )
    p.add_argument('config', nargs='?', metavar='SWEEP.yaml', help='the sweep file')
    p.add_argument(
        '--address',
        metavar='HOST:PORT',
        help='join the Ray cluster whose head listens there (`ray start --head`); default: '
        'start Ray locally on every core',
    )
    p.add_argument(
        '--resume',
        metavar='DIR',
        help='continue the sweep in DIR: its finished trials are kept; the rest (those not run, '
        'stopped by an interruption, or failed) run',
    )
    p.add_argument(
        '--out',
        metavar='DIR',
        help='directory of the results (default: runs/sweeps/<name>-<time>)',
    )
    p.add_argument('--cpus', type=int, metavar='N', help='local Ray: CPUs to use (default: all)')
    p.add_argument('--no-plots', action='store_true', help='skip the curves')
    p.add_argument('--quiet', action='store_true', help='no progress lines')
    return p


def _out_dir(args, plan: SweepPlan) -> Path:
    if args.resume:
        return Path(args.resume)
    if args.out:
        return Path(args.out)
    stamp = datetime.datetime.now().strftime('%Y%m%d-%H%M%S')
    return Path('runs/sweeps') / f'{plan.name}-{stamp}'


def _load(args) -> SweepPlan:
    if args.resume:
        saved = Path(args.resume) / SAVED_FILE
        if not saved.is_file():
            raise SweepError(
                f'--resume {args.resume}: no {SAVED_FILE} there (not a sweep directory)'
            )
        if args.config and Path(args.config).read_bytes() != saved.read_bytes():
            raise SweepError(
                f'--resume {args.resume}: {args.config} differs from the sweep file it was '
                f'started with ({saved}); leave SWEEP.yaml out to resume that one'
            )
        base_file = Path(args.resume) / BASE_FILE
        lines = base_file.read_text(encoding='utf-8').splitlines() if base_file.is_file() else []
        base, name = ([line.strip() or None for line in lines] + [None, None])[:2]
        return load_plan(saved, base, name=name)  # no name: a sweep from before it was kept
    if not args.config:
        raise SweepError('give a sweep file (SWEEP.yaml) or --resume DIR')
    return load_plan(args.config)


def settings_text(plan: SweepPlan) -> str:
    search = (
        plan.search
        if plan.search == 'grid'
        else f'{plan.search}, {plan.trials} trials per scenario x learner'
    )
    params = (
        ', '.join(f'{k} {_values(v)}' for k, v in plan.params.items()) or 'none (harness settings)'
    )
    return (
        f'Sweep file {plan.path.name}: {len(plan.groups)} scenario x learner group(s), seeds '
        f'{", ".join(map(str, plan.seeds))}, mode {plan.mode}, search {search}; parameters: '
        f'{params}; {len(plan.extra)} extra trial(s). Greedy evaluation every '
        f'{plan.eval_every} episodes.'
    )


def _values(spec) -> str:
    if isinstance(spec, list):
        return '/'.join(map(str, spec))
    return f'{spec.low:g} to {spec.high:g}{" (log)" if spec.log else ""}'


def sweep(
    plan: SweepPlan, out: Path, *, address=None, cpus=None, plots=True, say=print
) -> tuple[Path, dict]:
    """Run what is not finished in ``out`` and write the report: (results.md, its status).
    Interrupted (after the report, marked so) when a signal stopped it."""
    from stealth_experiments.sweep_report import SweepStore, sweep_status, write_report
    from stealth_experiments.sweep_stop import clean_up, signals_stop
    from stealth_experiments.sweep_trials import objective

    store = SweepStore(out)
    done = store.finished()
    todo = [t for t in plan.fixed_trials() if t['id'] not in done]
    searches = []
    if plan.search == 'optuna':
        for group in plan.groups:
            base = plan.trial(group, {}, list(plan.seeds))
            mine = _group_trials(store.records(), base)
            seen = [(trial_records[0]['settings']['params'], objective(trial_records))
                    for trial_records in mine.values()]  # fmt: skip
            searches.append((group, base, plan.trials - len(mine), seen))
    remaining = len(todo) + sum(budget for *_, budget, _ in searches)
    say(f'sweep: {plan.name}: {len(done)} trial(s) already finished in {out}, {remaining} to run')
    interrupted = None
    with signals_stop() as mark:
        try:
            if remaining:
                _run(plan, todo, searches, store, out / 'ray', address, cpus, say)
        except Interrupted as stop:
            interrupted = stop
            clean_up(mark, say, plan.mode == 'ros' or any(t['mode'] == 'ros' for t in plan.extra))
    status = sweep_status(store, len(done) + remaining, interrupted and interrupted.name)
    report = write_report(store, plan.name, settings_text(plan), plots, status)
    if interrupted:
        interrupted.report, interrupted.status = report, status
        raise interrupted
    return report, status


def _run(plan, todo, searches, store, storage, address, cpus, say) -> None:
    from stealth_experiments.sweep_engine import Engine

    options = {'cpus_per_trial': plan.cpus_per_trial, 'max_failures': plan.max_failures}
    with Engine(address, cpus, say) as engine:
        engine.run_fixed(todo, store.add, **options)
        for group, base, budget, seen in searches:
            say(f'sweep: optuna search on {group.label}: {budget} trial(s), {len(seen)} known')
            engine.run_search(
                base, plan.optuna_space(), budget, seen, store.add, storage,
                seed=plan.seed, **options,
            )  # fmt: skip


def _group_trials(records: list[dict], base: dict) -> dict[str, list[dict]]:
    """The finished trials (id: records) of one optuna group, whatever their parameters."""
    keys = ('mode', 'scenario', 'goal', 'learner', 'episodes', 'eval_every', 'slip')
    found: dict[str, list[dict]] = {}
    for record in records:
        if all(record['settings'][k] == base[k] for k in keys):
            found.setdefault(record['trial'], []).append(record)
    return found


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    prog = 'stealth sweep'
    try:
        plan = _load(args)
        if args.cpus is not None and args.cpus < 1:
            raise SweepError(f'--cpus must be >= 1, got {args.cpus}')
        if args.address:
            from stealth_experiments.sweep_engine import check_address

            check_address(args.address)
    except (SweepError, RuntimeError) as error:
        print(f'{prog}: {error}', file=sys.stderr)
        return 1
    out = _out_dir(args, plan)
    out.mkdir(parents=True, exist_ok=True)
    if not args.resume:
        shutil.copyfile(plan.path, out / SAVED_FILE)
        (out / BASE_FILE).write_text(
            f'{plan.path.parent.resolve()}\n{plan.name}\n', encoding='utf-8'
        )
    say = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    try:
        report, status = sweep(plan, out, address=args.address, cpus=args.cpus,
                               plots=not args.no_plots, say=say)  # fmt: skip
    except Interrupted as stop:
        from stealth_experiments.sweep_report import status_line

        if stop.status is not None:
            print(stop.report)
            print(f'{prog}: {status_line(stop.status, out)}', file=sys.stderr)
        else:
            print(f'{prog}: interrupted by {stop.name}; finished trials are kept: --resume {out}',
                  file=sys.stderr)  # fmt: skip
        return stop.exit_code
    except KeyboardInterrupt:
        print(f'{prog}: interrupted; finished trials are kept: --resume {out}', file=sys.stderr)
        return 130
    except (OSError, RuntimeError, ValueError) as error:
        print(f'{prog}: {error}; finished trials are kept: --resume {out}', file=sys.stderr)
        return 1
    print(report)
    if status['status'] == 'failed':
        from stealth_experiments.sweep_report import status_line

        print(f'{prog}: {status_line(status, out)}', file=sys.stderr)
        return 1
    failed, runs = failed_runs(out)
    if failed:
        print(f'{prog}: {len(failed)} of {runs} runs failed, the rest finished (exit '
              f'{SOME_FAILED}); `stealth sweep --resume {out}` runs the failed ones again:',
              file=sys.stderr)  # fmt: skip
        for line in failed[:MAX_FAILED_LINES]:
            print(f'  {line}', file=sys.stderr)
        if len(failed) > MAX_FAILED_LINES:
            print(f'  ... and {len(failed) - MAX_FAILED_LINES} more', file=sys.stderr)
        return SOME_FAILED
    return 0


def failed_runs(out: Path) -> tuple[list[str], int]:
    """(one line per failed run of the sweep in ``out``: its trial, seed and error; the runs)."""
    from stealth_experiments.sweep_report import SweepStore

    records = SweepStore(out).records()
    failed = [
        f'{r["trial"]} seed {r["seed"]}: {r.get("error") or "no error text"}'
        for r in records
        if r['status'] != 'ok'
    ]
    return failed, len(records)


if __name__ == '__main__':
    sys.exit(main())
