"""`stealth benchmark`'s parts: the regret and its floor, the summary's maths, results.csv's
columns, failed rows (an unreadable scenario, a method that raises), the method registry and
one trial of each kind on a shipped scenario."""

import csv
import math
from pathlib import Path
import subprocess
import sys

import pytest
from stealth_agent.learners import LEARNER_NAMES
from stealth_core.gym_env import lattice_model
from stealth_core.planners import step_terms, value_iteration
from stealth_experiments import benchmark
from stealth_experiments.benchmark_methods import (
    COLUMNS,
    DEFAULT_TRACKS,
    EPISODE_TRACKS,
    METHODS,
    TRACKS,
    floor_of,
    method_name,
    regret,
    run_case,
)
from stealth_experiments.benchmark_plan import (
    TEST_SEED,
    Case,
    file_case,
    generated_cases,
    set_cases,
    trials,
)
from stealth_experiments.benchmark_report import summarise, write_csv, write_summary
from stealth_experiments.harness import RunSpec, policy_path, run

SCENARIO = 'simple-maze'
REQUIRED = (
    'scenario', 'goal', 'track', 'method', 'success', 'detected', 'return', 'vi_return',
    'path_length', 'vi_path_length', 'exposure', 'seconds',
)  # fmt: skip


def _trial(method, tracks=EPISODE_TRACKS, scenario=SCENARIO, goal='easy', **extra):
    case = Case(scenario, Path(scenario).stem, goal, scenario)
    laid = trials([case], [method], list(tracks), episodes=extra.pop('episodes', 50), **extra)
    return laid[0]


# --- the regret and its floor ---------------------------------------------------------------


def test_regret_is_0_at_the_optimum_1_at_the_floor_and_nan_without_a_span():
    assert regret(900.0, 900.0, -1100.0) == 0.0
    assert regret(-1100.0, 900.0, -1100.0) == 1.0
    assert regret(-100.0, 900.0, -1100.0) == pytest.approx(0.5)
    assert regret(-1300.0, 900.0, -1100.0) == pytest.approx(1.1)  # worse than caught at once
    assert math.isnan(regret(0.0, -5.0, -5.0))


def test_the_floor_is_being_detected_at_the_first_step():
    model = lattice_model(SCENARIO, 'hard')
    _, caught, _ = step_terms(model)  # the planners' reward of being detected on each move
    floor = floor_of(model)
    assert floor == pytest.approx(caught[model.start].min())  # the worst first move
    weights = model.task.scenario.rewards
    start_distance = float(model.distance[model.start])
    caught_here = -(weights.detection_penalty + weights.detection_distance_weight * start_distance)
    # one move (at most a diagonal) changes the distance still to go by at most a step's
    step = model.task.scenario.step_distance
    assert abs(floor - caught_here) <= weights.detection_distance_weight * step * 1.5 + 1e-9
    assert floor < value_iteration(model).optimal_return


# --- the summary's maths ----------------------------------------------------------------------


def _row(method, success, regret_value, length, vi_length, exposure, vi_exposure, **extra):
    return {
        'scenario': 's', 'goal': 'g', 'track': 'full', 'method': method, 'status': 'ok',
        'error': '', 'success': success, 'detected': not success, 'regret': regret_value,
        'path_length': length, 'vi_path_length': vi_length, 'exposure': exposure,
        'vi_exposure': vi_exposure, 'seconds': 2.0, 'return': 10.0 * length, **extra,
    }  # fmt: skip


