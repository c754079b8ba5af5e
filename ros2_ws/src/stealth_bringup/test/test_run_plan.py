"""The train command line checked and laid out before anything starts (no ROS)."""

from pathlib import Path
import socket

import pytest
from stealth_bringup.run_arguments import train_parser
from stealth_bringup.run_config import RunConfigError
from stealth_bringup.run_plan import make_plan

SCENARIOS = Path(__file__).resolve().parents[4] / 'scenarios'


def plan_of(*argv, runs_dir):
    args = train_parser().parse_args([*argv, '--runs-dir', str(runs_dir)])
    return make_plan(args, 'train', ['stealth', 'train', *argv])


@pytest.mark.parametrize(
    'scenario', ['simple-maze', str(SCENARIOS / 'simple-maze.yaml'), 'scenarios/simple-maze.yaml']
)
def test_the_default_scenario_defaults_to_its_quick_goal_however_it_is_named(
    scenario, tmp_path, monkeypatch
):
    monkeypatch.chdir(SCENARIOS.parent)
    assert plan_of('--scenario', scenario, runs_dir=tmp_path).goal == 'easy'


def test_other_scenarios_default_to_their_own_goal(tmp_path):
    from stealth_core.scenario import load_scenario

    plan = plan_of('--scenario', 'lgfloor', runs_dir=tmp_path)
    assert plan.goal == load_scenario('lgfloor').default_goal


@pytest.mark.parametrize(
    ('argv', 'message'),
    [
        (['--seed', 'abc'], "argument --seed: 'abc' is not a whole number"),
        (['--episodes', '2.5'], "argument --episodes: '2.5' is not a whole number"),
        (['--stall-timeout', 'soon'], "argument --stall-timeout: 'soon' is not a number"),
    ],
)
def test_bad_numbers_name_the_option_and_the_value(argv, message, capsys):
    with pytest.raises(SystemExit):
        train_parser().parse_args(argv)
    assert capsys.readouterr().err.strip().splitlines()[-1].endswith(message)


def test_unknown_parameter_names_are_refused_before_anything_exists(tmp_path):
    with pytest.raises(RunConfigError, match=r"--set agent.epsilonn: agent has no parameter "
                       r"'epsilonn'; did you mean 'epsilon'\?"):  # fmt: skip
        plan_of('--set', 'agent.epsilonn=0.2', runs_dir=tmp_path / 'runs')
    params = tmp_path / 'params'
    params.mkdir()
    (params / 'simulator.yaml').write_text('simulator:\n  ros__parameters:\n    partcles: 9\n')
    with pytest.raises(RunConfigError, match=f"parameter file {params / 'simulator.yaml'}: "
                       "simulator has no parameter 'partcles'"):  # fmt: skip
        plan_of('--params-dir', str(params), runs_dir=tmp_path / 'runs')
    assert not (tmp_path / 'runs').exists()


def test_a_params_dir_value_the_run_sets_is_refused_or_said(tmp_path):
    params = tmp_path / 'params'
    params.mkdir()
    (params / 'agent.yaml').write_text('agent:\n  ros__parameters:\n    load_policy: true\n')
    refused = r'agent.load_policy: true is set by the run itself \(here to false\); use stealth'
    with pytest.raises(RunConfigError, match=refused + ' train --resume'):
        plan_of('--params-dir', str(params), runs_dir=tmp_path / 'runs')
    (params / 'agent.yaml').write_text('agent:\n  ros__parameters:\n    first_episode: 6\n')
    with pytest.raises(RunConfigError, match=r'agent.first_episode: 6 is set by the run itself'):
        plan_of('--params-dir', str(params), runs_dir=tmp_path / 'runs')
    (params / 'agent.yaml').write_text(
        'agent:\n  ros__parameters:\n    policy_file: /elsewhere/policy.npz\n    epsilon: 0.3\n'
    )
    plan = plan_of('--params-dir', str(params), '--prior', 'none', runs_dir=tmp_path / 'runs')
    assert plan.parameters['agent'].values['epsilon'] == 0.3
    assert plan.parameters['agent'].values['policy_file'] == str(plan.policy_path.resolve())
    (note,) = plan.notes
    assert 'agent.policy_file /elsewhere/policy.npz replaced by the run' in note


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def test_watch_adds_the_foxglove_bridge_on_its_port(tmp_path):
    plain = plan_of(runs_dir=tmp_path)
    assert 'bridge' not in plain.nodes and plain.watch_port is None
    port = free_port()
    plan = plan_of('--watch', '--set', f'bridge.port={port}', runs_dir=tmp_path)
    assert plan.nodes == ['recorder', 'bridge', 'simulator', 'environment', 'agent']
    assert plan.commands['bridge'][0].endswith('/stealth_tools/bridge')
    assert plan.watch_port == port
    assert plan.parameters['simulator'].values['real_time_factor'] == 1.0


