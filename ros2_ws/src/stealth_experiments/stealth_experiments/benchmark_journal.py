"""The benchmark's journal of finished trials, ``OUT/trials.jsonl``: each trial's rows are
appended (flushed and synced) as it ends, so a benchmark that is killed (SIGKILL, a lost
machine, a full disk) loses only the trials then running, and ``--resume`` runs only the trials
the journal lacks. No Ray, no rclpy.

A line is one trial: ``{"format": FORMAT, "trial": id, "fingerprint": ..., "rows": [...]}``.
The fingerprint covers what decides the trial's rows (``FIELDS``: its scenario file and goal,
method, tracks, seed, training budget and weights files) and the SHA-256 of its scenario file
and of the weights files it names, so a journal line is reused only by the same trial of the
same inputs; one run with other settings is run again (and said). Only trials whose every row
ran (status ok) are written: a failed trial runs again on resume. A last line cut short (the
kill came mid-write) is left out, and said; any other line that is not a trial is refused in
one line naming the file and line (``JournalError``).
"""

from __future__ import annotations

from collections.abc import Iterable
import hashlib
import json
import os
from pathlib import Path

JOURNAL = 'trials.jsonl'
FORMAT = 'stealth benchmark journal v1'
FIELDS = ('id', 'scenario', 'goal', 'method', 'tracks', 'episodes', 'seed', 'learning_seeds',
          'policy', 'policy_file')  # fmt: skip
FILES = ('scenario', 'policy', 'policy_file')  # their content is part of the fingerprint


class JournalError(ValueError):
    """A journal that cannot be read or written."""


def fingerprint(trial: dict) -> str:
    """The SHA-256 of the trial's defining fields and of the files it reads (module
    docstring); a file that cannot be read counts as its error (its trial fails anyway)."""
    digest = hashlib.sha256()
    digest.update(json.dumps({k: trial.get(k) for k in FIELDS}, sort_keys=True).encode())
    for key in FILES:
        path = trial.get(key)
        if path:
            digest.update(_file_digest(Path(path)).encode())
    return digest.hexdigest()


def _file_digest(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as error:
        return f'unreadable: {error.strerror or error}'


def read(path: Path, say=print) -> dict[str, tuple[str, list[dict]]]:
    """{trial id: (fingerprint, rows)} of the journal at ``path`` (a later line for the same
    trial wins); JournalError, one line naming the file and line, for a line that is not a
    trial (a last line cut short is left out and said)."""
    try:
        lines = path.read_text(encoding='utf-8').split('\n')
    except OSError as error:
        raise JournalError(f'{path}: cannot be read ({error.strerror or error})') from None
    except UnicodeDecodeError:
        raise JournalError(f'{path}: not a benchmark journal (not UTF-8 text)') from None
    found = {}
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            if number == len(lines):  # no newline after it: the write was cut short
                say(f'{path}: line {number} was cut short (the run stopped mid-write); its '
                    'trial runs again')  # fmt: skip
                continue
            raise JournalError(
                f'{path}: line {number}: not JSON; expected one trial a line ({FORMAT!r}), or '
                'remove the file and start over'
            ) from None
        if not _is_entry(entry):
            raise JournalError(f'{path}: line {number}: expected a trial of {FORMAT!r} '
                               '(format, trial, fingerprint, rows)')  # fmt: skip
        found[entry['trial']] = (entry['fingerprint'], entry['rows'])
    return found


def _is_entry(entry) -> bool:
    return (
        isinstance(entry, dict)
        and entry.get('format') == FORMAT
        and isinstance(entry.get('trial'), str)
        and isinstance(entry.get('fingerprint'), str)
        and isinstance(entry.get('rows'), list)
        and all(isinstance(row, dict) and 'track' in row for row in entry['rows'])
    )


def reusable(journal: dict, laid: Iterable[dict]) -> tuple[dict[str, list[dict]], int]:
    """({trial id: rows} of the laid trials the journal holds with the same fingerprint, how
    many journal trials of the same ids were run with other settings or inputs)."""
    kept, stale = {}, 0
    for trial in laid:
        entry = journal.get(trial['id'])
        if entry is None or trial['error']:
            continue
        if entry[0] == fingerprint(trial):
            kept[trial['id']] = entry[1]
        else:
            stale += 1
    return kept, stale


class Writer:
    """Appends finished trials to the journal (``add``); ``fresh`` empties it first."""

    def __init__(self, path: Path, fresh: bool):
        self.path = path
        try:
            self._stream = path.open('w' if fresh else 'a', encoding='utf-8')
        except OSError as error:
            raise JournalError(f'{path}: cannot be written ({error.strerror or error})') from None

    def add(self, trial: dict, rows: list[dict]) -> None:
        """Write the trial if every row ran (module docstring), flushed and synced."""
        if not rows or any(row.get('status') != 'ok' or 'track' not in row for row in rows):
            return
        entry = {'format': FORMAT, 'trial': trial['id'], 'fingerprint': fingerprint(trial),
                 'rows': rows}  # fmt: skip
        self._stream.write(json.dumps(entry, default=_plain) + '\n')
        self._stream.flush()
        os.fsync(self._stream.fileno())

    def close(self) -> None:
        self._stream.close()

    def __enter__(self) -> Writer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _plain(value):
    """numpy scalars and other stragglers as JSON: their Python value, else their text."""
    item = getattr(value, 'item', None)
    return item() if callable(item) else str(value)