def test_the_summary_rates_regret_path_and_exposure_over_the_rows_that_ran():
    rows = [
        _row('A*', True, 0.0, 12.0, 10.0, 3.0, 1.0),
        _row('A*', True, 0.2, 15.0, 10.0, 1.0, 1.0),
        _row('A*', False, 0.9, 5.0, 10.0, 9.0, 1.0),  # detected: no path or exposure ratio
        {**_row('A*', False, None, 0, 0, 0, 0), 'status': 'failed', 'error': 'x'},
        _row('Dark Path', True, 0.0, 10.0, 10.0, 0.0, 0.0),  # an optimum in the dark
    ]
    summary = {s['method']: s for s in summarise(rows)}
    star = summary['A*']
    assert (star['rows'], star['ran'], star['failed']) == (4, 3, 1)
    assert star['success'] == pytest.approx(2 / 3)
    assert star['detected'] == pytest.approx(1 / 3) and star['undetected'] == pytest.approx(2 / 3)
    assert star['return'] == pytest.approx(sum(r['return'] for r in rows[:3]) / 3)
    assert star['regret'] == pytest.approx((0.0 + 0.2 + 0.9) / 3)
    assert star['path_ratio'] == pytest.approx((1.2 + 1.5) / 2)
    assert star['exposure_ratio'] == pytest.approx((3.0 + 1.0) / (1.0 + 1.0))
    assert summary['Dark Path']['exposure_ratio'] is None  # 0 / 0 is not a ratio
    assert summary['Dark Path']['path_ratio'] == 1.0
    # The success criterion: path <= 1.1x the optimum's, exposure <= the optimum's + 0.1.
    assert star['criterion'] == 0.0  # 1.2x, 1.5x and a detection
    assert summary['Dark Path']['criterion'] == 1.0


def test_the_criterion_column_judges_path_and_exposure_against_the_optimum():
    rows = [
        _row('Dark Path', True, 0.0, 10.5, 10.0, 1.1, 1.0),  # 1.05x, +0.1: meets it
        _row('Dark Path', True, 0.0, 10.5, 10.0, 1.5, 1.0),  # +0.5: too much light
        _row('Dark Path', True, 0.0, 11.5, 10.0, 1.0, 1.0),  # 1.15x: too long
        _row('Dark Path', False, 0.9, 5.0, 10.0, 0.0, 1.0),  # detected
    ]
    (summary,) = summarise(rows)
    assert summary['criterion'] == 0.25 and summary['success'] == 0.75


def test_summary_md_has_a_table_per_track_and_names_the_rows_that_did_not_run(tmp_path):
    rows = [
        _row('A*', True, 0.0, 12.0, 10.0, 3.0, 1.0),
        {**_row('A*', True, 0.0, 1, 1, 0, 0), 'track': 'sensed'},
        {
            **_row('A*', False, None, 0, 0, 0, 0),
            'scenario': 'broken',
            'status': 'failed',
            'error': 'broken.yaml: no such file',
        },  # fmt: skip
    ]
    text = write_summary(tmp_path / 'summary.md', rows, 'settings here', 'a note').read_text()
    assert '## Track: full' in text and '## Track: sensed' in text
    row = '| A* | 100 % | 100 % | 0 % | 0.000 | 120.0 | 1.20 | 3.00 | 3.00 | 2.00 | 2 (1) |'
    assert row in text
    assert 'criterion: met the success criterion (reached the goal undetected, path' in text
    assert '- broken g: failed: A* (full): broken.yaml: no such file' in text
    assert '**a note**' in text and 'settings here' in text


# --- results.csv --------------------------------------------------------------------------------


def test_results_csv_has_the_required_columns_and_empty_cells_for_a_failed_row(tmp_path):
    assert list(COLUMNS[: len(REQUIRED)]) != [] and set(REQUIRED) <= set(COLUMNS)
    rows = run_case(_trial('value iteration'))
    rows.append({'scenario': 'b', 'goal': '', 'track': 'full', 'method': 'A*',
                 'status': 'failed', 'error': 'b.yaml: bad', 'seconds': None})  # fmt: skip
    path = write_csv(tmp_path / 'results.csv', rows)
    with open(path, encoding='utf-8') as stream:
        reader = csv.DictReader(stream)
        assert reader.fieldnames == list(COLUMNS)
        written = list(reader)
    assert [r['track'] for r in written] == ['full', 'sensed', 'full']
    assert written[0]['success'] == 'True' and written[0]['regret'] == '0'
    assert written[0]['return'] == written[0]['vi_return']
    assert written[2]['status'] == 'failed' and written[2]['error'] == 'b.yaml: bad'
    assert written[2]['return'] == '' and written[2]['success'] == ''


