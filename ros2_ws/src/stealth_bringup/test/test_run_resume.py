"""`stealth train --resume RUN` checked before anything starts: a continued run goes on where
it stopped, and what cannot be continued says why (no ROS)."""

import json
from pathlib import Path

import pytest
from stealth_bringup.episode_tracker import EpisodeRecord, Tracker
from stealth_bringup.run_arguments import train_parser
from stealth_bringup.run_config import RunConfigError
from stealth_bringup.run_outputs import append_episode
from stealth_bringup.run_plan import make_plan
from stealth_bringup.run_report import RunFacts, RunReport

SCENARIOS = Path(__file__).resolve().parents[4] / 'scenarios'


def plan_of(*argv, runs_dir):
    args = train_parser().parse_args([*argv, '--runs-dir', str(runs_dir)])
    return make_plan(args, 'train', ['stealth', 'train', *argv])


def finished_run(tmp_path, episodes=6, eval_every=3):
    """A training run as stealth train leaves it: params/, summary.json, episodes.csv, the
    recording's first file (its contents do not matter here)."""
    plan = plan_of('--episodes', str(episodes), '--eval-every', str(eval_every), '--seed', '4',
                   '--name', 'first', '--prior', 'none', runs_dir=tmp_path)  # fmt: skip
    # --prior none: no policy.npz until the agent saves one (killed before it did, here).
    plan.write_params_files()
    report = RunReport(plan, Tracker(), RunFacts(0.0), print)
    report.write_progress()
    for episode in range(episodes):
        greedy = (episode + 1) % eval_every == 0
        append_episode(record(episode, 'SUCCESS' if greedy else 'TIMEOUT', greedy),
                       plan.file('episodes.csv'))  # fmt: skip
    plan.file('recording.mcap').write_bytes(b'')
    return plan.directory


def record(episode, outcome, greedy):
    return EpisodeRecord(episode, outcome, 10, 1.0, 0.0, 0.0, 5.0, 0.1, greedy, 0.1, 0.3,
                         episode, 10 * episode, 5, float(episode),
                         meets_criterion=outcome == 'SUCCESS')  # fmt: skip


def resume(run, *argv):
    args = train_parser().parse_args(['--resume', str(run), *argv])
    return make_plan(args, 'train', ['--resume', str(run), *argv])


def test_a_continued_run_goes_on_where_it_stopped(tmp_path):
    run = finished_run(tmp_path)
    plan = resume(run, '--episodes', '12', '--success-streak', '0')
    assert plan.directory == run and plan.continued.first_episode == 6
    assert (plan.episodes, plan.eval_every, plan.streak) == (12, 3, 0)  # eval_every the run's
    agent, environment = plan.parameters['agent'].values, plan.parameters['environment'].values
    assert agent['load_policy'] is True and agent['evaluate'] is False
    assert agent['first_episode'] == environment['first_episode'] == 6
    assert agent['seed'] == environment['seed'] == 4  # from the run's own params/
    assert plan.parameters['recorder'].values['output'] == str(run.resolve() / 'recording_1.mcap')
    assert 'continued from episode 6 (6 done), up to 12 episodes in all' in plan.describe()
    assert any('policy.npz is not there' in note for note in plan.notes)
    (run / 'params' / 'recorder.yaml').unlink()  # as a run with --no-record leaves it
    assert 'recorder' not in resume(run, '--episodes', '12').parameters


BUDGET_SPENT = 'the run has 6 episodes, its budget of 6 is spent; give --episodes N, the new'


@pytest.mark.parametrize(
    ('argv', 'message'),
    [
        ([], BUDGET_SPENT),
        (
            ['--episodes', '9', '--success-streak', '2'],
            'the run ended on 2 greedy evaluations in a row that met the success criterion',
        ),
        (['--episodes', '9', '--goal', 'hard'], 'a continued run keeps its goal; drop --goal'),
    ],
)
def test_a_continued_run_that_would_stop_at_once_is_refused(tmp_path, argv, message):
    run = finished_run(tmp_path)
    with pytest.raises(RunConfigError, match=message):
        resume(run, *argv)


