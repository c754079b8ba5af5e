"""The experiment harness, small: the success criterion and settling on it, one run, the reports,
and a policy trained in-process that the ROS agent's code runs on ROS-style states."""

import csv

import numpy as np
import pytest
from stealth_agent.learners import LEARNER_NAMES
from stealth_agent.policy_store import check_compatible, load_policy
from stealth_agent.protocol import ProtocolAgent
from stealth_core.gym_env import lattice_model
from stealth_core.path_scores import OPTIMUM_GAMMA, Criterion, CriterionError
from stealth_core.planners import value_iteration
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import content_identity
from stealth_core.task import StealthTask
from stealth_experiments import experiments
from stealth_experiments.harness import (
    DEFAULT_EPISODES,
    MOVING_EPISODES,
    SENSED_BASELINES,
    RunSpec,
    baselines,
    configured,
    criterion_params,
    default_budget,
    grid_specs,
    policy_path,
    run,
    sensed_baselines,
    settled,
    settled_within,
    tuned_config,
)
from stealth_experiments.harness_report import _labelled_paths, baseline_row

SCENARIO = 'simple-maze'


@pytest.fixture(scope='module')
def trained(tmp_path_factory):
    """Dyna-Q on simple-maze for 150 episodes (it settles by ~70), policy saved."""
    policy_dir = tmp_path_factory.mktemp('policies')
    return run(RunSpec(SCENARIO, 'dyna', 3, episodes=150, policy_dir=str(policy_dir)))


def test_settled_means_passing_every_evaluation_from_then_on():
    at = np.array([10, 20, 30, 40, 50])
    assert settled(at, [False, True, False, True, True]) == 40
    assert settled(at, [True] * 5) == 10
    assert settled(at, [True, True, True, True, False]) is None
    assert settled([], []) is None


def test_the_old_return_criterion_is_kept_for_runs_without_scores():
    at = np.array([10, 20, 30, 40, 50])
    assert settled_within(at, [900, 990, 900, 985, 999], 1000.0) == 40
    assert settled_within(at, [990, 990, 990, 990, 990], 1000.0) == 10
    assert settled_within(at, [990, 990, 990, 990, 900], 1000.0) is None
    assert settled_within(at, [-1050] * 5, -1000.0) == 10  # 5 % of |optimum| below it
    assert settled_within(at, [-1051] * 5, -1000.0) is None


def test_every_learner_gets_the_same_settings():
    configs = {name: tuned_config(name) for name in ('qlearning', 'sarsa', 'dyna')}
    assert len(set(configs.values())) == 1
    assert configs['dyna'].alpha(0) == 1.0 and tuned_config('q', True).alpha(0) == 0.3
    # Undiscounted, as the optimum the criterion judges by (and agent.yaml's, through ROS).
    assert {tuned_config(name).gamma for name in LEARNER_NAMES} == {OPTIMUM_GAMMA}
    with pytest.raises(ValueError):
        tuned_config('ppo')


def test_prioritized_sweeping_explores_by_optimism_at_the_goal_reward():
    """Given the task's goal reward, prioritized sweeping's untried pairs are worth it and
    epsilon is 0; the other learners' settings do not change with it."""
    optimistic = configured('prioritized', goal_reward=1000.0)
    assert optimistic.initial_value == 1000.0 and optimistic.epsilon(0) == 0.0
    assert optimistic.n_planning == tuned_config('prioritized').n_planning
    for name in ('qlearning', 'sarsa', 'dyna'):
        assert configured(name, goal_reward=1000.0) == tuned_config(name)
    # A sweep may still ask for epsilon-greedy exploration, with the usual time constant.
    swept = configured('prioritized', params=[('epsilon', 0.1)], goal_reward=1000.0)
    assert swept.epsilon(0) == 0.1 and swept.epsilon.decay == 100.0