def test_watch_with_the_bridge_port_in_use_is_one_line_naming_port_and_option(tmp_path):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(RunConfigError) as error:
            plan_of('--watch', '--set', f'bridge.port={port}', runs_dir=tmp_path)
    message = str(error.value)
    assert '\n' not in message and f'port {port} is in use' in message
    assert message.endswith('--set bridge.port=N')
    assert not (tmp_path / 'runs').exists()  # nothing was made


@pytest.mark.parametrize(('value', 'shown'), [('99999', '99999'), ('-5', '-5'), ('abc', "'abc'")])
def test_watch_with_a_bridge_port_that_is_no_port_is_one_line(value, shown, tmp_path):
    with pytest.raises(RunConfigError) as error:
        plan_of('--watch', '--set', f'bridge.port={value}', runs_dir=tmp_path / 'runs')
    assert str(error.value) == (
        f'--set bridge.port: expected a TCP port, a whole number from 1 to 65535, got {shown}'
    )
    assert not (tmp_path / 'runs').exists()


def test_a_bridge_port_that_is_no_port_in_a_parameter_file_names_the_file(tmp_path):
    params = tmp_path / 'params'
    params.mkdir()
    (params / 'bridge.yaml').write_text('bridge:\n  ros__parameters:\n    port: 70000\n')
    with pytest.raises(RunConfigError, match=f'^{params / "bridge.yaml"}: bridge.port: expected'):
        plan_of('--watch', '--params-dir', str(params), runs_dir=tmp_path / 'runs')


def test_a_bridge_executable_without_watch_is_refused(tmp_path):
    with pytest.raises(RunConfigError, match='this run has no bridge node'):
        plan_of('--executable', 'bridge=/bin/true', runs_dir=tmp_path)


def test_compose_runs_the_simulator_in_the_environments_process(tmp_path):
    plan = plan_of('--compose', '--set', 'simulator.seed=5', runs_dir=tmp_path)
    assert plan.composed and 'simulator' not in plan.commands
    assert Path(plan.commands['environment'][0]).name == 'sim_env'
    assert plan.nodes == ['recorder', 'simulator', 'environment', 'agent']  # all on the graph
    assert plan.process_of('simulator') == 'environment' == plan.process_of('environment')
    files = [str(plan.params_file(n).resolve()) for n in ('simulator', 'environment')]
    # Both files, and no -p: `-p seed:=5` would set the environment's seed too.
    assert plan.ros_args('environment') == [
        '--ros-args', '--params-file', files[0], '--params-file', files[1]
    ]  # fmt: skip
    assert plan.parameters['simulator'].values['seed'] == 5  # in the simulator's file
    separate = plan_of('--set', 'simulator.seed=5', runs_dir=tmp_path / 'separate')
    assert not separate.composed and separate.process_of('simulator') == 'simulator'
    assert separate.ros_args('simulator')[-2:] == ['-p', 'seed:=5']


