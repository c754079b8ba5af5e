"""Sweeps without Ray: the sweep file checked and laid out as trials, one trial's runs as
records, and the report written from records (what --resume reads back)."""

import json
from pathlib import Path

import pytest
from stealth_core.scenario import find_scenario
from stealth_experiments import experiments
from stealth_experiments.harness import configured, tuned_config
from stealth_experiments.sweep_plan import (
    MAX_TRIALS,
    SweepError,
    load_plan,
    make_trial,
    parse_plan,
)
from stealth_experiments.sweep_report import SweepStore, best_configurations, write_report
from stealth_experiments.sweep_trials import objective, record_result, ros_command, run_trial

BASE = {'scenarios': ['simple-maze'], 'learners': ['qlearning', 'dyna'], 'seeds': [0, 1]}


def plan(path='sweep.yaml', **fields):
    from pathlib import Path

    return parse_plan({**BASE, **fields}, Path(path))


def test_a_grid_crosses_values_with_seeds_and_ids_depend_only_on_settings():
    grid = plan(params={'alpha': [0.5, 1.0], 'n_planning': [5]})
    trials = grid.fixed_trials()
    assert len(trials) == 2 * 2 * 2  # learners x alpha values x seeds
    assert len({t['id'] for t in trials}) == len(trials)
    assert {t['params']['alpha'] for t in trials} == {0.5, 1.0}
    again = plan(params={'n_planning': [5], 'alpha': [0.5, 1.0]}).fixed_trials()
    assert sorted(t['id'] for t in again) == sorted(t['id'] for t in trials)


def test_a_sweep_may_start_any_learner_from_the_floor_plan_or_from_nothing():
    trials = plan(params={'prior': ['floor_plan', 'none']}).fixed_trials()
    assert len(trials) == 2 * 2 * 2
    assert {(t['learner'], t['params']['prior']) for t in trials} == {
        (learner, prior) for learner in ('qlearning', 'dyna') for prior in ('floor_plan', 'none')
    }
    assert plan(params={'prior': 'none'}).fixed_trials()[0]['params'] == {'prior': 'none'}


def test_random_samples_are_reproducible_and_inside_their_ranges():
    fields = {'search': 'random', 'trials': 3, 'params': {'epsilon': {'low': 0.05, 'high': 0.3}}}
    first, second = plan(**fields).fixed_trials(), plan(**fields).fixed_trials()
    assert [t['id'] for t in first] == [t['id'] for t in second]
    assert len(first) == 2 * 3 * 2
    assert all(0.05 <= t['params']['epsilon'] <= 0.3 for t in first)
    assert plan(**{**fields, 'seed': 1}).fixed_trials()[0]['id'] != first[0]['id']


def test_optuna_lays_out_only_the_extra_trials():
    search = plan(
        search='optuna',
        trials=4,
        params={'alpha': {'low': 0.1, 'high': 1.0}},
        extra=[{'mode': 'ros', 'learner': 'dyna', 'episodes': 20}],
    )
    trials = search.fixed_trials()
    assert [t['mode'] for t in trials] == ['ros'] and trials[0]['seeds'] == [0]
    assert set(search.optuna_space()) == {'alpha'}


@pytest.mark.parametrize(
    ('fields', 'expected'),
    [
        ({'learners': ['ppo']}, "learners: unknown learner 'ppo'"),
        ({'scenarios': ['nowhere']}, "scenarios[0]: scenario 'nowhere'"),
        ({'scenarios': [{'scenario': 'simple-maze', 'goal': 'top'}]}, "has no goal 'top'"),
        ({'params': {'beta': [1]}}, 'params.beta: unknown parameter'),
        ({'params': {'alpha': []}}, 'params.alpha: empty list'),
        ({'search': 'random', 'params': {'alpha': {'low': 1, 'high': 0.5}}}, 'empty range'),
        ({'params': {'alpha': {'low': 0.1, 'high': 0.5}}}, 'a grid needs a list'),
        ({'params': {'alpha': [2.0]}}, 'params.alpha: alpha must stay in [0, 1]'),
        ({'episodes': {'qlearning': 10}}, "episodes: no budget for learner 'dyna'"),
        ({'seeds': []}, 'seeds: expected a non-empty list'),
        ({'colour': 'red'}, 'colour: unknown field'),
        ({'extra': [{'mode': 'ros', 'learner': 'q', 'params': {'alpha': [0.1, 0.2]}}]},
         'extra[0].params.alpha: an extra trial takes one value'),
        ({'learners': ['q', 'dyna', 'qlearning']}, "learners: 'qlearning' is listed twice"),
        ({'seeds': [0, 1, 0]}, 'seeds: 0 is listed twice'),
        ({'scenarios': ['simple-maze', 'map1', 'simple-maze']},
         'scenarios: simple-maze is listed twice'),
        ({'params': {'alpha': [0.5, 1.0, 0.5]}}, 'params.alpha: 0.5 is listed twice'),
        ({'params': {'prior': ['dark']}},
         "params.prior: prior: expected one of floor_plan, none, got 'dark'"),
        ({'mode': 'ros', 'params': {'prior': 'none'}},
         'params.prior: in-process trials only (mode gym): the agent node has no floor plan'),
    ],
)  # fmt: skip
def test_bad_input_is_one_line_naming_the_field(fields, expected):
    with pytest.raises(SweepError) as error:
        plan('bad.yaml', **fields)
    message = str(error.value)
    assert message.startswith('sweep file bad.yaml: ') and expected in message
    assert '\n' not in message


