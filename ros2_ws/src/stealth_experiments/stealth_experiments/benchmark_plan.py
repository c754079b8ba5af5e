"""What a benchmark runs: its scenarios (a named set or files), their goals, and the trials
(one per scenario, goal and method, over the method's tracks). No Ray, no rclpy.

Sets (``SETS``):

- ``test``: ``count`` generated test scenarios, seeds ``first`` (default ``TEST_SEED``),
  ``first + 1``, ... (``scenario_generator.SEED_RANGES``' test range, never used for tuning;
  below ``FINAL_TEST_SEED``, the development part, unless the final test range is asked for by
  name), generated on the fly with the generator's default options (or the size and lights
  given) into a cache directory (``benchmark_cache``: a scenario there is reused while its
  provenance record holds), plus every goal of the shipped maps;
- ``shipped``: every goal of the shipped maps (``SHIPPED``) only;
- ``generated``: the generated test scenarios only.

Scenarios given by name or file instead are run at their default goal. A scenario that cannot
be read (or generated) is a case with its ``error``: the benchmark names the file, marks its
rows failed and goes on with the rest. The method ``policy`` runs only on the cases its file
was trained on (``benchmark_checks.policy_cases``).
"""

from __future__ import annotations

from collections.abc import Callable, Collection
import dataclasses
from pathlib import Path
import re

from stealth_core.scenario import find_scenario, load_scenario
from stealth_core.scenario_generator import (
    FINAL_TEST_SEED,
    SEED_RANGES,
    GenerationError,
    Options,
    scenario_name,
)

from stealth_experiments.benchmark_cache import OPTIONS, cached_scenario, check_cache
from stealth_experiments.benchmark_methods import METHODS, TRACKS
from stealth_experiments.harness import scenario_argument, scenario_label

SHIPPED = ('simple-maze', 'map1', 'lgfloor', 'floorplan')  # the shipped maps (static lights)
SETS = ('test', 'shipped', 'generated')
TEST_SEED = SEED_RANGES['test'][0]
DEFAULT_COUNT = 20


def check_seeds(first: int, count: int, final: bool) -> None:
    """ValueError, one line, unless seeds ``first`` .. ``first + count - 1`` are all in the
    test range's development part (``TEST_SEED`` up to ``FINAL_TEST_SEED``) or, with
    ``final``, all in the final test range (``FINAL_TEST_SEED`` and up): the final range is
    evaluated once, at the end, and only when asked for by name."""
    last = first + count - 1
    if final and first < FINAL_TEST_SEED:
        raise ValueError(
            f'--final-test-range: the final test range starts at seed {FINAL_TEST_SEED:,}, '
            f'--seeds starts at {first:,}'
        )
    if not final and first < TEST_SEED:
        raise ValueError(
            f'--seeds: expected a test seed >= {TEST_SEED:,} (the training and validation '
            f'ranges lie below), got {first:,}'
        )
    if not final and last >= FINAL_TEST_SEED:
        raise ValueError(
            f'--seeds {first:,} --count {count}: seeds up to {last:,} reach the final test range '
            f'({FINAL_TEST_SEED:,} and up), which is evaluated once at the end of an issue; '
            'give --final-test-range to evaluate it'
        )


@dataclasses.dataclass(frozen=True)
class Case:
    """One scenario and goal of the benchmark; ``error`` says why it cannot be run."""

    scenario: str  # a name on the search path or an absolute path, as a trial takes it
    label: str  # its name in the tables
    goal: str | None  # None: unknown (the scenario could not be read)
    file: str  # the scenario file, for the messages and the rows
    error: str = ''


def shipped_cases() -> list[Case]:
    """Every goal of every shipped map."""
    cases = []
    for name in SHIPPED:
        try:
            scenario = load_scenario(name)
        except (OSError, ValueError) as error:
            cases.append(Case(name, name, None, name, _one_line(error)))
            continue
        file = str(find_scenario(name))
        cases += [Case(name, name, goal, file) for goal in scenario.goals]
    return cases


def generated_cases(
    count: int,
    cache: Path,
    say: Callable[[str], None],
    first: int = TEST_SEED,
    options: Options = OPTIONS,
) -> list[Case]:
    """The ``count`` generated test scenarios of seeds ``first`` on, with ``options``, written
    to (or found in) ``cache`` (``benchmark_cache``: ``say`` gets a line for each entry
    generated again; CacheError for a cache that cannot be used)."""
    cache = Path(cache)
    check_cache(cache)
    cases = []
    for seed in range(first, first + count):
        try:
            path = cached_scenario(cache, seed, say, options)
        except GenerationError as error:  # `stealth benchmark` names it, rows failed
            path = cache / f'{scenario_name(seed)}.yaml'
            cases.append(Case(str(path), path.stem, None, str(path), _one_line(error)))
            continue
        cases.append(file_case(str(path), Path.cwd()))
    return cases


def file_case(entry: str, base: Path) -> Case:
    """A scenario given by name or path (relative to ``base``), at its default goal; a case
    with its error when it cannot be read."""
    scenario = scenario_argument(entry, base)
    label = scenario_label(scenario)
    try:
        file = str(find_scenario(scenario))
        goal = load_scenario(file).default_goal
    except (OSError, ValueError) as error:
        return Case(scenario, label, None, entry, _one_line(error))
    return Case(scenario, label, goal, file)


def set_cases(
    name: str,
    count: int,
    cache: Path,
    say: Callable[[str], None],
    first: int = TEST_SEED,
    options: Options = OPTIONS,
) -> list[Case]:
    """The cases of a named set (module docstring); ``say``, ``first`` and ``options`` as
    generated_cases'."""
    if name not in SETS:
        raise ValueError(f'--set: expected one of {", ".join(SETS)}, got {name!r}')
    cases = []
    if name in ('test', 'generated'):
        cases += generated_cases(count, cache, say, first, options)
    if name in ('test', 'shipped'):
        cases += shipped_cases()
    return cases


def trials(
    cases: list[Case],
    methods: list[str],
    tracks: list[str],
    *,
    episodes: int | None = None,
    seed: int = 0,
    learning_seeds: int | None = None,
    policy: str | None = None,
    policy_file: str | None = None,
    policy_cases: Collection[Case] | None = None,
) -> list[dict]:
    """One trial per case and method that runs on one of ``tracks`` at least, in that order;
    the method policy on ``policy_cases`` only where given (the cases its file was trained on,
    ``benchmark_checks.policy_cases``)."""
    laid = []
    for case in cases:
        for method in methods:
            mine = [track for track in TRACKS if track in tracks and track in METHODS[method]]
            untrained = method == 'policy' and policy_cases is not None
            if not mine or (untrained and case not in policy_cases):
                continue
            laid.append({
                'id': trial_id(case, method),
                'scenario': case.scenario,
                'label': case.label,
                'goal': case.goal,
                'file': case.file,
                'error': case.error,
                'method': method,
                'tracks': mine,
                'episodes': episodes,
                'seed': seed,
                'learning_seeds': learning_seeds,
                'policy': policy,
                'policy_file': policy_file,
            })  # fmt: skip
    return laid


def trial_id(case: Case, method: str) -> str:
    words = [case.label, case.goal or 'default', re.sub(r'[^A-Za-z0-9]+', '-', method).strip('-')]
    return '-'.join(words)


def _one_line(error: Exception) -> str:
    lines = [line for line in str(error).splitlines() if line.strip()]
    return lines[0] if lines else type(error).__name__