@pytest.mark.parametrize(
    ('argv', 'message'),
    [
        (['--watch'], '--compose with --watch: the simulator paced to real time'),
        (['--remote', 'simulator'], '--compose with --remote simulator: the simulator and'),
        (['--executable', 'environment=/bin/true'], '--compose with --executable environment'),
    ],
)
def test_compose_refuses_what_one_process_cannot_be(argv, message, tmp_path):
    with pytest.raises(RunConfigError, match=message):
        plan_of('--compose', *argv, runs_dir=tmp_path / 'runs')
    assert not (tmp_path / 'runs').exists()


@pytest.mark.parametrize(('scenario', 'features'), [('simple-maze', 2), ('map1-exposure', 3)])
def test_the_sensed_track_keys_the_agents_table_on_the_full_tracks_state(
    scenario, features, tmp_path
):
    plan = plan_of('--scenario', scenario, runs_dir=tmp_path)
    assert plan.parameters['agent'].values['state_features'] == 0  # full: every feature
    plan = plan_of('--scenario', scenario, '--set', 'environment.track=sensed', runs_dir=tmp_path)
    assert plan.parameters['environment'].values['track'] == 'sensed'
    assert plan.parameters['agent'].values['state_features'] == features
    plan = plan_of(
        '--scenario', scenario, '--set', 'environment.track=sensed', '--set',
        'agent.state_features=1', runs_dir=tmp_path,
    )  # fmt: skip
    assert plan.parameters['agent'].values['state_features'] == 1