def test_parameters_override_the_tuned_settings():
    config = configured('dyna', False, [('alpha', 0.5), ('epsilon', 0.2), ('n_planning', 3.0)])
    tuned = tuned_config('dyna')
    assert config.alpha(0) == 0.5 and config.epsilon(0) == 0.2 and config.n_planning == 3
    assert config.epsilon.decay == tuned.epsilon.decay and config.gamma == tuned.gamma


def test_a_ros_trial_is_a_stealth_train_with_the_parameters_set(tmp_path):
    trial = make_trial('ros', 'simple-maze', 'easy', 'dyna', [3], 40, 5, 0.0, {'alpha': 0.4})
    command = ros_command(trial, 3, tmp_path)
    assert command[1:3] == ['-m', 'stealth_bringup.orchestrate']
    text = ' '.join(command)
    assert '--seed 3' in text and '--goal easy' in text and '--episodes 40' in text
    assert 'agent.agent=dyna' in text and 'agent.alpha=0.4' in text


def test_runs_become_records_and_the_report_and_resume_read_them(tmp_path):
    ok = make_trial('gym', 'simple-maze', 'easy', 'qlearning', [0, 1], 20, 10, 0.0, {})
    bad = make_trial('gym', 'simple-maze', 'easy', 'qlearning', [0], 20, 10, 0.7, {'alpha': 2.0})
    records = run_trial(ok, {'node': 'n1'})
    assert [r['status'] for r in records] == ['ok', 'ok'] and records[0]['policy']
    assert records[0]['node'] == 'n1' and len(records[0]['eval_returns']) == 2
    result = record_result(records[0])
    assert result.spec.seed == 0 and result.eval_at.tolist() == [10, 20]
    failed = run_trial(bad)
    assert failed[0]['status'] == 'failed' and 'alpha' in failed[0]['error']
    assert objective(failed) == -1.0 and objective(records) > -1.0
    store = SweepStore(tmp_path)
    store.add(records)
    store.add(failed)
    assert store.finished() == {ok['id']}  # the failed trial runs again on --resume
    assert (tmp_path / 'policies' / f'{ok["id"]}-seed1.npz').stat().st_size > 0
    kept = json.loads((tmp_path / 'trials' / f'{ok["id"]}.json').read_text())['records']
    assert 'policy' not in kept[0] and kept[0]['policy_file'].startswith('policies/')
    [best] = best_configurations(store.records())
    assert best['learner'] == 'qlearning' and best['seeds'] == 2
    report = write_report(store, 'unit', 'settings', plots=True)
    text = report.read_text()
    assert '## Best configuration per scenario' in text and 'failed: ValueError' in text
    assert (tmp_path / 'results.csv').read_text().count('\n') == 4  # header + 3 runs
    assert (tmp_path / 'curves_simple-maze.png').stat().st_size > 10_000


def test_a_sweep_of_more_than_max_trials_is_refused_from_its_lists_alone():
    """10^12 combinations: refused at once (laying them out would never end), with the count and
    how it is made; a sweep just under the limit is accepted."""
    values = [round(0.01 * k, 2) for k in range(1, 101)]
    huge = dict.fromkeys(('alpha', 'epsilon', 'gamma', 'initial_value'), values)
    huge['n_planning'] = list(range(1, 101))
    huge['epsilon_decay'] = list(range(1, 101))
    with pytest.raises(SweepError) as error:
        plan('big.yaml', params=huge)
    message = str(error.value)
    assert (
        '4,000,000,000,000 trials (2 scenario x learner group(s) x 1,000,000,000,000 ' in message
    )
    assert f'more than the {MAX_TRIALS:,} a sweep may have' in message and '\n' not in message
    with pytest.raises(SweepError, match='20,000 trials'):
        plan(search='random', trials=5000, params={'alpha': {'low': 0.1, 'high': 1.0}})
    with pytest.raises(SweepError, match='10,002 trials'):
        plan(search='optuna', trials=5001, params={'alpha': {'low': 0.1, 'high': 1.0}})
    under = plan(params={'alpha': values})
    assert under.trial_count()[0] == 2 * 100 * 2 <= MAX_TRIALS


