"""What `stealth benchmark` refuses before it runs anything, in one line and exit 1: a policy
file trained on another scenario (by name and goal, or by map and lights under the same name), a
misspelled scenario, a method on none of the tracks asked for, an --out holding earlier results
(unless --force); --jobs capped at the CPUs the process may use; the counts it prints."""

import os
from pathlib import Path

import pytest
from stealth_agent.learners import make_learner
from stealth_agent.policy_store import save_policy
from stealth_agent.state_index import StateIndex
from stealth_core.scenario import content_identity, load_scenario
from stealth_core.task import StealthTask
from stealth_experiments import benchmark
from stealth_experiments.benchmark_checks import policy_cases
from stealth_experiments.benchmark_plan import shipped_cases, trials
from stealth_experiments.options import capped_jobs

REPO = Path(__file__).resolve().parents[4]
PROG = 'stealth benchmark'


def _policy(path: Path, scenario_file, goal=None, content=True) -> Path:
    """A policy file as a run on that scenario and goal saves it (content: with the hashes)."""
    scenario = load_scenario(scenario_file)
    identity = {'title': StealthTask(scenario, goal).title}
    if content:
        identity.update(content_identity(scenario))
    save_policy(path, make_learner('qlearning', 8), StateIndex(), scenario=identity)
    return path


def _main(capsys, *argv):
    code = benchmark.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# --- a policy file trained on another scenario --------------------------------------------------


def test_a_policy_trained_on_another_scenario_is_refused_before_anything_runs(tmp_path, capsys):
    policy = _policy(tmp_path / 'policy.npz', 'map1')
    out = tmp_path / 'out'
    code, _, err = _main(
        capsys, 'simple-maze', '--methods', 'vi', 'policy', '--policy', policy, '--jobs', '1',
        '--out', out,
    )  # fmt: skip
    assert code == 1
    assert err == (
        f"{PROG}: --policy {policy} was trained on 'stealth-nav: map1 (hard)', not on "
        "'stealth-nav: simple-maze (hard)'; give that scenario (a name or file runs at its "
        'default goal, --set shipped at every shipped goal)\n'
    )
    assert not out.exists()  # nothing made, nothing ran


def test_a_policy_trained_under_the_same_name_on_other_lights_is_refused(tmp_path, capsys):
    policy = _policy(tmp_path / 'policy.npz', 'simple-maze')
    text = (REPO / 'scenarios' / 'simple-maze.yaml').read_text()
    moved = text.replace('x: 0.75, y: 8.0', 'x: 0.75, y: 8.5')
    assert moved != text
    other = tmp_path / 'simple-maze.yaml'  # the same name, a light moved
    other.write_text(moved.replace('map: ../maps/', f'map: {REPO / "maps"}/'))
    code, _, err = _main(
        capsys, other, '--methods', 'policy', '--policy', policy, '--out', tmp_path / 'out'
    )
    assert code == 1
    assert err == (
        f"{PROG}: --policy {policy} was trained on 'stealth-nav: simple-maze (hard)' with "
        f'different lights than {other} has (the same name, other content); give the scenario '
        'file it was trained on, or train a policy on this one\n'
    )


def test_a_policy_runs_only_on_the_scenario_goals_it_was_trained_on(tmp_path):
    cases = shipped_cases()
    policy = _policy(tmp_path / 'policy.npz', 'map1', 'easy')
    fits, notes = policy_cases(policy, cases)
    assert [(c.label, c.goal) for c in fits] == [('map1', 'easy')]
    assert notes == [
        f"--policy {policy} was trained on 'stealth-nav: map1 (easy)': the method policy runs "
        'there only, not on the other 11 scenario goal(s)'
    ]
    laid = trials(cases, ['A*', 'policy'], ['full'], policy=str(policy), policy_cases=fits)
    assert [t['id'] for t in laid if t['method'] == 'policy'] == ['map1-easy-policy']
    assert sum(t['method'] == 'A*' for t in laid) == len(cases)
    unhashed = _policy(tmp_path / 'old.npz', 'map1', 'easy', content=False)
    assert policy_cases(unhashed, cases)[1][0] == (
        f'--policy {unhashed} records no map or lights hash (saved before policies did): only '
        'its scenario name is checked'
    )


# --- names --------------------------------------------------------------------------------------


