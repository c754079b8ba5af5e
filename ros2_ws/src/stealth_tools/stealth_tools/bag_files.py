"""Which .mcap files a bag path names, in order: a recording split over several files.

A run directory (runs/<name>/) records into `recording.mcap`; when its recorder is restarted
(a respawn) or the run is continued (`stealth train --resume`), the next file goes beside it as
`recording_1.mcap`, `recording_2.mcap`, ..., the way rosbag2 numbers the files of a split bag
(`<name>_0.mcap`, `<name>_1.mcap`, ...). Every bag tool reads a directory as all the files of
its one recording, in that order; a file of which `stealth bag recover` made an indexed copy
(`<file>.recovered.mcap`) is read from the copy. No rclpy.
"""

from __future__ import annotations

import os
from pathlib import Path
import re

from stealth_tools.bag_format import BagError, resolve_bag_file

RECORDING_STEM = 'recording'  # runs/<name>/recording.mcap, recording_1.mcap, ...
RECOVERED_SUFFIX = '.recovered.mcap'
_SPLIT = re.compile(r'^(?P<base>.+?)(?:_(?P<number>\d+))?$')


def _split_key(path: Path) -> tuple[str, int]:
    """(base name, number) of a split file: recording -> ('recording', -1), recording_2 ->
    ('recording', 2), run_0 -> ('run', 0)."""
    match = _SPLIT.match(path.name.removesuffix('.mcap'))
    number = match.group('number')
    return match.group('base'), -1 if number is None else int(number)


def _originals(directory: Path) -> list[Path]:
    """The .mcap files of a directory, a recovered copy standing for its original."""
    names = {p.name for p in directory.glob('*.mcap')}
    originals = set()
    for name in names:
        if name.endswith(RECOVERED_SUFFIX):
            name = name.removesuffix(RECOVERED_SUFFIX) + '.mcap'
        originals.add(name)
    return [directory / name for name in originals]


def _readable(path: Path) -> Path:
    """The file to read for a split: its recovered copy when there is one."""
    recovered = path.with_name(path.name.removesuffix('.mcap') + RECOVERED_SUFFIX)
    return recovered if recovered.exists() else path


def recording_files(run_dir: str | os.PathLike) -> list[Path]:
    """The files of a run's recording in order (recording.mcap, recording_1.mcap, ...), each
    the recovered copy where one exists; [] when the run recorded nothing."""
    directory = Path(run_dir)
    files = [p for p in _originals(directory) if _split_key(p)[0] == RECORDING_STEM]
    return [_readable(p) for p in sorted(files, key=lambda p: _split_key(p)[1])]


def next_recording_file(run_dir: str | os.PathLike) -> Path:
    """Where the run's next recorder writes: recording.mcap, else the number after the last."""
    directory = Path(run_dir)
    numbers = [
        _split_key(p)[1] for p in _originals(directory) if _split_key(p)[0] == RECORDING_STEM
    ]
    if not numbers:
        return directory / f'{RECORDING_STEM}.mcap'
    return directory / f'{RECORDING_STEM}_{max(max(numbers), 0) + 1}.mcap'


def bag_files(path: str | os.PathLike) -> list[Path]:
    """The .mcap files a bag path names, in order: a file itself; a directory's one recording
    (its split files by number); BagError when it names none or several recordings."""
    path = Path(path)
    if not path.is_dir():
        return [resolve_bag_file(path)]
    groups: dict[str, list[Path]] = {}
    for file in _originals(path):
        groups.setdefault(_split_key(file)[0], []).append(file)
    if not groups:
        raise BagError(f'{path} is a directory without an .mcap file')
    if len(groups) > 1:
        names = ', '.join(sorted(p.name for files in groups.values() for p in files))
        raise BagError(f'{path} holds the files of several recordings ({names}); name one of them')
    (files,) = groups.values()
    ordered = sorted(files, key=lambda p: _split_key(p)[1])
    return [resolve_bag_file(_readable(p)) for p in ordered]