def _scenario_copy(directory: Path) -> Path:
    """map1's scenario file in ``directory`` (its map given by absolute path)."""
    original = find_scenario('map1')
    text = original.read_text().replace(
        'map: ../maps/map1.yaml', f'map: {(original.parent / "../maps/map1.yaml").resolve()}'
    )
    directory.mkdir(parents=True, exist_ok=True)
    (directory / 'map1.yaml').write_text(text)
    return directory / 'map1.yaml'


def test_scenario_paths_in_a_sweep_file_are_relative_to_it_and_made_absolute(
    tmp_path, monkeypatch
):
    scenario = _scenario_copy(tmp_path / 'scenarios')
    sweeps = tmp_path / 'sweeps'
    sweeps.mkdir()
    (sweeps / 'mine.yaml').write_text(
        'scenarios: [../scenarios/map1.yaml, simple-maze]\nlearners: [dyna]\n'
        'extra: [{scenario: ../scenarios/map1.yaml, learner: q, episodes: 5}]\n'
    )
    monkeypatch.chdir(tmp_path / 'scenarios')  # elsewhere: the sweep file's directory counts
    loaded = load_plan(sweeps / 'mine.yaml')
    assert [g.scenario for g in loaded.groups] == [str(scenario), 'simple-maze']
    assert loaded.extra[0]['scenario'] == str(scenario)
    assert all(t['scenario'] in (str(scenario), 'simple-maze') for t in loaded.fixed_trials())
    # A path relative to the current directory, not to the sweep file, is refused by name.
    (sweeps / 'cwd.yaml').write_text('scenarios: [map1.yaml]\nlearners: [dyna]\n')
    with pytest.raises(SweepError) as error:
        load_plan(sweeps / 'cwd.yaml')
    message = str(error.value)
    assert message.startswith(f'sweep file {sweeps / "cwd.yaml"}: scenarios[0]: ')
    assert "map1.yaml is relative to the sweep file's directory" in message
    # --resume reads a copy elsewhere, with the original's directory as the base.
    (tmp_path / 'out').mkdir()
    copy = tmp_path / 'out' / 'sweep.yaml'
    copy.write_bytes((sweeps / 'mine.yaml').read_bytes())
    assert load_plan(copy, sweeps).groups[0].scenario == str(scenario)


def test_scenario_paths_on_the_experiments_command_line_are_relative_to_the_current_directory(
    tmp_path, monkeypatch
):
    """Made absolute before the grid is handed to Ray (whose trials run in a directory of their
    own: a relative path failed there)."""
    _scenario_copy(tmp_path / 'here')
    monkeypatch.chdir(tmp_path)
    handed = []

    def run_grid(scenarios, *args, **kwargs):
        handed.extend(scenarios)
        raise RuntimeError('run x failed: stop here')

    monkeypatch.setattr(experiments, 'run_grid', run_grid)
    code = experiments.main(['--scenarios', 'here/map1.yaml', 'simple-maze', '--learners', 'dyna',
                             '--seeds', '0', '--out', str(tmp_path / 'out')])  # fmt: skip
    assert code == 1  # the RuntimeError is one line, not a traceback
    assert handed == [str(tmp_path / 'here' / 'map1.yaml'), 'simple-maze']


def test_a_resumed_sweep_keeps_the_name_of_its_file(tmp_path, monkeypatch, capsys):
    """--resume reads the copy DIR/sweep.yaml, whose stem is no name: it said `sweep: sweep:`."""
    from stealth_experiments import sweep

    monkeypatch.setattr(sweep, '_run', lambda *args: None)  # no trial runs (no Ray)
    (tmp_path / 'mine.yaml').write_text(
        'scenarios: [simple-maze]\nlearners: [dyna]\nseeds: [0]\nepisodes: 5\n'
    )
    out = tmp_path / 'out'
    assert sweep.main([str(tmp_path / 'mine.yaml'), '--out', str(out), '--no-plots']) == 0
    assert capsys.readouterr().out.splitlines()[0] == (
        f'sweep: mine: 0 trial(s) already finished in {out}, 1 to run'
    )
    assert sweep.main(['--resume', str(out), '--no-plots']) == 0
    assert capsys.readouterr().out.splitlines()[0] == (
        f'sweep: mine: 0 trial(s) already finished in {out}, 1 to run'
    )
    assert (out / 'results.md').read_text().startswith('# Sweep mine\n')