def test_a_misspelled_scenario_is_refused_in_one_line_listing_the_known_names(tmp_path, capsys):
    out = tmp_path / 'out'
    code, _, err = _main(capsys, 'simple-maze', 'nosuch', '--jobs', '1', '--out', out)
    assert code == 1 and err.count('\n') == 1
    assert err.startswith(f"{PROG}: scenario 'nosuch': not found (known scenarios: ")
    assert 'simple-maze, simple-maze-exposure' in err
    missing = tmp_path / 'missing.yaml'
    code, _, err = _main(capsys, 'simple-maze', missing, '--out', out)
    assert (code, err) == (1, f'{PROG}: scenario {missing}: no such file ({missing})\n')
    assert not out.exists()  # nothing made, nothing ran


def test_a_method_on_none_of_the_tracks_asked_for_is_refused(tmp_path, capsys):
    argv = ['simple-maze', '--out', tmp_path / 'out']
    code, _, err = _main(capsys, *argv, '--methods', 'vi', 'dark-path', '--tracks', 'sensed')
    assert (code, err) == (
        1, f"{PROG}: method 'Dark Path' runs on the full track only, not on --tracks sensed\n"
    )  # fmt: skip
    code, _, err = _main(capsys, *argv, '--methods', 'greedy')
    assert code == 1 and err.startswith(f"{PROG}: --methods: unknown method 'greedy' (expected")
    with pytest.raises(SystemExit) as stop:  # argparse's choices: usage, then the line
        benchmark.main([*map(str, argv), '--tracks', 'sensd'])
    assert stop.value.code == 2
    line = capsys.readouterr().err.splitlines()[-1]
    assert line.startswith(f"{PROG}: error: argument --tracks: invalid choice: 'sensd' (choose")
    assert 'full' in line and 'sensed' in line
    assert not (tmp_path / 'out').exists()


# --- the output directory, the CPUs and the counts ----------------------------------------------


def test_earlier_results_are_refused_unless_force(tmp_path, capsys):
    out = tmp_path / 'out'
    argv = ['simple-maze', '--methods', 'astar', '--tracks', 'full', '--jobs', '1', '--out', out]
    code, _, _ = _main(capsys, *argv)
    assert code == 0 and (out / 'benchmark.png').is_file()
    before = (out / 'results.csv').read_bytes()
    (out / 'results.csv').write_text('an earlier benchmark')
    code, _, err = _main(capsys, *argv)
    assert code == 1
    assert err == (
        f'{PROG}: --out {out}: holds the results of an earlier benchmark (results.csv, '
        'summary.md, benchmark.png, trials.jsonl); give a new or empty directory, or --force '
        'to overwrite them\n'
    )
    assert (out / 'results.csv').read_text() == 'an earlier benchmark'
    code, _, _ = _main(capsys, *argv, '--force', '--no-plots')
    assert code == 0
    assert (out / 'results.csv').read_bytes().splitlines()[0] == before.splitlines()[0]
    assert not (out / 'benchmark.png').exists()  # not the earlier run's beside these


def test_jobs_beyond_the_cpus_the_process_may_use_are_capped_saying_so(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.setattr(os, 'sched_getaffinity', lambda pid: {0, 1}, raising=False)
    assert capped_jobs(2) == (2, '') and capped_jobs(1) == (1, '')
    assert capped_jobs(999) == (2, '--jobs 999: this process may use 2 CPU(s); running on 2')
    assert benchmark.parser().parse_args([]).jobs == 2  # the default: the usable CPUs
    argv = ['simple-maze', '--methods', 'astar', '--tracks', 'full', '--no-plots']
    code, out, _ = _main(capsys, *argv, '--jobs', '999', '--out', tmp_path / 'out')
    assert code == 0
    assert f'{PROG}: --jobs 999: this process may use 2 CPU(s); running on 2\n' in out
    assert '(one after another)' in (tmp_path / 'out' / 'summary.md').read_text()  # 1 trial


def test_the_counts_it_prints_are_trials_and_rows(tmp_path, capsys):
    out = tmp_path / 'out'
    argv = ['simple-maze', '--methods', 'vi', 'astar', '--jobs', '1', '--no-plots', '--out', out]
    code, printed, _ = _main(capsys, *argv)
    assert code == 0
    counted = '2 trials (a method on a scenario goal), 4 rows (a trial on each of its tracks)'
    assert f'benchmark: 1 scenario goal x 2 methods: {counted}\n' in printed
    assert f'{counted} in ' in (out / 'summary.md').read_text()
    assert len((out / 'results.csv').read_text().splitlines()) == 1 + 4