# --- failed rows ----------------------------------------------------------------------------


def test_an_unreadable_scenario_is_a_case_naming_the_file_and_its_rows_are_failed(tmp_path):
    broken = tmp_path / 'broken.yaml'
    broken.write_text('not: [yaml\n')
    case = file_case(str(broken), tmp_path)
    assert case.error.startswith(str(broken)) and 'YAML' in case.error
    missing = file_case('no-such-scenario', tmp_path)
    assert 'no-such-scenario' in missing.error
    laid = trials([case], ['value iteration', 'Dark Path'], list(TRACKS))  # learning too
    rows = benchmark.collect(laid, {})
    assert [(r['method'], r['track'], r['status']) for r in rows] == [
        ('value iteration', 'full', 'failed'),
        ('value iteration', 'sensed', 'failed'),
        ('Dark Path', 'full', 'failed'),
    ]
    assert all(r['error'] == case.error and r['file'] == str(broken) for r in rows)


def test_trials_not_done_are_interrupted_rows_and_a_lost_worker_is_a_failed_row():
    laid = [_trial('A*'), _trial('Dark Path')]
    lost = [{'trial': laid[1]['id'], 'status': 'failed', 'error': 'worker lost: killed'}]
    rows = benchmark.collect(laid, {laid[1]['id']: lost})
    assert [(r['method'], r['status']) for r in rows] == [
        ('A*', 'interrupted'), ('A*', 'interrupted'), ('Dark Path', 'failed'),
    ]  # fmt: skip
    assert rows[2]['error'] == 'worker lost: killed'


def test_a_method_that_raises_fails_its_row_only(tmp_path):
    rows = run_case(_trial('policy', policy=str(tmp_path / 'missing.npz')))
    assert len(rows) == 1 and rows[0]['status'] == 'failed'
    assert 'missing.npz: no such file' in rows[0]['error']


# --- methods ------------------------------------------------------------------------------------


def test_the_method_registry_says_which_track_each_method_runs_on():
    assert METHODS['value iteration'] == EPISODE_TRACKS and METHODS['A*'] == EPISODE_TRACKS
    assert (*EPISODE_TRACKS, 'learning') == TRACKS and DEFAULT_TRACKS == EPISODE_TRACKS
    assert METHODS['Dark Path'] == ('full',) and METHODS['policy'] == ('full',)
    for name in ('replan (unknown dark)', 'replan (unknown lit)'):
        assert METHODS[name] == ('sensed',)
    for learner in LEARNER_NAMES:  # light-model too, once registered
        assert METHODS[learner] == ('full', 'learning')
    assert method_name('replan-lit') == 'replan (unknown lit)' and method_name('dyna') == 'dyna'
    with pytest.raises(ValueError, match=r"--methods: unknown method 'greedy' \(expected one of"):
        method_name('greedy')
    laid = trials([Case('s', 's', None, 's')], ['Dark Path', 'replan (unknown dark)'], ['full'])
    assert [(t['method'], t['tracks']) for t in laid] == [('Dark Path', ['full'])]


def test_each_kind_of_method_runs_a_trial_on_a_shipped_scenario(tmp_path):
    optimum = value_iteration(lattice_model(SCENARIO, 'easy')).optimal_return
    rows = {}
    for method in ('A*', 'Dark Path', 'replan (unknown dark)', 'replan (unknown lit)'):
        for row in run_case(_trial(method)):
            rows[method, row['track']] = row
    assert all(r['status'] == 'ok' and r['vi_return'] == optimum for r in rows.values())
    assert rows['A*', 'full']['return'] == rows['A*', 'sensed']['return']
    assert rows['Dark Path', 'full']['success']
    assert rows['replan (unknown dark)', 'sensed']['steps'] > 0
    learned = run_case(_trial('qlearning', episodes=30))
    assert learned[0]['status'] == 'ok' and learned[0]['budget'] == 30
    spec = RunSpec(SCENARIO, 'qlearning', 0, 30, 30, goal='easy', policy_dir=str(tmp_path))
    run(spec)
    played = run_case(_trial('policy', policy=str(policy_path(spec))))
    assert played[0]['status'] == 'ok', played[0]['error']
    assert played[0]['track'] == 'full' and played[0]['regret'] >= 0.0


