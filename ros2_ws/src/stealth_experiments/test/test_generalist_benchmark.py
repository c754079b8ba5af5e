"""`stealth generalist`: the benchmark with the generalist's defaults. Every generalist figure
is printed beside the oracle, its hand-set and untrained twins and the replanners, on both
tracks; the generated set's seeds and size are the user's; the final test range is refused
unless asked for by name (issue 42)."""

import csv
import json

import pytest
from stealth_core.scenario_generator import FINAL_TEST_SEED
from stealth_experiments import generalist_benchmark
from stealth_experiments.benchmark_plan import TEST_SEED, check_seeds


@pytest.mark.parametrize(
    ('argv', 'line'),
    [
        (
            ['--seeds', str(FINAL_TEST_SEED - 5), '--count', '10'],
            '--seeds 1,999,995 --count 10: seeds up to 2,000,004 reach the final test range '
            '(2,000,000 and up), which is evaluated once at the end of an issue; give '
            '--final-test-range to evaluate it',
        ),
        (
            ['--seeds', str(FINAL_TEST_SEED)],
            '--seeds 2,000,000 --count 20: seeds up to 2,000,019 reach the final test range',
        ),
        (
            ['--seeds', '5'],
            '--seeds: expected a test seed >= 1,000,000 (the training and validation ranges lie '
            'below), got 5',
        ),
        (
            ['--final-test-range', '--seeds', str(TEST_SEED)],
            '--final-test-range: the final test range starts at seed 2,000,000, --seeds starts '
            'at 1,000,000',
        ),
        (['--width', '61'], '--width: expected a whole number in [20, 60], got 61'),
        (
            ['simple-maze', '--seeds', str(TEST_SEED)],
            '--seeds: for generated scenarios (--set test or generated), not for scenario files '
            'or --set shipped',
        ),
    ],
)
def test_seeds_outside_the_development_range_are_refused_before_anything(
    tmp_path, capsys, argv, line
):
    out = tmp_path / 'out'
    assert generalist_benchmark.main([*argv, '--out', str(out)]) == 1
    _, err = capsys.readouterr()
    assert err.startswith(f'stealth generalist: {line}') and err.count('\n') == 1
    assert not out.exists()


def test_the_final_test_range_is_only_evaluated_when_asked_for_by_name(capsys):
    check_seeds(FINAL_TEST_SEED, 50, final=True)
    check_seeds(FINAL_TEST_SEED - 50, 50, final=False)  # the last development seeds
    with pytest.raises(ValueError, match='reach the final test range'):
        check_seeds(FINAL_TEST_SEED - 50, 51, final=False)
    with pytest.raises(SystemExit):
        generalist_benchmark.main(['--help'])
    text = ' '.join(capsys.readouterr().out.split())
    assert 'Seeds 2,000,000 and up are the final test range, evaluated once at the end' in text
    assert '--final-test-range evaluate the final test range (seeds 2,000,000 and up)' in text


def test_every_generalist_figure_stands_beside_its_baselines_on_both_tracks(tmp_path, capsys):
    """One small generated building of the user's size: the oracle, the generalist, its three
    twins on both tracks, the replanners on the sensed one; the tables printed."""
    pytest.importorskip('jax')
    out = tmp_path / 'out'
    argv = ['--seeds', str(TEST_SEED + 3), '--count', '1', '--width', '20', '--height', '20',
            '--lights', '3', '--jobs', '1', '--no-plots', '--out', str(out)]  # fmt: skip
    assert generalist_benchmark.main(argv) == 0
    printed = capsys.readouterr().out
    with open(out / 'results.csv', encoding='utf-8') as stream:
        rows = list(csv.DictReader(stream))
    assert {r['status'] for r in rows} == {'ok'}
    twins = ('generalist', 'generalist (hand-set)', 'generalist (dark steps)')
    on_both = ('value iteration', *twins, 'generalist (untrained)')
    assert sorted((r['method'], r['track']) for r in rows) == sorted(
        [(m, t) for m in on_both for t in ('full', 'sensed')]
        + [('replan (unknown dark)', 'sensed'), ('replan (unknown lit)', 'sensed')]
        + [('generalist (cycle rule)', 'full')]
    )
    full = {r['method']: r for r in rows if r['track'] == 'full'}
    assert all(full[m]['success'] == 'True' for m in (*twins, 'generalist (cycle rule)'))
    # static lights: the cycle's brightest field is the light itself, the rule the hand-set twin
    assert full['generalist (cycle rule)']['return'] == full['generalist (hand-set)']['return']
    assert float(full['generalist (hand-set)']['regret']) == pytest.approx(0.0, abs=1e-6)
    header = '| method | undetected | success | criterion | regret | mean return |'
    assert printed.count(header) == 2 and '## Track: sensed' in printed
    for method in (*on_both, 'replan (unknown dark)', 'replan (unknown lit)'):
        assert f'| {method} | ' in printed
    assert 'Generated: seeds 1,000,003 to 1,000,003, 20 x 20 m, 3 lights' in printed
    record = json.loads((out / 'scenarios' / 'gen-1000003.provenance.json').read_text())
    assert (record['options']['width'], record['options']['lights']) == (20, 3)


def test_moving_lights_with_the_time_aware_weights_beside_the_cycle_rule(tmp_path, capsys):
    """--moving: a generated building with moving lights; the time-aware weights (the shipped
    generalist-moving.npz), their hand-set and untrained twins and the cycle rule play it on
    the full track beside value iteration; the hand-set twin at the optimum."""
    pytest.importorskip('jax')
    from stealth_learn.train_generalist import MOVING_OUT

    if not MOVING_OUT.is_file():
        pytest.skip('no time-aware weights')
    out = tmp_path / 'out'
    argv = ['--seeds', str(TEST_SEED + 1), '--count', '1', '--width', '20', '--height', '20',
            '--lights', '3', '--moving', 'sweeping', '--tracks', 'full', '--jobs', '1',
            '--no-plots', '--policy-file', str(MOVING_OUT), '--out', str(out),
            '--methods', 'vi', 'generalist', 'generalist-hand-set', 'generalist-untrained',
            'generalist-cycle-rule']  # fmt: skip
    assert generalist_benchmark.main(argv) == 0
    with open(out / 'results.csv', encoding='utf-8') as stream:
        rows = {r['method']: r for r in csv.DictReader(stream)}
    assert {r['status'] for r in rows.values()} == {'ok'}, rows
    assert len(rows) == 5 and {r['track'] for r in rows.values()} == {'full'}
    assert float(rows['generalist (hand-set)']['regret']) == pytest.approx(0.0, abs=1e-6)
    record = json.loads((out / 'scenarios' / 'gen-1000001.provenance.json').read_text())
    assert record['options']['moving'] == 'sweeping'
    assert 'moving: sweeping' in capsys.readouterr().out
