"""The cache of the benchmark's generated test scenarios (``--cache``). No Ray, no rclpy.

An entry is one scenario as the generator writes it (``gen-<seed>.yaml``, ``maps/gen-<seed>.pgm``
and ``.yaml``) and its provenance record, ``gen-<seed>.provenance.json``: the seed, the generator's
options (``OPTIONS``, or the size and lights the benchmark is given) and version
(``scenario_generator.GENERATOR_VERSION``) and the SHA-256 of every file written. An entry is
reused when its record holds: the same seed, options and generator version, and every file as
recorded. Otherwise it is generated again over its old files, said in one line: a file edited
since, a newer generator, a cache written before the records were kept (its scenario's header names
the generator's command for that seed and options). A cache that is a file, or holds anything else
(other scenarios, other files), is refused in one line naming it (``CacheError``), before anything
is written: the cache overwrites only what the benchmark wrote there.
"""

from __future__ import annotations

from collections.abc import Callable
import dataclasses
import hashlib
import json
from pathlib import Path
import re

from stealth_core.scenario_generator import (
    GENERATOR_VERSION,
    Generated,
    Options,
    generate,
    scenario_name,
    seed_range_of,
)

OPTIONS = Options()  # the test set's by default: the generator's defaults
FORMAT = 'stealth benchmark cache entry'
RECORD = '.provenance.json'  # gen-<seed> + RECORD: the entry's provenance record
# The files of an entry, at the top of the cache and in its maps/ (the seed: group 1).
_TOP = re.compile(r'gen-(\d{7,})(?:\.yaml|' + re.escape(RECORD) + ')')
_MAPS = re.compile(r'gen-(\d{7,})\.(?:pgm|yaml)')


class CacheError(ValueError):
    """A --cache that cannot be used: one line naming the directory or file and why."""


def check_cache(cache: Path) -> None:
    """CacheError unless ``cache`` is a directory of cache entries only, or nothing yet."""
    if not cache.exists():
        return
    if not cache.is_dir():
        raise CacheError(f'--cache {cache}: not a directory')
    try:
        foreign = [p.name for p in sorted(cache.iterdir()) if not _entry_file(p, _TOP)]
        maps = cache / 'maps'
        if maps.is_dir():
            foreign += [f'maps/{p.name}' for p in sorted(maps.iterdir()) if not _entry_file(p)]
    except OSError as error:
        raise CacheError(f'--cache {cache}: cannot be read ({error.strerror or error})') from None
    if foreign:
        more = f' and {len(foreign) - 3} more' if len(foreign) > 3 else ''
        raise CacheError(
            f'--cache {cache}: holds {", ".join(foreign[:3])}{more}, which the benchmark did not '
            'write (its cache holds generated test scenarios only); give a new or empty '
            "directory, or an earlier benchmark's cache"
        )


def _entry_file(path: Path, pattern: re.Pattern = _MAPS) -> bool:
    if pattern is _TOP and path.name == 'maps':
        return path.is_dir()
    found = pattern.fullmatch(path.name)
    return bool(found) and path.is_file() and seed_range_of(int(found[1])) == 'test'


def cached_scenario(
    cache: Path, seed: int, say: Callable[[str], None], options: Options = OPTIONS
) -> Path:
    """The scenario file of ``seed`` with ``options`` in the cache (``check_cache`` first),
    generated where its entry is missing and again where it does not match its record (``say``
    gets the line).
    GenerationError when the seed gives no scenario; CacheError when the entry cannot be
    written, or is a scenario the benchmark did not write (no record, another generator command
    in its header)."""
    name = scenario_name(seed)
    path = cache / f'{name}.yaml'
    record = cache / f'{name}{RECORD}'
    if not path.exists() and not record.exists():
        _write(cache, generate(seed, options), options)
        return path
    stale = _stale(cache, seed, record, options)
    if not stale:
        return path
    generated = generate(seed, options)
    if not record.exists() and path.is_file() and _header(path) != _header(generated):
        raise CacheError(
            f'--cache {cache}: {path.name} has no provenance record and another header than '
            f"the generator's for seed {seed} with these options (the scenario of "
            'another command?); give a new or empty directory'
        )
    _write(cache, generated, options)
    say(f'--cache {cache}: {name} generated again: {stale}')
    return path


def _stale(cache: Path, seed: int, record: Path, options: Options) -> str:
    """Why the entry of ``seed`` does not match its record ('' when it does)."""
    if not record.exists():
        return 'it has no provenance record (a cache written before they were kept)'
    name = scenario_name(seed)
    entry = {f'{name}.yaml', f'maps/{name}.pgm', f'maps/{name}.yaml'}  # Generated.files()
    try:
        kept = json.loads(record.read_text(encoding='utf-8'))
        if not isinstance(kept, dict) or kept.get('format') != FORMAT:
            raise ValueError(f'not a {FORMAT}')
        files = kept.get('files')
        if not isinstance(files, dict) or f'{name}.yaml' not in files or set(files) - entry:
            raise ValueError(f'its files are not {", ".join(sorted(entry))}')
    except (OSError, ValueError) as error:
        return f'its provenance record {record.name} cannot be read ({error})'
    if kept.get('seed') != seed:
        return f'its provenance record names seed {kept.get("seed")!r}'
    if kept.get('generator_version') != GENERATOR_VERSION:
        version = kept.get('generator_version')
        return f'generator version {version!r} wrote it, this is version {GENERATOR_VERSION}'
    if kept.get('options') != dataclasses.asdict(options):
        return f'generated with other options ({kept.get("options")!r})'
    for relative, digest in sorted(files.items()):
        file = cache / relative
        if not file.is_file():
            return f'{relative} is missing'
        if _sha256(file.read_bytes()) != digest:
            return f'{relative} is not the file its provenance record names (edited since?)'
    return ''


def _write(cache: Path, generated: Generated, options: Options) -> None:
    """The entry's files, then its record (a crash between: no record, generated again)."""
    record = {
        'format': FORMAT,
        'seed': generated.seed,
        'options': dataclasses.asdict(options),
        'generator_version': GENERATOR_VERSION,
        'files': {relative: _sha256(data) for relative, data in generated.files().items()},
    }
    try:
        generated.write(cache)
        text = json.dumps(record, indent=2) + '\n'
        (cache / f'{generated.name}{RECORD}').write_text(text, encoding='utf-8')
    except OSError as error:
        raise CacheError(
            f'--cache {cache}: cannot write {generated.name} ({error.strerror or error})'
        ) from None


def _header(source: Path | Generated) -> str:
    """A scenario's first line: the generator's command for its seed and options."""
    if isinstance(source, Generated):
        return source.scenario_text.split('\n', 1)[0]
    try:
        with open(source, encoding='utf-8', errors='replace') as stream:
            return stream.readline().rstrip('\n')
    except OSError:
        return ''


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