def test_an_output_directory_that_cannot_be_made_is_one_line(tmp_path, capsys):
    blocker = tmp_path / 'a-file'
    blocker.write_text('')
    assert benchmark.main(['simple-maze', '--out', str(blocker / 'out')]) == 1
    _, err = capsys.readouterr()
    assert err == f'stealth benchmark: --out {blocker / "out"}: cannot be made (Not a directory)\n'


def test_the_test_set_is_the_generated_test_seeds_and_every_shipped_goal(tmp_path):
    cache = tmp_path / 'cache'
    cases = generated_cases(2, cache, print)
    assert [c.label for c in cases] == ['gen-1000000', 'gen-1000001']
    assert all(not c.error and c.goal and Path(c.scenario).is_absolute() for c in cases)
    shipped = [(c.label, c.goal) for c in set_cases('test', 1, cache, print)[1:]]
    assert shipped[:3] == [('simple-maze', goal) for goal in ('easy', 'medium', 'hard')]
    assert len(shipped) == 12


# --- the generalist ------------------------------------------------------------------------


def test_the_generalist_crosses_a_small_unseen_building_on_both_tracks(tmp_path):
    """A 20 x 20 m generated test-range building (static lights): the shipped weights reach
    the goal undetected on the full track; the sensed track runs its episode on the belief."""
    pytest.importorskip('jax')
    from stealth_core.scenario_generator import Options, generate

    path = generate(TEST_SEED + 3, Options(width=20, height=20, lights=3)).write(tmp_path)
    rows = {r['track']: r for r in run_case(_trial('generalist', scenario=str(path), goal=None))}
    assert {r['status'] for r in rows.values()} == {'ok'}, rows
    full = rows['full']
    assert full['success'] and full['return'] >= 0.97 * full['vi_return'], full
    assert rows['sensed']['steps'] > 0 and rows['sensed']['outcome'] != 'none'


def test_the_generalist_without_its_weights_is_refused_in_one_line(tmp_path, capsys):
    pytest.importorskip('jax')
    missing = tmp_path / 'none.npz'
    rows = run_case(_trial('generalist', policy_file=str(missing)))
    assert [r['status'] for r in rows] == ['failed', 'failed']
    assert all(f'{missing}: no such policy file' in r['error'] for r in rows)
    out = tmp_path / 'out'
    argv = ['simple-maze', '--methods', 'generalist', '--policy-file', str(missing)]
    assert benchmark.main([*argv, '--out', str(out)]) == 1
    _, err = capsys.readouterr()
    assert err.startswith(f'stealth benchmark: {missing}: no such policy file')
    assert err.count('\n') == 1


def test_without_the_learning_extra_the_generalist_rows_fail_naming_make_learn():
    """jax missing (in a process of its own): the generalist is no default method, and asked
    for, its rows fail with the extra's one line naming make learn while the others run."""
    script = (
        "import sys; sys.modules['jax'] = None\n"
        'from stealth_experiments import benchmark\n'
        "assert 'generalist' not in benchmark.default_methods()\n"
        'from stealth_experiments.benchmark_methods import run_case\n'
        'from stealth_experiments.benchmark_plan import Case, trials\n'
        "case = Case('simple-maze', 'simple-maze', 'easy', 'simple-maze')\n"
        "for trial in trials([case], ['generalist', 'A*'], ['full']):\n"
        "    row = run_case(trial)[0]; print(row['method'], row['status'], row['error'])\n"
    )
    done = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=120
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    generalist, astar = done.stdout.splitlines()
    assert generalist.startswith('generalist failed MissingExtraError: stealth_learn needs')
    assert 'make learn' in generalist
    assert astar == 'A* ok '
