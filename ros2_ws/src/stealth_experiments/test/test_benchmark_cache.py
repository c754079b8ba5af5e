"""The benchmark's cache of generated test scenarios: each entry written with its provenance
record and reused while the record holds; an edited entry, one of another generator version and
one of a cache without records generated again, each said in one line; a cache that is a file or
holds anything else refused in one line."""

import dataclasses
import hashlib
import json

import pytest
from stealth_core.scenario_generator import GENERATOR_VERSION, Options, generate
from stealth_experiments import benchmark
from stealth_experiments.benchmark_cache import CacheError, cached_scenario, check_cache
from stealth_experiments.benchmark_plan import TEST_SEED, generated_cases

NAME = 'gen-1000000'


def _files(cache):
    return {
        p.relative_to(cache).as_posix(): p.read_bytes() for p in cache.rglob('*') if p.is_file()
    }


def _record(cache, name=NAME):
    return json.loads((cache / f'{name}.provenance.json').read_text())


def test_an_entry_is_written_with_its_provenance_and_reused_while_it_holds(tmp_path):
    cache, notes = tmp_path / 'cache', []
    cases = generated_cases(2, cache, notes.append)
    assert [c.label for c in cases] == [NAME, 'gen-1000001'] and notes == []
    record = _record(cache)
    assert record['seed'] == TEST_SEED and record['generator_version'] == GENERATOR_VERSION
    assert record['options'] == dataclasses.asdict(Options())
    files = _files(cache)
    assert sorted(record['files']) == [f'{NAME}.yaml', f'maps/{NAME}.pgm', f'maps/{NAME}.yaml']
    assert record['files'] == {
        name: hashlib.sha256(files[name]).hexdigest() for name in record['files']
    }
    stamps = {p: p.stat().st_mtime_ns for p in cache.rglob('*')}
    assert generated_cases(2, cache, notes.append) == cases and notes == []
    assert {p: p.stat().st_mtime_ns for p in cache.rglob('*')} == stamps  # not written again


def test_an_edited_entry_is_generated_again_saying_so_in_one_line(tmp_path):
    cache, notes = tmp_path / 'cache', []
    generated_cases(1, cache, notes.append)
    fresh = _files(cache)
    scenario = cache / f'{NAME}.yaml'
    edited = scenario.read_text().replace('detection_threshold: 0.3', 'detection_threshold: 0.9')
    assert edited != fresh[f'{NAME}.yaml'].decode()
    scenario.write_text(edited)  # still a valid scenario: reused, it would run as edited
    (case,) = generated_cases(1, cache, notes.append)
    assert not case.error
    assert notes == [
        f'--cache {cache}: {NAME} generated again: {NAME}.yaml is not the file its provenance '
        'record names (edited since?)'
    ]
    assert _files(cache) == fresh
    map_image = cache / 'maps' / f'{NAME}.pgm'
    image = map_image.read_bytes()
    map_image.write_bytes(image[:-1] + bytes([image[-1] ^ 0xFF]))  # a cell changed
    generated_cases(1, cache, notes.append)
    assert notes[-1].endswith(f'maps/{NAME}.pgm is not the file its provenance record names '
                              '(edited since?)')  # fmt: skip
    assert _files(cache) == fresh


def test_an_entry_of_another_generator_or_without_a_record_is_generated_again(tmp_path):
    cache, notes = tmp_path / 'cache', []
    generated_cases(1, cache, notes.append)
    fresh = _files(cache)
    record = cache / f'{NAME}.provenance.json'
    older = {**_record(cache), 'generator_version': GENERATOR_VERSION - 1}
    record.write_text(json.dumps(older))
    generated_cases(1, cache, notes.append)
    assert notes == [
        f'--cache {cache}: {NAME} generated again: generator version {GENERATOR_VERSION - 1} '
        f'wrote it, this is version {GENERATOR_VERSION}'
    ]
    record.unlink()  # a cache written before the records were kept
    generated_cases(1, cache, notes.append)
    assert notes[-1] == (
        f'--cache {cache}: {NAME} generated again: it has no provenance record (a cache written '
        'before they were kept)'
    )
    record.write_text('{not json')
    generated_cases(1, cache, notes.append)
    assert f'its provenance record {NAME}.provenance.json cannot be read' in notes[-1]
    assert _files(cache) == fresh and len(notes) == 3


def test_a_cache_that_is_not_one_is_refused_in_one_line_before_anything_is_written(tmp_path):
    blocker = tmp_path / 'a-file'
    blocker.write_text('')
    with pytest.raises(CacheError, match=rf'^--cache {blocker}: not a directory$'):
        check_cache(blocker)
    mixed = tmp_path / 'mixed'
    generated_cases(1, mixed, print)
    (mixed / 'notes.txt').write_text('mine')
    (mixed / 'maps' / 'simple-maze.pgm').write_bytes(b'P5')
    (mixed / 'gen-0000042.yaml').write_text('a train-range scenario')
    with pytest.raises(CacheError) as error:
        generated_cases(2, mixed, print)
    assert str(error.value).startswith(
        f'--cache {mixed}: holds gen-0000042.yaml, notes.txt, maps/simple-maze.pgm, which the '
        'benchmark did not write'
    )
    assert not (mixed / 'gen-1000001.yaml').exists()
    # a test-seed scenario of another command (other options), without a record: not ours
    other = tmp_path / 'other'
    generate(TEST_SEED, Options(width=20, height=20, lights=3)).write(other)
    mine = _files(other)
    with pytest.raises(CacheError) as error:
        cached_scenario(other, TEST_SEED, print)
    assert str(error.value).startswith(
        f'--cache {other}: {NAME}.yaml has no provenance record and another header than the '
        "generator's for seed 1000000"
    )
    assert _files(other) == mine  # not overwritten


def test_the_command_refuses_a_cache_that_is_a_file_in_one_line(tmp_path, capsys):
    blocker = tmp_path / 'a-file'
    blocker.write_text('')
    argv = ['--set', 'generated', '--count', '1', '--cache', str(blocker)]
    assert benchmark.main([*argv, '--out', str(tmp_path / 'out')]) == 1
    out, err = capsys.readouterr()
    assert err == f'stealth benchmark: --cache {blocker}: not a directory\n'
    assert not (tmp_path / 'out').exists()  # refused before anything was made