def test_a_run_learns_the_optimal_path(trained):
    optimum = lattice_model(SCENARIO)
    assert trained.optimum == pytest.approx(value_iteration(optimum).optimal_return)
    assert len(trained.train_returns) == len(trained.train_outcomes) == 150
    assert trained.eval_at.tolist() == list(range(10, 151, 10))
    assert trained.episodes_to_criterion is not None and trained.episodes_to_criterion <= 150
    assert trained.episodes_to_within == trained.episodes_to_criterion  # sweep_trials' name
    assert trained.eval_met[-1] and trained.eval_met.shape == trained.eval_at.shape
    settled_at = int(np.flatnonzero(trained.eval_at == trained.episodes_to_criterion)[0])
    assert trained.eval_met[settled_at:].all()
    optimum_path = trained.optimum_scores
    assert optimum_path.reached and optimum_path.steps > 0
    assert trained.final['path_length'] <= 1.1 * optimum_path.path_length + 1e-9
    assert trained.final['outcome'] == EpisodeOutcome.SUCCESS
    assert trained.final['total_reward'] == pytest.approx(trained.eval_returns[-1])
    assert trained.final['points'].shape == (trained.final['steps'] + 1, 2)


def test_a_converged_learner_meets_the_criterion_where_lights_move():
    """simple-maze-moving, whose optimum discounted at 0.99 takes +0.114 more light than the
    undiscounted one (test_path_scores): at the harness's gamma prioritized sweeping settles on
    a path that meets the default criterion (seed 0: from episode 250)."""
    result = run(RunSpec('simple-maze-moving', 'prioritized', 0, episodes=300))
    assert result.episodes_to_criterion is not None
    assert result.eval_met[-1] and result.final['outcome'] == EpisodeOutcome.SUCCESS
    excess = result.final['accumulated_visibility'] - result.optimum_scores.accumulated_exposure
    assert excess <= 0.1 + 1e-9


def test_a_run_is_reproducible(trained):
    again = run(RunSpec(SCENARIO, 'dyna', seed=3, episodes=30, eval_every=10))
    np.testing.assert_array_equal(again.train_returns, trained.train_returns[:30])
    np.testing.assert_array_equal(again.eval_returns, trained.eval_returns[:3])


def test_the_saved_policy_runs_on_states_the_ros_environment_sends(trained):
    """Train in-process, save, reload into a ProtocolAgent (as the agent node does) and act
    greedily on states made by StealthTask.state_of from poses anywhere in the cell around each
    node, as the ROS environment makes them from the localisation estimate: the robot reaches
    the goal on the optimal path with the optimal return."""
    policy = load_policy(policy_path(trained.spec))
    model = lattice_model(SCENARIO)
    task = StealthTask(model.task.scenario)
    check_compatible(policy, num_actions=4, state_dim=2, learner='dyna', scenario_title=task.title)
    identity = content_identity(task.scenario)  # by content too, for stealth rollout
    assert {key: policy.scenario[key] for key in identity} == identity
    agent = ProtocolAgent(policy.learner, policy.index, np.random.default_rng(0), learning=False)
    noise = np.random.default_rng(1)
    node, reward, total = model.start, 0.0, 0.0
    for step_index in range(1, task.step_limit + 1):
        x, y = model.points[node] + noise.uniform(-0.49, 0.49, size=2) * task.cell
        state = np.array(task.state_of(x, y), dtype=np.float32)
        assert policy.index.lookup(state) is not None, 'a state the policy never saw'
        action = agent.first_action(state) if step_index == 1 else agent.next_action(reward, state)
        node = int(model.successors[node, action])
        judgement = task.judge(*model.points[node], 0.0, step_index)
        reward = judgement.reward
        total += reward
        if judgement.terminal:
            break
    assert judgement.outcome is EpisodeOutcome.SUCCESS
    assert total == pytest.approx(trained.final['total_reward'])


