"""`stealth benchmark`'s learning track: the medians over seeds, the regret curve's band, and
the track end to end on a tiny budget (in this process, --jobs 1)."""

import csv

import numpy as np
import pytest
from stealth_experiments import benchmark
from stealth_experiments.benchmark_learning import median_of, summarise_seeds
from stealth_experiments.benchmark_learning_report import (
    band,
    learner_colours,
    summarise_learning,
)
from stealth_experiments.benchmark_methods import LEARNERS, METHODS


def _seed(episodes, detections, curve=(0, 1, 1)):
    met = episodes is not None
    return {
        'seed': 0,
        'episodes_to_criterion': episodes,
        'detections_to_criterion': detections,
        'steps_to_criterion': 10 * episodes if met else None,
        'seconds_to_criterion': 0.5 * episodes if met else None,
        'training_detections': curve[-1],
        'curve': list(curve),
    }


def test_a_seed_that_never_met_the_criterion_counts_as_more_than_any():
    assert median_of([5, None, 7]) == 7
    assert median_of([5, None, None]) is None
    assert median_of([None]) is None and median_of([]) is None
    assert median_of([4, 8]) == 6


def test_a_rows_figures_are_the_medians_over_its_seeds():
    row = summarise_seeds([_seed(5, 2, (1, 2, 2)), _seed(None, None, (1, 3, 6)), _seed(9, 4)])
    assert row['seeds_met'] == '2/3'
    assert (row['episodes_to_criterion'], row['detections_to_criterion']) == (9, 4)
    assert (row['steps_to_criterion'], row['seconds_to_criterion']) == (90, 4.5)
    assert row['training_detections'] == 2  # over the budget: every seed has it


def test_the_band_is_the_median_and_the_range_over_the_episodes_every_seed_trained():
    median, low, high = band([[0, 1, 1, 2], [1, 1, 2], [0, 0, 3]])
    assert list(median) == [0, 1, 2] and list(low) == [0, 0, 1] and list(high) == [1, 1, 3]


def test_the_learners_and_only_they_run_on_the_learning_track():
    assert {m for m, tracks in METHODS.items() if 'learning' in tracks} == set(LEARNERS)


def test_the_help_describes_the_learning_track(capsys):
    with pytest.raises(SystemExit):
        benchmark.main(['--help'])
    text = ' '.join(capsys.readouterr().out.split())
    assert 'The learning track (not a default' in text and '--learning-seeds' in text
    assert 'until the first of 3 evaluations in a row' in text and 'learning.png' in text


def test_the_learning_track_end_to_end_on_a_tiny_budget(tmp_path):
    """Prioritized sweeping and Dyna-Q on simple-maze's default goal, 2 seeds of 25 episodes:
    prioritized sweeping meets the criterion within them (it needs 5 on seeds 0-2), Dyna-Q
    (about 70) does not, and says so; the curves are each seed's detections."""
    out = tmp_path / 'out'
    argv = ['simple-maze', '--tracks', 'learning', '--methods', 'prioritized', 'dyna',
            '--episodes', '25', '--learning-seeds', '2', '--jobs', '1']  # fmt: skip
    assert benchmark.main([*argv, '--out', str(out)]) == 0
    assert sorted(p.name for p in out.iterdir() if p.is_file()) == [
        'learning.csv', 'learning.png', 'results.csv', 'summary.md', 'trials.jsonl',
    ]  # fmt: skip
    with open(out / 'results.csv', encoding='utf-8') as stream:
        rows = {r['method']: r for r in csv.DictReader(stream)}
    assert set(rows) == {'prioritized', 'dyna'}
    swept, dyna = rows['prioritized'], rows['dyna']
    assert swept['track'] == 'learning' and swept['status'] == 'ok' and swept['budget'] == '25'
    assert swept['seeds_met'] == '2/2' and 1 <= float(swept['episodes_to_criterion']) <= 22
    assert float(swept['steps_to_criterion']) > 0 and float(swept['seconds_to_criterion']) > 0
    assert dyna['seeds_met'] == '0/2' and dyna['episodes_to_criterion'] == ''
    assert swept['return'] == '' and swept['success'] == ''  # no single episode here
    with open(out / 'learning.csv', encoding='utf-8') as stream:
        seeds = list(csv.DictReader(stream))
    assert [(s['method'], s['seed']) for s in seeds] == [
        ('prioritized', '0'), ('prioritized', '1'), ('dyna', '0'), ('dyna', '1'),
    ]  # fmt: skip
    for seed in seeds:
        curve = np.array([int(v) for v in seed['cumulative_detections'].split()])
        assert len(curve) == int(seed['episodes']) == 25 and (np.diff(curve) >= 0).all()
        assert curve[-1] == int(seed['training_detections'])
        if seed['episodes_to_criterion']:
            reached = int(seed['episodes_to_criterion'])
            assert curve[reached - 1] == int(seed['detections_to_criterion'])
    summary = (out / 'summary.md').read_text(encoding='utf-8')
    assert '## Track: learning' in summary and '| prioritized | 1/1 |' in summary
    assert '| dyna | 0/1 | never |' in summary and '## Track: full' not in summary
    assert 'on the learning track on 2 seeds from 0 on' in summary
    assert (out / 'learning.png').stat().st_size > 10_000


def test_without_the_learning_track_no_learning_files_are_left(tmp_path):
    out = tmp_path / 'out'
    out.mkdir()
    (out / 'learning.csv').write_text('an earlier benchmark\n')
    (out / 'learning.png').write_bytes(b'')
    argv = ['simple-maze', '--methods', 'vi', '--jobs', '1', '--out', str(out)]
    assert benchmark.main(argv) == 1  # an earlier benchmark's results: refused
    assert benchmark.main([*argv, '--force']) == 0
    assert not (out / 'learning.csv').exists() and not (out / 'learning.png').exists()


def test_the_summary_of_a_method_counts_the_rows_its_median_seed_met_the_criterion_on():
    def row(episodes, status='ok'):
        return {'track': 'learning', 'method': 'm', 'status': status, 'seconds': 1.0,
                'seeds_met': '', 'episodes_to_criterion': episodes,
                'detections_to_criterion': None if episodes is None else 1,
                'steps_to_criterion': None, 'seconds_to_criterion': None,
                'training_detections': 3}  # fmt: skip

    (entry,) = summarise_learning([row(4), row(None), row(10), row(None, 'failed')])
    assert (entry['rows'], entry['ran'], entry['met']) == (4, 3, 2)
    assert entry['episodes_to_criterion'] == 10 and entry['training_detections'] == 3


def test_every_learner_on_the_plot_has_its_own_colour():
    colours = learner_colours([*LEARNERS, 'another-learner'])
    assert len(set(colours.values())) == len(colours)