def test_a_floor_plan_prior_is_the_runs_policy_file_with_a_row_per_place(tmp_path):
    """--prior floor_plan: the agent loads a table whose every lattice state holds value
    iteration's action values with the lights dark, at the agent's gamma, for its learner."""
    import numpy as np
    from stealth_agent.policy_store import check_compatible, load_policy
    from stealth_core.floor_plan_prior import floor_plan_values
    from stealth_core.gym_env import lattice_model

    plan = plan_of('--prior', 'floor_plan', '--set', 'agent.gamma=0.95', runs_dir=tmp_path)
    agent = plan.parameters['agent'].values
    assert agent['load_policy'] is True and Path(agent['policy_file']) == plan.policy_path
    policy = load_policy(plan.policy_path)
    check_compatible(policy, num_actions=4, learner='prioritized', scenario_title=None)
    model = lattice_model('simple-maze', plan.goal)
    values = floor_plan_values(model, gamma=0.95)
    assert len(policy.index) == len(model.states) and policy.learner.episodes == 0
    for place in (model.start, len(model.states) // 2):
        row = policy.index.lookup(model.states[place])
        np.testing.assert_allclose(policy.learner.values(row), values[place])
    assert any('starts from the floor plan (603 states)' in note for note in plan.notes)
    # With --prior none the agent starts from a fresh table.
    fresh = plan_of('--prior', 'none', '--name', 'fresh', runs_dir=tmp_path)
    assert fresh.parameters['agent'].values['load_policy'] is False
    assert not fresh.policy_path.exists()


def test_prioritized_sweeping_starts_from_the_floor_plan_by_default(tmp_path):
    plan = plan_of(runs_dir=tmp_path)
    assert plan.parameters['agent'].values['load_policy'] is True and plan.policy_path.is_file()
    assert any('starts from the floor plan' in note for note in plan.notes)
    assert not any('epsilon 0' in note for note in plan.notes)


@pytest.mark.parametrize(
    'argv',
    [
        ['--set', 'agent.agent=dyna'],
        ['--set', 'agent.agent=generalist'],
        ['--set', 'environment.track=sensed'],
    ],
)
def test_where_no_table_takes_it_the_default_prior_is_none_without_a_word(argv, tmp_path):
    plan = plan_of(*argv, runs_dir=tmp_path)
    assert plan.parameters['agent'].values['load_policy'] is False
    assert not plan.policy_path.exists()
    assert not any('floor plan' in note for note in plan.notes)


def test_a_learner_that_explores_at_random_is_told_epsilon_is_0(tmp_path):
    plan = plan_of('--set', 'agent.agent=dyna', runs_dir=tmp_path)
    assert any(
        'agent dyna with epsilon 0' in note and 'agent.epsilon=0.2' in note for note in plan.notes
    )
    plan = plan_of('--set', 'agent.agent=dyna', '--set', 'agent.epsilon=0.2', runs_dir=tmp_path)
    assert not any('epsilon 0' in note for note in plan.notes)


@pytest.mark.parametrize(
    ('argv', 'message'),
    [
        (['--set', 'agent.agent=generalist'], "--prior: agent 'generalist' keeps no table"),
        (['--set', 'environment.track=sensed'], '--prior: the full track only'),
    ],
)
def test_a_prior_where_no_table_can_take_it_is_one_line(argv, message, tmp_path):
    with pytest.raises(RunConfigError, match=message):
        plan_of('--prior', 'floor_plan', *argv, runs_dir=tmp_path)
    assert not any(tmp_path.iterdir())  # refused before the run's directory exists


@pytest.mark.parametrize(('argv', 'readers'), [([], 2), (['--no-record'], 1)])
def test_episodes_start_once_the_run_s_step_readers_are_matched(argv, readers, tmp_path):
    """The monitor (and the recorder) must have every step: an episode whose steps were built
    before its reader was matched cannot be scored."""
    plan = plan_of(*argv, runs_dir=tmp_path)
    assert plan.parameters['environment'].values['step_readers'] == readers


@pytest.mark.parametrize(('value', 'shown'), [('1.5', '1.5'), ('-0.5', '-0.5'), ('abc', "'abc'")])
def test_a_set_value_out_of_its_range_is_one_line_and_leaves_nothing(value, shown, tmp_path):
    """With the default prior (floor_plan for prioritized sweeping), a gamma the floor plan's
    value iteration cannot take was a traceback and an empty run directory that took the
    name."""
    runs = tmp_path / 'runs'
    runs.mkdir()
    with pytest.raises(RunConfigError) as error:
        plan_of('--set', f'agent.gamma={value}', '--name', 'g', runs_dir=runs)
    assert str(error.value) == f'--set agent.gamma: expected a number from 0 to 1, got {shown}'
    assert not any(runs.iterdir())
    plan = plan_of('--set', 'agent.gamma=0.9', '--name', 'g', runs_dir=runs)  # the name is free
    assert plan.directory == runs / 'g' and plan.parameters['agent'].values['gamma'] == 0.9


@pytest.mark.parametrize(
    ('item', 'message'),
    [
        ('simulator.particles=5', 'expected a whole number from 10 to 100000, got 5'),
        ('simulator.laser_noise=true', 'expected a number from 0 to 1, got True'),
        ('environment.seed=1.5', 'expected a whole number from 0 to 2147483647, got 1.5'),
        ('environment.track=partial', "track must be one of full, sensed, got 'partial'"),
        ('agent.agent=sarsaa', "unknown learner 'sarsaa' (expected one of"),
        ('agent.epsilon_schedule=cosine', 'epsilon_schedule must be one of constant, linear'),
        ('agent.initialvalue=.inf', 'expected a finite number, got inf'),
        ('recorder.batch_period=2', 'expected a number from 0 to 1, got 2'),
        ('recorder.chunk_size=big', "expected a whole number from 1 to 2147483647, got 'big'"),
        ('recorder.topics=/odom', "expected a list of strings, got '/odom'"),
    ],
)
def test_every_node_s_set_values_are_checked_against_its_table(item, message, tmp_path):
    runs = tmp_path / 'runs'
    with pytest.raises(RunConfigError) as error:
        plan_of('--set', item, runs_dir=runs)
    assert str(error.value).startswith(f'--set {item.partition("=")[0]}: {message}')
    assert not runs.exists()


def test_a_value_out_of_range_in_a_parameter_file_names_the_file(tmp_path):
    params = tmp_path / 'params'
    params.mkdir()
    (params / 'simulator.yaml').write_text('simulator:\n  ros__parameters:\n    laser_beams: 2\n')
    with pytest.raises(RunConfigError) as error:
        plan_of('--params-dir', str(params), runs_dir=tmp_path / 'runs')
    assert str(error.value) == (
        f'parameter file {params / "simulator.yaml"}: simulator.laser_beams: expected a whole '
        'number from 3 to 3600, got 2'
    )
    assert not (tmp_path / 'runs').exists()


def test_a_whole_number_for_a_double_is_passed_as_a_double(tmp_path):
    """rclpy refuses an integer for a double parameter: `-p summary_wait:=5` stopped the agent
    (a parameter its file has was made a double already; one it has not was not)."""
    plan = plan_of('--set', 'agent.summary_wait=5', '--set', 'simulator.idle_period=1',
                   runs_dir=tmp_path)  # fmt: skip
    assert plan.parameters['agent'].overrides['summary_wait'] == 5.0
    assert isinstance(plan.parameters['agent'].values['summary_wait'], float)
    assert 'summary_wait:=5.0' in plan.ros_args('agent')
    assert 'idle_period:=1.0' in plan.ros_args('simulator')


def test_a_prior_that_cannot_be_written_leaves_no_run_directory(tmp_path, monkeypatch):
    from stealth_bringup import run_plan

    def full_disk(path, *args):
        Path(path).write_bytes(b'part')
        raise OSError(28, 'No space left on device')

    monkeypatch.setattr(run_plan, 'write_prior_policy', full_disk)
    runs = tmp_path / 'runs'
    runs.mkdir()
    with pytest.raises(RunConfigError, match=r'cannot write the prior: .*No space left'):
        plan_of('--name', 'g', runs_dir=runs)
    assert not any(runs.iterdir())


def test_light_model_is_given_the_scenario_without_its_lights(tmp_path):
    from stealth_core.scenario import load_scenario
    import yaml

    plan = plan_of('--learner', 'light_model', '--scenario', 'simple-maze', runs_dir=tmp_path)
    agent = plan.parameters['agent'].values
    assert agent['agent'] == 'light-model'
    world = Path(agent['world_file'])
    assert world == (plan.directory / 'world.yaml').resolve() and world.is_file()
    fields = yaml.safe_load(world.read_text())
    assert fields['lights'] == [] and fields['default_goal'] == 'easy'
    assert load_scenario(world).lights == ()
    shown = yaml.safe_dump(agent)
    for light in load_scenario('simple-maze').lights:  # no light reaches the agent's values
        assert light.name not in shown and light.name not in world.read_text()
    assert not any('light' in key and key != 'lights_sha256' for key in agent)
    assert plan.parameters['agent'].values.get('load_policy') is False  # no prior table
    assert not any('epsilon 0' in note for note in plan.notes)


def test_light_model_on_moving_lights_is_given_their_timing_not_the_lights(tmp_path):
    import yaml

    plan = plan_of('--learner', 'light-model', '--scenario', 'map1-moving', runs_dir=tmp_path)
    world = Path(plan.parameters['agent'].values['world_file'])
    fields = yaml.safe_load(world.read_text())
    assert fields['lights'] == [] and fields['phase_bins'] == 8
    assert fields['cycle_seconds'] == 24.0 and fields['step_seconds'] == 3.0
    assert 'kitchen' not in world.read_text()


@pytest.mark.parametrize(
    ('argv', 'message'),
    [
        (['--prior', 'floor_plan'], '--prior: light-model plans on the floor plan itself'),
        (['--set', 'agent.agent=dyna'], '--learner with --set agent.agent=...'),
    ],
)  # fmt: skip
def test_what_light_model_cannot_do_is_one_line_before_anything_exists(argv, message, tmp_path):
    with pytest.raises(RunConfigError) as error:
        plan_of('--learner', 'light-model', *argv, runs_dir=tmp_path / 'runs')
    assert str(error.value).startswith(message) and '\n' not in str(error.value)
    assert not (tmp_path / 'runs').exists()


def test_an_unknown_learner_is_one_line(tmp_path):
    with pytest.raises(RunConfigError, match=r"^--learner: unknown learner 'ppo' \(expected"):
        plan_of('--learner', 'ppo', runs_dir=tmp_path / 'runs')
