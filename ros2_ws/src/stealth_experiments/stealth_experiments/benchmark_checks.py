"""What `stealth benchmark` checks before it runs anything: every scenario name, each method
asked for against the tracks asked for, the output directory, and the scenario a policy file was
trained on. A refusal is one line (``BenchmarkError``) naming what was wrong and what is
expected. No Ray, no rclpy.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from stealth_agent.policy_store import content_differences, load_policy
from stealth_bringup.rollout_source import CONTENT_WORDS
from stealth_core.scenario import ScenarioError, content_identity, find_scenario, load_scenario
from stealth_core.task import StealthTask

from stealth_experiments.benchmark_journal import JOURNAL
from stealth_experiments.benchmark_methods import METHODS
from stealth_experiments.benchmark_plan import Case
from stealth_experiments.benchmark_report import RESULT_FILES
from stealth_experiments.harness import scenario_argument


class BenchmarkError(ValueError):
    """A benchmark that cannot start: the message is one line."""


def check_scenarios(entries: Sequence[str], base: Path) -> None:
    """BenchmarkError for a scenario name not on the search path (the line lists the known
    names) or a scenario file that does not exist: a misspelling is refused, not run as a
    scenario whose rows fail (a file that exists but cannot be read is: its rows fail)."""
    for entry in entries:
        try:
            path = find_scenario(scenario_argument(entry, base))
        except ScenarioError as error:
            raise BenchmarkError(str(error)) from None
        if not path.exists():
            raise BenchmarkError(f'scenario {entry}: no such file ({path})')


def check_tracks(methods: Sequence[str], tracks: Sequence[str]) -> None:
    """BenchmarkError for a method asked for that runs on none of the tracks asked for (it
    would have no row)."""
    for method in methods:
        if not set(METHODS[method]) & set(tracks):
            runs = ' and '.join(METHODS[method])
            raise BenchmarkError(
                f'method {method!r} runs on the {runs} track only, not on --tracks '
                f'{" ".join(tracks)}'
            )


def check_out(out: Path, force: bool) -> list[str]:
    """The earlier results in ``out`` (RESULT_FILES there), which --force lets the benchmark
    overwrite; BenchmarkError when there are some without --force."""
    if out.exists() and not out.is_dir():
        raise BenchmarkError(f'--out {out}: not a directory')
    earlier = [name for name in (*RESULT_FILES, JOURNAL) if (out / name).exists()]
    if earlier and not force:
        raise BenchmarkError(
            f'--out {out}: holds the results of an earlier benchmark ({", ".join(earlier)}); '
            'give a new or empty directory, or --force to overwrite them'
        )
    return earlier


def policy_cases(path: Path, cases: Sequence[Case]) -> tuple[list[Case], list[str]]:
    """(the cases the policy file was trained on, notes): its scenario and goal by the title it
    records, its map and lights by their hashes (``policy_store.content_differences``, as
    `stealth rollout` checks them). BenchmarkError naming the file, the scenario it was trained on
    and the ones asked for when it was trained on none of them; PolicyFileError for a file that
    cannot be read. Cases that cannot be read are kept (their rows fail, naming the file)."""
    saved = load_policy(path)
    trained = str(saved.scenario.get('title') or '')
    unread = [case for case in cases if case.error]
    fits, asked, other = [], [], []
    unhashed = False
    for case in cases:
        if case.error:
            continue
        scenario = load_scenario(case.file)
        title = StealthTask(scenario, case.goal).title
        asked.append(title)
        if trained and title != trained:
            continue
        keys = content_differences(saved.scenario, content_identity(scenario))
        if keys is None and not trained:
            raise BenchmarkError(
                f'--policy {path} records neither the scenario it was trained on nor its map '
                'and lights; train it again'
            )
        if keys:
            other.append((case, ' and '.join(CONTENT_WORDS[key] for key in keys)))
            continue
        unhashed = unhashed or keys is None
        fits.append(case)
    if not asked:
        return unread, []
    if not fits and other:
        case, words = other[0]
        raise BenchmarkError(
            f'--policy {path} was trained on {trained!r} with {words} than {case.file} has (the '
            'same name, other content); give the scenario file it was trained on, or train a '
            'policy on this one'
        )
    if not fits:
        where = repr(asked[0]) if len(asked) == 1 else f'any of the {len(asked)} asked for'
        if len(asked) > 1:
            where += f' ({", ".join(repr(title) for title in asked[:2])}, ...)'
        raise BenchmarkError(
            f'--policy {path} was trained on {trained!r}, not on {where}; give that scenario '
            '(a name or file runs at its default goal, --set shipped at every shipped goal)'
        )
    notes = []
    if unhashed:
        notes.append(
            f'--policy {path} records no map or lights hash (saved before policies did): only '
            'its scenario name is checked'
        )
    if len(fits) < len(asked):
        notes.append(
            f'--policy {path} was trained on {trained!r}: the method policy runs there only, '
            f'not on the other {len(asked) - len(fits)} scenario goal(s)'
        )
    return [case for case in cases if case in fits or case in unread], notes