def test_what_cannot_be_continued_says_why(tmp_path):
    with pytest.raises(RunConfigError, match='--resume .*nowhere: no such directory'):
        resume(tmp_path / 'nowhere')
    with pytest.raises(RunConfigError, match='not a run directory .it has no summary.json'):
        resume(tmp_path)
    run = finished_run(tmp_path)
    summary = json.loads((run / 'summary.json').read_text())
    (run / 'summary.json').write_text(json.dumps({**summary, 'mode': 'eval'}))
    with pytest.raises(RunConfigError, match='a run of stealth rollout, not a training run'):
        resume(run, '--episodes', '9')


def test_a_run_whose_scenario_changed_is_not_continued(tmp_path):
    scenario = tmp_path / 'mine.yaml'
    text = (SCENARIOS / 'simple-maze.yaml').read_text()
    scenario.write_text(text.replace('../maps/', f'{SCENARIOS.parent / "maps"}/'))
    args = train_parser().parse_args(['--scenario', str(scenario), '--goal', 'easy', '--name',
                                      'mine', '--runs-dir', str(tmp_path)])  # fmt: skip
    plan = make_plan(args, 'train', [])
    plan.write_params_files()
    RunReport(plan, Tracker(), RunFacts(0.0), print).write_progress()
    assert resume(plan.directory).continued.first_episode == 0
    scenario.write_text(scenario.read_text() + '\n# edited\n')
    with pytest.raises(RunConfigError, match=f'its scenario file {scenario} changed since the '
                       'run started'):  # fmt: skip
        resume(plan.directory)


def test_a_continued_run_keeps_its_criterion_unless_given(tmp_path):
    """The criterion's options are summary.json's "criterion"; given again, they replace it."""
    run = finished_run(tmp_path)
    summary_file = run / 'summary.json'
    summary = json.loads(summary_file.read_text())
    summary['criterion'] = {'max_path_ratio': 1.3, 'exposure_tolerance': 0.5}
    summary_file.write_text(json.dumps(summary))
    plan = resume(run, '--episodes', '12')
    assert (plan.criterion.max_path_ratio, plan.criterion.exposure_tolerance) == (1.3, 0.5)
    plan = resume(run, '--episodes', '12', '--max-path-ratio', '1.05')
    assert (plan.criterion.max_path_ratio, plan.criterion.exposure_tolerance) == (1.05, 0.5)
    summary['criterion'] = {'max_path_ratio': 0.5}
    summary_file.write_text(json.dumps(summary))
    with pytest.raises(RunConfigError, match=r'criterion: --max-path-ratio: expected a number in'):
        resume(run, '--episodes', '12')


@pytest.mark.parametrize(
    ('argv', 'line'),
    [
        (['--max-path-ratio', '0.9'], 'argument --max-path-ratio: expected a number in [1, 10], '
                                      "got '0.9'"),
        (['--exposure-tolerance', 'lots'], 'argument --exposure-tolerance: expected a number in '
                                           "[0, 100], got 'lots'"),
    ],
)  # fmt: skip
def test_a_criterion_option_out_of_range_is_one_line_naming_it(capsys, argv, line):
    with pytest.raises(SystemExit) as stop:
        train_parser().parse_args(argv)
    assert stop.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == f'stealth train: error: {line}'


def test_the_run_states_its_criterion(tmp_path):
    plan = plan_of('--max-path-ratio', '1.25', '--episodes', '4', runs_dir=tmp_path)
    assert 'meet the success criterion (path <= 1.25x, exposure <= opt + 0.1)' in plan.describe()
    RunReport(plan, Tracker(), RunFacts(0.0), print).write_progress()
    summary = json.loads(plan.file('summary.json').read_text())
    assert summary['criterion']['max_path_ratio'] == 1.25
    assert summary['criterion']['exposure_tolerance'] == 0.1
