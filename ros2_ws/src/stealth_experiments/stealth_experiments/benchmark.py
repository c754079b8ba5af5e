"""`stealth benchmark`: methods x scenarios x tracks, on the Ray engine of the sweeps.

    stealth benchmark --set test --count 20 --out runs/benchmark      # or scenario files
    stealth benchmark --set generated --seeds 1710000 --count 50 --width 50 --height 40 --lights 8

``Preset``: the defaults of a command that is this benchmark with other defaults
(`stealth generalist`, ``generalist_benchmark``).

The scenarios (``benchmark_plan``: a named set, generated test scenarios and the shipped maps'
goals, or files), the methods and their tracks (``benchmark_methods``), one trial per scenario,
goal and method on a local Ray over ``--jobs`` CPUs (``sweep_engine``, with a progress line per
trial) or, with ``--jobs 1``, one after another in this process without Ray (a line per trial).
Written to ``--out`` (``benchmark_report``): results.csv, summary.md, benchmark.png, and with
the learning track (``--tracks learning``, ``benchmark_learning``) learning.csv and learning.png.

Before anything runs (``benchmark_checks``), one line and exit 1 for: a scenario name that is not
on the search path, a method asked for on none of the tracks asked for, an unusable --policy or
--policy-file (a policy file runs only on the scenario goals it was trained on, refused where it
was trained on none of them), --out holding an earlier benchmark's results (unless --force), an
unusable --cache (``benchmark_cache``); --jobs beyond the CPUs this process may use is capped
(one line). A scenario file that cannot be read is named (one line) and its rows are marked
failed; a method that raises on a scenario fails its row only. SIGINT or SIGTERM
(``sweep_stop``): the trials done are written, the rest marked interrupted, and the exit status
is 130 (143).

Each trial's rows are also written to ``--out``'s journal as the trial ends
(``benchmark_journal``: trials.jsonl, synced), so a benchmark killed outright loses only the
trials then running; ``--resume`` goes on with it: the trials the journal holds from the same
settings and inputs are kept, the others run, and the results of all are written.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
import dataclasses
from pathlib import Path
import sys
import time

from stealth_core.scenario_generator import FINAL_TEST_SEED, MOVING, Options

from stealth_experiments import sweep_stop
from stealth_experiments.benchmark_cache import check_cache
from stealth_experiments.benchmark_checks import (
    BenchmarkError,
    check_out,
    check_scenarios,
    check_tracks,
    policy_cases,
)
from stealth_experiments.benchmark_journal import JOURNAL, JournalError, Writer, read, reusable
from stealth_experiments.benchmark_learning import LEARNING_SEEDS
from stealth_experiments.benchmark_learning_report import write_learning_csv, write_learning_plot
from stealth_experiments.benchmark_methods import (
    DEFAULT_TRACKS,
    GENERALISTS,
    LEARNERS,
    METHODS,
    TRACKS,
    failed_row,
    learning_extra,
    method_name,
    run_case,
)
from stealth_experiments.benchmark_plan import (
    DEFAULT_COUNT,
    SETS,
    SHIPPED,
    TEST_SEED,
    check_seeds,
    file_case,
    set_cases,
    trials,
)
from stealth_experiments.benchmark_report import (
    RESULT_FILES,
    write_csv,
    write_plot,
    write_summary,
)
from stealth_experiments.harness import DEFAULT_EPISODES, MOVING_EPISODES, STREAK
from stealth_experiments.options import add_episodes_option, add_output_options, capped_jobs
from stealth_experiments.sweep_pool import duration as _duration

PROG = 'stealth benchmark'
DEFAULT_OUT = Path('runs/benchmark')
# The generalist and its twins are default methods where the learning extra is installed
# (default_methods).
DEFAULT_METHODS = tuple(m for m in METHODS if m != 'policy' and m not in GENERALISTS)


def default_methods() -> list[str]:
    """DEFAULT_METHODS, and the generalist and its twins when the learning extra is installed
    (not the cycle rule: on static lights it is the hand-set twin; `stealth generalist` has it)."""
    twins = [m for m in GENERALISTS if m != 'generalist (cycle rule)']
    return [*DEFAULT_METHODS, *(twins if learning_extra() else ())]


@dataclasses.dataclass(frozen=True)
class Preset:
    """A command that is the benchmark with other defaults: its name, what it says it does,
    its default methods (a function: the generalist's depend on the learning extra) and their
    --help, set and --out."""

    prog: str
    description: str
    methods: Callable[[], list[str]]
    methods_help: str
    set: str
    out: Path
    prints_summary: bool = False  # its tables on stdout at the end, not only summary.md's path


BENCHMARK = Preset(
    PROG,
    'Benchmark the planners, the replanning baselines, the tabular learners, a learned policy '
    'and the generalist (and its hand-set and untrained twins) on a test set of scenarios, on '
    'the full-knowledge and the sensed track: results.csv, summary.md (undetected and success '
    "rates, normalised regret, mean return, path and exposure against value iteration's "
    'optimum) and benchmark.png; with --tracks learning, how fast each learner learns: '
    'learning.csv and learning.png.',
    default_methods,
    'all but policy (policy too with --policy; the generalist and its twins where the '
    'learning extra is installed)',
    'test',
    DEFAULT_OUT,
)


def parser(preset: Preset = BENCHMARK) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=preset.prog,
        description=preset.description,
        epilog='Tracks per method: value iteration (the oracle), A*, the generalist and its twins '
        'on full and sensed; Dark Path and policy on the full track only; the learners on the '
        'full and the learning track; the replanners on the sensed track only. The learning '
        'track (not a default: it costs several times the default run): each learner trained on '
        f'--learning-seeds seeds (from --seed on) for its budget, a greedy evaluation after '
        f'every episode; per scenario goal the median over the seeds of the episodes to the '
        f'criterion (until the first of {STREAK} evaluations in a row that meet the success '
        'criterion), the detections, environment steps and wall time before it '
        '(results.csv, summary.md, learning.csv per seed), and learning.png, the cumulative '
        'training detections against episodes per method, median over the seeds and min-max '
        'band (the regret curve). The generalist needs the learning extra (make learn): a '
        'default method only where it is installed; asked for without it, its rows fail saying '
        'so and the rest run. '
        f'Test scenarios are generated from seed --seeds on (default {TEST_SEED:,}, the test '
        'range) into the cache, each with a provenance record, and generated again where a file '
        f'no longer matches it. Seeds {FINAL_TEST_SEED:,} and up are the final test range, '
        'evaluated once at the end of an issue: refused unless --final-test-range is given '
        '(then only they). Refused before anything runs (one line, exit 1): an unknown scenario, '
        'method or track, a policy file trained on none of the scenario goals, an --out with '
        'earlier results (without --force), a --cache that is not one; --jobs is capped at the '
        'CPUs this process may use. A scenario file that cannot be read is named and its rows '
        'marked failed; the rest run. Ctrl-C or SIGTERM writes what is done, marks the rest '
        'interrupted and exits 130 (143). Exit 1 when no row ran.',
    )
    p.add_argument(
        'scenarios',
        nargs='*',
        metavar='SCENARIO',
        help='scenario names or YAML paths, each at its default goal (instead of --set)',
    )
    p.add_argument(
        '--set',
        choices=SETS,
        help=f'a named set: test (--count generated test scenarios + every goal of '
        f'{", ".join(SHIPPED)}), shipped, generated (default: {preset.set}, unless scenarios '
        'are given)',
    )
    p.add_argument(
        '--count',
        type=int,
        default=DEFAULT_COUNT,
        help='generated test scenarios in the set (default: %(default)s)',
    )
    add_generated_options(p)
    p.add_argument(
        '--cache',
        type=Path,
        help='where generated test scenarios are written and reused, each with its provenance '
        'record (default: OUT/scenarios)',
    )
    p.add_argument(
        '--tracks',
        nargs='+',
        choices=TRACKS,
        default=list(DEFAULT_TRACKS),
        help=f'default: {" ".join(DEFAULT_TRACKS)} (learning: asked for by name)',
    )
    p.add_argument(
        '--learning-seeds',
        type=int,
        default=LEARNING_SEEDS,
        help="the learning track's seeds per learner and scenario goal, from --seed on "
        '(default: %(default)s)',
    )
    p.add_argument(
        '--methods',
        nargs='+',
        metavar='METHOD',
        help=f'default: {preset.methods_help}: vi, astar, dark-path, replan-dark, replan-lit, '
        + ', '.join(LEARNERS)
        + ', policy, generalist, generalist-hand-set, generalist-dark-steps, '
        'generalist-untrained, generalist-cycle-rule',
    )
    add_episodes_option(
        p, "the learners' training budget per scenario, in episodes (default: the harness's, "
    )
    p.add_argument('--seed', type=int, default=0, help="learners' and episodes' seed (default 0)")
    p.add_argument(
        '--policy',
        type=Path,
        help='a learned policy file (method policy): it runs on the scenario goals it was '
        'trained on only (by name, goal, map and lights)',
    )
    p.add_argument(
        '--policy-file',
        type=Path,
        help="the generalist's weights (method generalist; default: the shipped "
        'stealth_learn/policies/generalist-full.npz)',
    )
    add_output_options(p, 'trials', preset.out, 'benchmark.png')
    p.add_argument(
        '--force',
        action='store_true',
        help=f"overwrite an earlier benchmark's results in --out ({', '.join(RESULT_FILES)}, "
        f'{JOURNAL})',
    )
    p.add_argument(
        '--resume',
        action='store_true',
        help=f'go on with the benchmark in --out: its journal ({JOURNAL}, each trial written '
        'as it ends) gives the trials run before with the same settings and inputs; only the '
        'others run, then the results of all are written',
    )
    return p


def add_generated_options(p: argparse.ArgumentParser) -> None:
    """The generated set's seeds and generator options."""
    p.add_argument(
        '--seeds',
        type=int,
        metavar='START',
        help=f'the first generated test seed (default {TEST_SEED:,}; with --final-test-range '
        f'{FINAL_TEST_SEED:,}): seeds START .. START + --count - 1, below {FINAL_TEST_SEED:,}',
    )
    defaults = Options()
    for name, unit in (('width', 'm'), ('height', 'm'), ('lights', 'searchlights')):
        p.add_argument(
            f'--{name}',
            type=int,
            help=f"generated buildings' {name} ({unit}; default: {getattr(defaults, name)})",
        )
    p.add_argument(
        '--moving',
        choices=MOVING,
        help="generated buildings' moving lights (the generator's --moving; default: "
        f'{defaults.moving})',
    )
    p.add_argument(
        '--final-test-range',
        action='store_true',
        help=f'evaluate the final test range (seeds {FINAL_TEST_SEED:,} and up): once, at the '
        'end of an issue, never while developing; refused without this flag',
    )


GENERATED_OPTIONS = ('seeds', 'width', 'height', 'lights', 'moving')


def generated_options(args, generated: bool) -> tuple[int, Options]:
    """(the first seed, the generator's options) of the generated set; ValueError, one line,
    for seeds outside the range asked for, options out of the generator's ranges, or any of
    them given where nothing is generated."""
    given = [f'--{n}' for n in GENERATED_OPTIONS if getattr(args, n) is not None]
    given += ['--final-test-range'] if args.final_test_range else []
    if given and not generated:
        raise ValueError(
            f'{", ".join(given)}: for generated scenarios (--set test or generated), not '
            'for scenario files or --set shipped'
        )
    first = args.seeds
    if first is None:
        first = FINAL_TEST_SEED if args.final_test_range else TEST_SEED
    check_seeds(first, args.count, args.final_test_range)
    sizes = {n: getattr(args, n) for n in GENERATED_OPTIONS[1:] if getattr(args, n) is not None}
    options = Options(**sizes)
    options.check()  # GenerationError, a ValueError: '--width: expected ...'
    return first, options


def main(argv: Sequence[str] | None = None, preset: Preset = BENCHMARK) -> int:
    p = parser(preset)
    args = p.parse_args(argv)
    prog = preset.prog
    if args.scenarios and args.set:
        p.error('give scenarios or --set, not both')
    if args.resume and args.force:
        p.error('give --resume (go on) or --force (start over), not both')
    if (
        args.count < 1
        or args.jobs < 1
        or args.learning_seeds < 1
        or (args.episodes is not None and args.episodes < 1)
    ):
        p.error('--count, --jobs, --learning-seeds and --episodes must be >= 1')
    say = _say
    chosen = args.set or preset.set
    generated = not args.scenarios and chosen != 'shipped'
    cache = args.cache or args.out / 'scenarios'
    try:  # everything a user gave, before anything is made or run (benchmark_checks)
        first, options = generated_options(args, generated)
        methods = _methods(args, preset)
        check_tracks(_asked(args, methods), args.tracks)
        check_scenarios(args.scenarios, Path.cwd())
        check_out(args.out, args.force or args.resume)
        if args.resume and not (args.out / JOURNAL).is_file():
            raise BenchmarkError(
                f'--resume: {args.out / JOURNAL} does not exist: nothing to go on with; run '
                'without --resume'
            )
        if generated:
            check_cache(cache)
    except ValueError as error:  # BenchmarkError, CacheError, PolicyFileError: one line
        print(f'{prog}: {error}', file=sys.stderr)
        return 1
    jobs, capped = capped_jobs(args.jobs)
    if capped:
        say(f'{prog}: {capped}')
    wanting = [m for m in methods if m in GENERALISTS]
    if wanting and not learning_extra():
        say(f'{prog}: {", ".join(wanting)} need the learning extra (jax, flax, optax): install '
            'it with make learn; their rows are marked failed')  # fmt: skip
    notes = []
    try:
        if args.scenarios:
            cases = [file_case(entry, Path.cwd()) for entry in args.scenarios]
        else:
            cases = set_cases(chosen, args.count, cache, notes.append, first, options)
        policy_on = None
        if 'policy' in methods:
            policy_on, policy_notes = policy_cases(args.policy, cases)
            notes += policy_notes
    except ValueError as error:  # CacheError, BenchmarkError: one line
        print(f'{prog}: {error}', file=sys.stderr)
        return 1
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        print(f'{prog}: --out {args.out}: cannot be made ({error.strerror or error})',
              file=sys.stderr)  # fmt: skip
        return 1
    for line in notes:
        say(f'{prog}: {line}')
    for case in cases:
        if case.error:
            where = '' if case.error.startswith(case.file) else f'{case.file}: '
            say(f'{prog}: {where}{case.error}; its rows are marked failed')
    laid = trials(
        cases, methods, args.tracks, episodes=args.episodes, seed=args.seed,
        learning_seeds=args.learning_seeds,
        policy=str(args.policy.resolve()) if args.policy else None,
        policy_file=str(args.policy_file.resolve()) if args.policy_file else None,
        policy_cases=policy_on,
    )  # fmt: skip
    say(f'benchmark: {_count(len(cases), "scenario goal")} x {_count(len(methods), "method")}: '
        f'{_counted(laid)}')  # fmt: skip
    done: dict[str, list[dict]] = {}
    try:
        if args.resume:
            done.update(_resumed(args.out / JOURNAL, laid, say))
        journal = Writer(args.out / JOURNAL, fresh=not args.resume)
    except JournalError as error:
        print(f'{prog}: {error}', file=sys.stderr)
        return 1
    resumed = len(done)
    started = time.monotonic()
    note, code = '', 0
    try:
        with journal:
            run_trials(laid, done, jobs=jobs, say=say, journal=journal)
    except KeyboardInterrupt as stop:  # sweep_stop.Interrupted
        name = getattr(stop, 'name', 'SIGINT')
        code = getattr(stop, 'exit_code', 130)
        note = f'Interrupted by {name}: {len(done)} of {len(laid)} trials done; the rest marked'
        note += f' interrupted; go on with the same command and --resume ({JOURNAL}).'
    rows = collect(laid, done)
    elapsed = time.monotonic() - started
    made = ''
    if generated:
        made = (
            f'Generated: seeds {first:,} to {first + args.count - 1:,}, {options.width} x '
            f'{options.height} m, {options.lights} lights ({options.difficulty}, moving: '
            f'{options.moving}). '
        )
    settings = _settings(args, methods, laid, elapsed, len(cases), jobs, made)
    if resumed:
        settings += (f' Resumed: {_count(resumed, "trial")} from {JOURNAL} (run before), '
                     f'{len(done) - resumed} run now in the time given.')  # fmt: skip
    csv_file, summary_file, plot, seeds_file, curves = (args.out / name for name in RESULT_FILES)
    try:
        write_csv(csv_file, rows)
        summary = write_summary(summary_file, rows, settings, note)
        if write_learning_csv(seeds_file, rows) is None:
            seeds_file.unlink(missing_ok=True)  # not an earlier benchmark's beside these
        for picture, draw in ((plot, write_plot), (curves, write_learning_plot)):
            if args.no_plots or draw(picture, rows) is None:
                picture.unlink(missing_ok=True)  # not an earlier benchmark's (--force)
    except OSError as error:
        print(f'{prog}: cannot write the results to {args.out} ({error.strerror or error})',
              file=sys.stderr)  # fmt: skip
        return 1
    failed = sum(r['status'] == 'failed' for r in rows)
    print(summary.read_text(encoding='utf-8') if preset.prints_summary else summary)
    if code:
        print(f'{prog}: {note} Partial results in {args.out}', file=sys.stderr)
        return code
    if failed:
        print(f'{prog}: {failed} of {len(rows)} rows failed (see {summary})', file=sys.stderr)
    return 1 if failed == len(rows) else 0


def _count(number: int, what: str) -> str:
    return f'{number} {what}{"" if number == 1 else "s"}'


def _counted(laid: list[dict]) -> str:
    """What the benchmark runs, counted: trials (a method on a scenario goal, over its tracks)
    and rows (a trial's tracks, one row each in results.csv)."""
    rows = sum(len(trial['tracks']) for trial in laid)
    return (
        f'{_count(len(laid), "trial")} (a method on a scenario goal), '
        f'{_count(rows, "row")} (a trial on each of its tracks)'
    )


def _say(line: str) -> None:
    print(line, flush=True)


def _asked(args, methods: list[str]) -> list[str]:
    """The methods asked for by name (--methods, or by --policy and --policy-file), not the
    defaults: each must run on a track asked for."""
    if args.methods:
        return methods
    return [m for m in methods if m == 'policy' or (m == 'generalist' and args.policy_file)]


def _methods(args, preset: Preset = BENCHMARK) -> list[str]:
    names = [method_name(m) for m in args.methods] if args.methods else preset.methods()
    if args.policy and 'policy' not in names:
        names.append('policy')
    if args.policy_file and 'generalist' not in names:
        names.append('generalist')
    if any(m in GENERALISTS for m in names) and learning_extra():
        # the twins take the file's architecture
        # a missing, corrupt or foreign weights file: refused here, one line naming it
        # (PolicyFileError, LayoutError: ValueErrors); the parameters' shapes are found
        # abstractly: no JAX backend, no XLA threads in this process before Ray starts workers
        from stealth_learn import policy_file

        path = args.policy_file or policy_file.SHIPPED
        policy_file.load(path, None)  # static or time-aware: the scenario checked in its row
    if 'policy' in names:
        if not args.policy:
            raise ValueError('--methods policy needs --policy FILE')
        from stealth_agent.policy_store import load_policy

        load_policy(args.policy)  # PolicyFileError (a ValueError) naming the file
    return list(dict.fromkeys(names))


def _resumed(path: Path, laid: list[dict], say: Callable[[str], None]) -> dict:
    """{trial id: rows} the journal at ``path`` holds for ``laid`` (``benchmark_journal``);
    said: how many, and how many it holds from other settings or inputs (run again)."""
    kept, stale = reusable(read(path, say), laid)
    say(f'benchmark: resuming: {len(kept)} of {len(laid)} trials from {path}')
    if stale:
        say(f'benchmark: {_count(stale, "trial")} of the journal ran with other settings or '
            'inputs (scenario file, weights, budget, seed): run again')  # fmt: skip
    return kept


def run_trials(
    laid: list[dict], done: dict, *, jobs: int, say: Callable[[str], None], journal=None
) -> None:
    """Each trial's rows into ``done`` (by trial id) as it ends, and into ``journal`` (a
    ``benchmark_journal.Writer``) where given; trials already in ``done`` (resumed) and trials
    of unreadable scenarios are not run. Raises sweep_stop.Interrupted on SIGINT or SIGTERM."""
    runnable = [t for t in laid if not t['error'] and t['id'] not in done]
    by_id = {t['id']: t for t in runnable}

    def finished(trial: dict, rows: list[dict]) -> None:
        done[trial['id']] = rows
        if journal is not None:
            journal.add(trial, rows)

    with sweep_stop.signals_stop():
        if jobs <= 1 or len(runnable) <= 1:
            started = time.monotonic()
            for k, trial in enumerate(runnable, start=1):
                finished(trial, run_case(trial))
                failed = sum(r['status'] != 'ok' for rows in done.values() for r in rows)
                mean = (time.monotonic() - started) / k
                say(
                    f'benchmark: trial finished: {k}/{len(runnable)} done ({trial["id"]}), '
                    f'{failed} row(s) failed, ETA {_duration(mean * (len(runnable) - k))}'
                )
            return
        from stealth_experiments.sweep_engine import Engine

        def keep(records: list[dict]) -> None:
            if records:
                trial = by_id.get(records[0]['trial'])
                if trial is None:
                    done[records[0]['trial']] = records
                else:
                    finished(trial, records)

        with Engine(None, jobs, say) as engine:
            engine.run_fixed(runnable, keep, runner=run_case, label='benchmark')


def collect(laid: list[dict], done: dict[str, list[dict]]) -> list[dict]:
    """The rows of every trial in order: those that ran, failed rows of unreadable scenarios and
    of trials whose worker was lost, interrupted rows of trials not done."""
    rows = []
    for trial in laid:
        found = done.get(trial['id'])
        if found and all('track' in r for r in found):
            rows += found
            continue
        if trial['error']:
            status, error = 'failed', trial['error']
        elif found:  # a lost worker's record (sweep_engine): no rows, its error
            status, error = 'failed', found[0].get('error', 'no result came back')
        else:
            status, error = 'interrupted', 'not run: the benchmark was interrupted'
        for track in trial['tracks']:
            base = {
                'scenario': trial['label'],
                'goal': trial['goal'] or '',
                'track': track,
                'method': trial['method'],
                'file': trial['file'],
            }
            rows.append(failed_row(base, error, status))
    return rows


def _settings(
    args, methods: list[str], laid: list[dict], elapsed: float, cases: int, jobs: int, made=''
) -> str:
    learners = [m for m in methods if m in LEARNERS]
    budget = ''
    if learners:
        if args.episodes:
            budget = f' Learners trained {args.episodes} episodes per scenario goal'
        else:
            budget = (
                " Learners trained for the harness's budget ("
                + ', '.join(
                    f'{m} {DEFAULT_EPISODES[m]}, {MOVING_EPISODES[m]} where lights move'
                    for m in learners
                )
                + ') per scenario goal'
            )
        if 'full' in args.tracks:
            budget += ', then one greedy episode (full track)'
        if 'learning' in args.tracks:
            budget += (
                f'; on the learning track on {args.learning_seeds} seeds from {args.seed} on, '
                'a greedy evaluation after every episode'
            )
        budget += '.'
    if any(m in GENERALISTS for m in methods):
        budget += f' Generalist weights: {args.policy_file or "the shipped generalist-full.npz"}.'
    alone = jobs <= 1 or sum(not trial['error'] for trial in laid) <= 1  # as run_trials runs
    where = 'one after another' if alone else f'local Ray, {jobs} CPUs'
    return (
        f'{made}Tracks: {", ".join(args.tracks)}. Methods: {", ".join(methods)}.{budget} Seed '
        f'{args.seed}. {_counted(laid)} in {elapsed:.0f} s ({where}): '
        f'{cases * 60 / max(elapsed, 1e-9):.1f} scenario goals/min.'
    )


if __name__ == '__main__':
    sys.exit(main())
