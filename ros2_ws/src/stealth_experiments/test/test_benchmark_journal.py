"""The benchmark's journal and ``--resume``: each finished trial is written as it ends; a
benchmark cut short goes on where it stopped, reusing only the trials of the same settings and
inputs; a journal line cut mid-write runs its trial again; a corrupt journal is one line."""

import csv
import json

import pytest
from stealth_experiments import benchmark
from stealth_experiments.benchmark_journal import (
    FORMAT,
    JOURNAL,
    JournalError,
    Writer,
    fingerprint,
    read,
    reusable,
)

ARGV = ['simple-maze', '--methods', 'vi', 'astar', '--tracks', 'full', '--jobs', '1']


def _rows(path):
    with path.open(newline='', encoding='utf-8') as stream:
        return [{k: v for k, v in row.items() if k != 'seconds'} for row in csv.DictReader(stream)]


@pytest.fixture
def counted(monkeypatch):
    """The trials the benchmark runs (ids), in order."""
    ran = []
    real = benchmark.run_case

    def run_case(trial):
        ran.append(trial['id'])
        return real(trial)

    monkeypatch.setattr(benchmark, 'run_case', run_case)
    return ran


def test_a_benchmark_cut_short_goes_on_with_resume(tmp_path, counted, capsys):
    out = tmp_path / 'out'
    assert benchmark.main([*ARGV, '--out', str(out)]) == 0
    assert len(counted) == 2
    first = _rows(out / 'results.csv')
    lines = (out / JOURNAL).read_text().splitlines()
    assert [json.loads(line)['trial'] for line in lines] == counted
    # killed while writing the second trial: half its line, no newline; results never written
    (out / JOURNAL).write_text(lines[0] + '\n' + lines[1][: len(lines[1]) // 2])
    (out / 'results.csv').unlink()
    counted.clear()
    assert benchmark.main([*ARGV, '--out', str(out), '--resume']) == 0
    said = capsys.readouterr().out
    assert 'line 2 was cut short' in said and 'resuming: 1 of 2 trials' in said
    assert len(counted) == 1 and counted[0] in lines[1]  # only the lost trial ran
    assert _rows(out / 'results.csv') == first
    assert 'Resumed: 1 trial' in (out / 'summary.md').read_text()
    assert len((out / JOURNAL).read_text().splitlines()) == 2  # the lost one written again


def test_trials_of_other_settings_run_again_and_are_said(tmp_path, counted, capsys):
    out = tmp_path / 'out'
    assert benchmark.main([*ARGV, '--out', str(out)]) == 0
    counted.clear()
    assert benchmark.main([*ARGV, '--out', str(out), '--resume', '--seed', '3']) == 0
    assert len(counted) == 2
    assert '2 trials of the journal ran with other settings' in capsys.readouterr().out


def test_resume_without_a_journal_and_a_journal_without_resume_are_refused(tmp_path, capsys):
    out = tmp_path / 'out'
    assert benchmark.main([*ARGV, '--out', str(out), '--resume']) == 1
    err = capsys.readouterr().err.strip()
    assert JOURNAL in err and 'run without --resume' in err and '\n' not in err
    out.mkdir()
    (out / JOURNAL).write_text('')
    assert benchmark.main([*ARGV, '--out', str(out)]) == 1
    assert f'earlier benchmark ({JOURNAL})' in capsys.readouterr().err
    with pytest.raises(SystemExit):
        benchmark.main([*ARGV, '--out', str(out), '--resume', '--force'])


def test_a_corrupt_journal_is_one_line_naming_the_file_and_line(tmp_path, capsys):
    out = tmp_path / 'out'
    out.mkdir()
    (out / JOURNAL).write_text('{"not": "a trial"}\n')
    assert benchmark.main([*ARGV, '--out', str(out), '--resume']) == 1
    err = capsys.readouterr().err.strip()
    assert f'{out / JOURNAL}: line 1: expected a trial' in err and '\n' not in err
    (out / JOURNAL).write_text('garbage\n{"also": 1}\n')
    with pytest.raises(JournalError, match='line 1: not JSON'):
        read(out / JOURNAL)


def test_the_fingerprint_follows_the_scenario_file_and_failed_trials_are_not_written(tmp_path):
    scenario = tmp_path / 's.yaml'
    scenario.write_text('name: a\n')
    trial = {'id': 't', 'scenario': str(scenario), 'error': '', 'method': 'vi', 'seed': 0}
    before = fingerprint(trial)
    assert fingerprint(dict(trial)) == before
    with Writer(tmp_path / JOURNAL, fresh=True) as journal:
        journal.add(trial, [{'track': 'full', 'status': 'ok', 'value': 1.5}])
        journal.add({**trial, 'id': 'u'}, [{'track': 'full', 'status': 'failed'}])
    found = read(tmp_path / JOURNAL)
    assert list(found) == ['t'] and found['t'][1][0]['value'] == 1.5
    assert json.loads((tmp_path / JOURNAL).read_text())['format'] == FORMAT
    assert reusable(found, [trial])[0] == {'t': found['t'][1]}
    scenario.write_text('name: b\n')  # the scenario file changed: the trial runs again
    assert reusable(found, [trial]) == ({}, 1)