def test_evaluate_writes_the_table_csv_and_pictures(tmp_path):
    rows = experiments.evaluate(
        [SCENARIO], ['qlearning'], [0], episodes=20, eval_every=10, out=tmp_path, progress=False
    )
    methods = [row['method'] for row in rows]
    assert methods == ['A*', 'Dark Path', 'value iteration', 'qlearning']
    with open(tmp_path / 'results.csv', encoding='utf-8') as stream:
        assert [row['method'] for row in csv.DictReader(stream)] == methods
    text = (tmp_path / 'results.md').read_text()
    assert '| simple-maze | A* | detected |' in text
    assert 'not met in 20' in text  # 20 episodes are not enough, and the table says so
    assert "path <= 1.1x the optimum's" in text  # the criterion is stated
    by_method = {row['method']: row for row in rows}
    assert by_method['value iteration']['meets_criterion'] is True
    assert by_method['value iteration']['path_over_optimum'] == 1.0
    assert by_method['A*']['meets_criterion'] is False  # detected
    for name in ('learning_curves.png', f'curves_{SCENARIO}.png', f'paths_{SCENARIO}.png'):
        assert (tmp_path / name).stat().st_size > 10_000
    assert (tmp_path / 'policies' / f'{SCENARIO}-qlearning-seed0.npz').is_file()


def test_the_command_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        experiments.main(['--help'])
    assert stop.value.code == 0 and '--scenarios' in capsys.readouterr().out
    with pytest.raises(SystemExit):
        experiments.main(['--episodes', '0'])
    code = experiments.main(
        ['--scenarios', SCENARIO, '--learners', 'sarsa', '--seeds', '1', '--episodes', '10',
         '--jobs', '1', '--no-plots', '--out', str(tmp_path)]
    )  # fmt: skip
    assert code == 0 and (tmp_path / 'results.md').is_file()
    assert not (tmp_path / 'learning_curves.png').exists()


@pytest.mark.parametrize(
    ('option', 'value', 'line'),
    [
        ('--max-path-ratio', '0.5', "--max-path-ratio: expected a number in [1, 10], got '0.5'"),
        ('--exposure-tolerance', '-1', '--exposure-tolerance: expected a number in [0, 100]'),
    ],
)
def test_a_criterion_option_out_of_range_is_one_line(tmp_path, capsys, option, value, line):
    with pytest.raises(SystemExit) as stop:
        experiments.main([option, value, '--scenarios', SCENARIO, '--out', str(tmp_path)])
    assert stop.value.code == 2
    option_line = line.split(': ', 1)
    assert (
        capsys.readouterr()
        .err.splitlines()[-1]
        .startswith(f'experiments: error: argument {option_line[0]}: {option_line[1]}')
    )
    assert not (tmp_path / 'results.md').exists()  # nothing ran


def test_the_criterion_options_reach_every_run():
    """In RunSpec.params, so that they travel with a run to a Ray worker (sweep_trials._spec
    rebuilds the RunSpec from them); none for the default criterion (trial ids unchanged)."""
    strict = Criterion(max_path_ratio=1.0, exposure_tolerance=0.0)
    specs = grid_specs([SCENARIO], ['dyna'], [0, 1], episodes=10, criterion=strict)
    assert [spec.criterion for spec in specs] == [strict, strict]
    assert criterion_params(Criterion()) == ()
    assert grid_specs([SCENARIO], ['dyna'], [0], episodes=10)[0].params == ()
    with pytest.raises(CriterionError, match='--max-path-ratio'):
        run(RunSpec(SCENARIO, 'dyna', 0, episodes=1, params=(('max_path_ratio', 20.0),)))


def test_a_stricter_criterion_never_passes_more_evaluations():
    """The same learning judged by a criterion that allows no longer path than the optimum's:
    never an evaluation more met than under the default."""
    loose = run(RunSpec(SCENARIO, 'dyna', 3, episodes=30, eval_every=10))
    tight = run(
        RunSpec(SCENARIO, 'dyna', 3, episodes=30, eval_every=10, params=(('max_path_ratio', 1.0),))
    )
    np.testing.assert_array_equal(loose.eval_returns, tight.eval_returns)  # the same learning
    assert (tight.eval_met <= loose.eval_met).all()


