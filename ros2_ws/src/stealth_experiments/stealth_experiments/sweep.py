"""`stealth sweep`: scenarios x learners x seeds x hyperparameters, on Ray.

    stealth sweep docs/sweeps/example.yaml                 # a local Ray on every core
    stealth sweep SWEEP.yaml --address HOST:6379           # an existing cluster (`ray start`)
    stealth sweep --resume runs/sweeps/example-<time>      # only the trials not finished yet

The sweep file (sweep_plan) is checked completely before Ray starts; each problem is one line
naming the field. Trials run on sweep_engine (Ray Tune), each through sweep_trials (in-process,
or `stealth train` in its own ROS domain); their records land in the sweep's directory as they
end (sweep_report), so a sweep stopped half-way and given to --resume reruns only the rest, and
the table, best configurations and curves are written at the end.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import datetime
from pathlib import Path
import shutil
import sys

from stealth_experiments.sweep_plan import SweepError, SweepPlan, load_plan

SAVED_FILE = 'sweep.yaml'


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='stealth sweep',
        description='Train learners over scenarios, seeds and hyperparameters (grid, random or '
        'Optuna search) on Ray: a local Ray on every core, or a cluster with --address. '
        'Writes results.csv, results.md (best configuration per scenario), curves and policies.',
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
        help='continue the sweep in DIR: its finished trials are kept, the rest run',
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
        return load_plan(saved)
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


def sweep(plan: SweepPlan, out: Path, *, address=None, cpus=None, plots=True, say=print) -> Path:
    """Run what is not finished in ``out`` and write the report; returns results.md."""
    from stealth_experiments.sweep_engine import Engine
    from stealth_experiments.sweep_report import SweepStore, write_report
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
    if remaining:
        storage = out / 'ray'
        options = {'cpus_per_trial': plan.cpus_per_trial, 'max_failures': plan.max_failures}
        with Engine(address, cpus, say) as engine:
            engine.run_fixed(todo, store.add, storage, **options)
            for group, base, budget, seen in searches:
                say(f'sweep: optuna search on {group.label}: {budget} trial(s), {len(seen)} known')
                engine.run_search(
                    base, plan.optuna_space(), budget, seen, store.add, storage,
                    seed=plan.seed, **options,
                )  # fmt: skip
    return write_report(store, plan.name, settings_text(plan), plots)


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
    say = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    try:
        report = sweep(plan, out, address=args.address, cpus=args.cpus,
                       plots=not args.no_plots, say=say)  # fmt: skip
    except KeyboardInterrupt:
        print(f'{prog}: interrupted; finished trials are kept: --resume {out}', file=sys.stderr)
        return 130
    except (OSError, RuntimeError, ValueError) as error:
        print(f'{prog}: {error}; finished trials are kept: --resume {out}', file=sys.stderr)
        return 1
    print(report)
    return 0


if __name__ == '__main__':
    sys.exit(main())
