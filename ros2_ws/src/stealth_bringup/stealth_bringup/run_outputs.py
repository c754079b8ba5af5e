"""The one report writer of `stealth train`/`stealth rollout` runs (runs/<name>/) and of the
experiment harness (runs/eval/): what they leave besides recordings, policies, parameters and
logs. No rclpy.

    episodes.csv        write_csv: one row per episode (the harness: results.csv, one per run)
    summary.json        write_json: strict JSON, NaN as null
    learning_curve.png  return of every episode (colour: outcome; diamonds: greedy evaluations),
                        the moving average of the training returns, steps per episode and epsilon
    path.png            plot_paths: the scenario (walls, visibility, cones) with labelled paths:
                        the robot's true path in the last greedy episode and the value-iteration
                        optimum on the move lattice (the harness: every method's path)

Every file is written whole or not at all: into a temporary file beside it, renamed over it
(the rows of episodes.csv, appended as episodes end, one write each, undone if it fails). A
full disk is stealth_node_kit.full_disk's DiskFullError naming the file; the file keeps what it
held before and no temporary file stays.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import contextlib
import csv
import dataclasses
import io
import json
import math
import os
from pathlib import Path

from matplotlib.figure import Figure  # no pyplot: no global state, no display (Agg)
from matplotlib.lines import Line2D
import numpy as np
from stealth_core import palette
from stealth_node_kit.full_disk import checked_write, remove_quietly

from stealth_bringup.episode_tracker import CSV_FIELDS, OUTCOMES, SCORE_FIELDS, EpisodeRecord
from stealth_bringup.run_config import RunConfigError, relative_to_cwd

AVERAGE_WINDOW = 20


def write_csv(rows: Iterable[dict], fields: Sequence[str], path: Path) -> Path:
    """A CSV with a header of `fields`; floats to 6 significant digits, NaN and None empty.
    Written atomically: a reader (or a crash) sees the old file or the new one."""

    def write(stream) -> None:
        writer = csv.DictWriter(stream, fieldnames=fields)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _csv_value(v) for k, v in row.items()})

    return _replace_atomically(path, write, newline='')


def _replace_atomically(path: Path, write, newline: str | None = None) -> Path:
    """write(stream) into a temporary file beside `path`, then rename it over `path`. On any
    failure the temporary file goes and `path` keeps what it held; a full disk is
    DiskFullError naming `path`."""
    path = Path(path)
    partial = path.with_name(f'.{path.name}.partial')
    try:
        with checked_write(path, relative_to_cwd(path)):
            with open(partial, 'w', newline=newline, encoding='utf-8') as stream:
                write(stream)
            os.replace(partial, path)
    except BaseException:
        remove_quietly(partial)
        raise
    return path


@contextlib.contextmanager
def replacing(path: Path):
    """A temporary path beside `path` with its suffix (a picture's format goes by it) to write
    to by name; renamed over `path` when the block ends, removed if it fails (a full disk:
    DiskFullError naming `path`), so a torn picture never takes the place of a whole one."""
    path = Path(path)
    temporary = path.with_name(f'.{path.stem}.partial{path.suffix}')
    try:
        with checked_write(path, relative_to_cwd(path)):
            yield temporary
            if temporary.exists():
                os.replace(temporary, path)
    except BaseException:
        remove_quietly(temporary)
        raise


def append_episode(record: EpisodeRecord, path: Path) -> None:
    """One more row of episodes.csv (the header first if the file is new), written to the OS
    in one call, so a killed orchestrator leaves every episode finished so far. A write that
    fails (a full disk: DiskFullError naming the file) is undone: the file keeps the rows it
    had, never a torn one."""
    path = Path(path)
    with checked_write(path, relative_to_cwd(path)):
        descriptor = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
        try:
            size = os.lseek(descriptor, 0, os.SEEK_END)
            stream = io.StringIO(newline='')
            writer = csv.DictWriter(stream, fieldnames=CSV_FIELDS)
            if size == 0:
                writer.writeheader()
            writer.writerow({k: _csv_value(v) for k, v in record.as_row().items()})
            rest = memoryview(stream.getvalue().encode('utf-8'))
            try:
                while rest:  # a write cut short by a full disk says so at the next call
                    rest = rest[os.write(descriptor, rest) :]
            except OSError:
                with contextlib.suppress(OSError):
                    os.ftruncate(descriptor, size)
                raise
        finally:
            os.close(descriptor)


def read_episodes_csv(path: Path) -> list[EpisodeRecord]:
    """The episodes of an episodes.csv (as written here); RunConfigError naming the file, the
    line and the field when it cannot be read back. A file written before the score columns
    existed reads with them unknown (episode_scores.UNSCORED)."""
    kinds = {f.name: f.type for f in dataclasses.fields(EpisodeRecord)}
    try:
        with open(path, newline='', encoding='utf-8') as stream:
            reader = csv.DictReader(stream)
            if reader.fieldnames is None:
                return []
            missing = [
                f for f in CSV_FIELDS if f not in reader.fieldnames and f not in SCORE_FIELDS
            ]
            if missing:
                columns = ', '.join(missing)
                raise RunConfigError(f'{path}: no column {columns} (not an episodes.csv)')
            records = []
            for row in reader:
                values = {}
                for name, kind in kinds.items():
                    if name not in row:  # a score column of a file written before them
                        continue
                    try:
                        values[name] = _parse_csv_value(row[name], kind)
                    except (TypeError, ValueError):
                        raise RunConfigError(
                            f'{path}, line {reader.line_num}: {name} {row[name]!r} is not '
                            f'a{"n" if kind == "int" else ""} {kind}'
                        ) from None
                records.append(EpisodeRecord(**values))
    except OSError as error:
        raise RunConfigError(f'{path}: cannot read it ({error.strerror})') from None
    return records


def _parse_csv_value(text: str, kind: str):
    if kind == 'float':
        return math.nan if text == '' else float(text)
    if kind == 'int':
        return int(text)
    if kind == 'bool':
        if text not in ('True', 'False'):
            raise ValueError(text)
        return text == 'True'
    return text


def _csv_value(value):
    if isinstance(value, float):
        return '' if math.isnan(value) else f'{value:.6g}'
    return '' if value is None else value


def write_episodes_csv(records: Sequence[EpisodeRecord], path: Path) -> Path:
    """One row per episode, the columns of EpisodeRecord."""
    return write_csv((record.as_row() for record in records), CSV_FIELDS, path)


def write_json(data: dict, path: Path) -> Path:
    """JSON with NaN written as null (strict JSON readers refuse NaN), atomically."""
    text = json.dumps(_finite(data), indent=2) + '\n'
    return _replace_atomically(path, lambda stream: stream.write(text))


def read_run_summary(directory: Path) -> dict:
    """A run directory's summary.json ({} where there is none, or it is not a JSON object)."""
    path = directory / 'summary.json'
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding='utf-8'))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _finite(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def moving_average(values: Sequence[float], window: int = AVERAGE_WINDOW) -> np.ndarray:
    """Mean of the last `window` values at every index (fewer at the start)."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return values
    sums = np.cumsum(np.insert(values, 0, 0.0))
    index = np.arange(1, values.size + 1)
    low = np.maximum(0, index - window)
    return (sums[index] - sums[low]) / (index - low)


def plot_learning_curve(
    records: Sequence[EpisodeRecord],
    path: Path,
    title: str,
    streak_start: int | None = None,
    optimal_return: float | None = None,
) -> Path | None:
    """Returns, outcomes, greedy evaluations, moving average; steps and epsilon below."""
    if not records:
        return None
    fig = Figure(figsize=(10.5, 7.0), dpi=110)
    top, bottom = fig.subplots(
        2, 1, sharex=True, gridspec_kw={'height_ratios': [3, 1.3], 'hspace': 0.08}
    )
    training = [r for r in records if not r.greedy]
    greedy = [r for r in records if r.greedy]
    # Training episodes as dots, greedy evaluations as outlined diamonds over them.
    styles = (
        (training, {'s': 14, 'alpha': 0.7, 'linewidths': 0, 'zorder': 2}),
        (
            greedy,
            {
                's': 60,
                'marker': 'D',
                'edgecolors': palette.PLOT_INK,
                'linewidths': 0.9,
                'zorder': 4,
            },
        ),
    )
    for outcome in OUTCOMES:
        for kind, style in styles:
            chosen = [r for r in kind if r.outcome == outcome]
            if chosen:
                episodes, returns = [r.episode for r in chosen], [r.total_reward for r in chosen]
                top.scatter(episodes, returns, color=palette.OUTCOMES[outcome], **style)
    if training:
        top.plot(
            [r.episode for r in training],
            moving_average([r.total_reward for r in training]),
            color=palette.RETURN,
            linewidth=2.0,
            zorder=3,
        )
    if optimal_return is not None:
        top.axhline(optimal_return, color=palette.RETURN, linestyle=':', linewidth=1.2, zorder=1)
    if streak_start is not None:
        for axes in (top, bottom):
            axes.axvline(
                streak_start, color=palette.STREAK, linestyle='--', linewidth=1.2, zorder=1
            )
    top.set_ylabel('return (sum of rewards)')
    top.grid(True, alpha=0.3)
    top.set_title(title)

    handles = [
        Line2D([], [], marker='o', linestyle='none', color=palette.OUTCOMES[o], label=o.lower())
        for o in OUTCOMES
        if any(r.outcome == o for r in records)
    ]
    handles.append(
        Line2D(
            [],
            [],
            marker='D',
            linestyle='none',
            color=palette.PLOT_PAPER,
            markeredgecolor=palette.PLOT_INK,
            label='greedy evaluation',
        )
    )
    if training:
        handles.append(
            Line2D(
                [],
                [],
                color=palette.RETURN,
                linewidth=2,
                label=f'mean of the last {AVERAGE_WINDOW} training episodes',
            )
        )
    if optimal_return is not None:
        handles.append(
            Line2D([], [], color=palette.RETURN, linestyle=':', label='optimum (value iteration)')
        )
    if streak_start is not None:
        handles.append(
            Line2D(
                [],
                [],
                color=palette.STREAK,
                linestyle='--',
                label=f'greedy streak meeting the criterion from {streak_start}',
            )
        )
    top.legend(handles=handles, loc='lower right', fontsize=8, framealpha=0.85)

    bottom.bar(
        [r.episode for r in records],
        [r.steps for r in records],
        width=1.0,
        color=[palette.OUTCOMES.get(r.outcome, palette.UNKNOWN_OUTCOME) for r in records],
        alpha=0.75,
    )
    bottom.set_ylabel('steps')
    bottom.set_xlabel('episode')
    bottom.grid(True, alpha=0.3)
    epsilons = [(r.episode, r.epsilon) for r in training if not math.isnan(r.epsilon)]
    if epsilons:
        twin = bottom.twinx()
        twin.plot(*zip(*epsilons, strict=True), color=palette.PLOT_INK, linewidth=1.2)
        twin.set_ylabel('epsilon (training)')
        twin.set_ylim(0, max(0.05, max(e for _, e in epsilons) * 1.15))
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as temporary:
        fig.savefig(temporary, bbox_inches='tight')
    return path


def plot_paths(
    scenario,
    goal: str,
    path: Path,
    labelled: Sequence[tuple[Sequence[Sequence[float]], str]],
    title: str,
    spread: float = 0.0,
    cache_dir: str | os.PathLike | None = None,
) -> Path:
    """The scenario with (points, label) paths, later ones drawn over earlier ones, written
    whole or not at all (replacing). Paths often share stretches: `spread` (m) shifts
    neighbouring ones apart so that all of them show."""
    from stealth_core.render import render_scenario

    middle = (len(labelled) - 1) / 2
    paths = [
        np.asarray(p, dtype=float) + (k - middle) * spread for k, (p, _) in enumerate(labelled)
    ]
    with replacing(path) as temporary:
        render_scenario(
            scenario,
            temporary,
            paths=paths,
            goal=goal,
            path_labels=[label for _, label in labelled],
            title=title,
            cache_dir=cache_dir,
        )
    return Path(path)


def plot_path(
    scenario,
    goal: str,
    path: Path,
    learned: Sequence[Sequence[float]] | None,
    learned_label: str,
    optimum: Sequence[Sequence[float]] | None,
    optimum_label: str,
    title: str,
    cache_dir: str | os.PathLike | None = None,
) -> Path | None:
    """A run's picture: the learned true path over the value-iteration optimum (drawn first, so
    the learned path shows where they coincide); None when neither has two points."""
    labelled = [
        (points, label)
        for points, label in ((optimum, optimum_label), (learned, learned_label))
        if points is not None and len(points) >= 2
    ]
    if not labelled:
        return None
    return plot_paths(scenario, goal, path, labelled, title, cache_dir=cache_dir)