def test_the_moving_variants_are_in_the_grid_with_their_optimum_and_time_aware_dark_path(
    tmp_path,
):
    assert {'simple-maze-moving', 'floorplan-moving'} <= set(experiments.DEFAULT_SCENARIOS)
    assert default_budget('dyna', 'simple-maze-moving') == MOVING_EPISODES['dyna']
    assert default_budget('dyna', 'simple-maze') == DEFAULT_EPISODES['dyna']
    rows = experiments.evaluate(
        ['simple-maze-moving'], ['dyna'], [0], episodes=5, out=tmp_path, plots=False,
        progress=False,
    )  # fmt: skip
    by_method = {row['method']: row for row in rows}
    assert by_method['A*']['greedy_outcome'] == 'DETECTED'
    assert by_method['Dark Path']['greedy_outcome'] == 'SUCCESS'
    assert by_method['Dark Path']['greedy_over_optimum'] > 0.95
    assert by_method['value iteration']['greedy_outcome'] == 'SUCCESS'
    assert '| simple-maze-moving | Dark Path | success |' in (tmp_path / 'results.md').read_text()


def test_the_exposure_variants_are_in_the_grid_at_the_static_budgets(tmp_path):
    """make compare measures the exposure variants (README: all six runs per variant met the
    criterion at these budgets); a learner takes the heading and the turns from the environment."""
    assert {'simple-maze-exposure', 'map1-exposure'} <= set(experiments.DEFAULT_SCENARIOS)
    assert default_budget('dyna', 'map1-exposure') == DEFAULT_EPISODES['dyna']
    assert default_budget('qlearning', 'simple-maze-exposure') == DEFAULT_EPISODES['qlearning']
    result = run(RunSpec('map1-exposure', 'dyna', 0, episodes=5, eval_every=5))
    assert result.optimum == pytest.approx(
        value_iteration(lattice_model('map1-exposure')).optimal_return
    )
    assert len(result.final['points']) == result.final['steps'] + 1


def test_the_sensed_baselines_play_the_sensed_track_into_the_report_rows():
    found = sensed_baselines('simple-maze', 'easy')
    assert [b.name for b in found] == list(SENSED_BASELINES)
    optimum = value_iteration(lattice_model('simple-maze', 'easy')).optimal_return
    for baseline in found:
        assert baseline.summary['outcome'] is EpisodeOutcome.SUCCESS
        assert len(baseline.summary['points']) == baseline.summary['steps'] + 1
        row = baseline_row('simple-maze', 'easy', optimum, baseline)
        assert row['meets_criterion'] == ''  # no optimum's scores given
        assert row['method'] == baseline.name and row['success_rate'] == 1.0
        assert row['greedy_return'] <= optimum + 1e-9


def test_every_path_in_the_picture_is_labelled_with_its_scores_against_the_optimum(trained):
    _, found = baselines(lattice_model(SCENARIO))
    labels = [label for _, label in _labelled_paths(found, [trained])]
    assert labels[0].startswith('A*: detected, 15 steps, 7.5 m (0.18x), exposure')
    assert labels[2] == 'value iteration: success, 83 steps, 41.5 m, exposure 0.00, peak 0.00'
    assert labels[3].startswith(f'dyna seed 3: success, {trained.final["steps"]} steps, ')
    assert '(1.0' in labels[3]  # its path's ratio to the optimum's


def test_with_slip_an_evaluation_is_judged_on_the_mean_of_its_rollouts():
    """Ten rollouts per evaluation with slip: the criterion judges their mean path and
    exposure, and fails the evaluation unless every one reached the goal undetected (20
    episodes of this seed are not enough for that)."""
    result = run(RunSpec(SCENARIO, 'dyna', 0, episodes=20, eval_every=10, slip=0.1))
    assert result.eval_met.tolist() == [False, False]
    assert result.episodes_to_criterion is None


@pytest.mark.parametrize(
    ('field', 'value'), [('episodes', 0), ('eval_every', 0), ('slip', 1.5), ('slip', -0.1)]
)
def test_a_run_spec_out_of_range_is_refused_naming_its_field(field, value):
    with pytest.raises(ValueError, match=f'RunSpec: .*{field}'):
        RunSpec('simple-maze', 'qlearning', 0, **{field: value})
