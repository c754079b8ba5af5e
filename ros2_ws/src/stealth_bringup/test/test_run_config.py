"""Parameter files, --set and run directories of `stealth train` (no ROS, no processes)."""

from pathlib import Path

import pytest
from stealth_bringup.run_config import (
    MANAGED,
    NODES,
    RunConfigError,
    choose_run_directory,
    coerce_like,
    create_run_directory,
    effective_parameters,
    params_sources,
    parse_set,
    read_params_file,
    ros_arg_value,
    write_params_file,
)
from stealth_core.path_scores import OPTIMUM_GAMMA
import yaml

CONFIG = Path(__file__).resolve().parent.parent / 'config'


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding='utf-8')
    return path


@pytest.mark.parametrize('node', list(NODES))
def test_the_shipped_parameter_files_are_valid_and_leave_the_managed_ones_to_the_run(node):
    values = read_params_file(CONFIG / f'{node}.yaml', node)
    assert values, f'{node}.yaml sets nothing'
    managed = {key.split('.', 1)[1] for key in MANAGED if key.startswith(f'{node}.')}
    assert not managed & values.keys(), f'{node}.yaml sets what the run decides'


def test_the_agent_learns_as_the_harness_does_undiscounted_and_by_optimism():
    """Through ROS the goal is judged on the lattice node as in-process, so stealth train's
    agent takes the harness's settings: gamma OPTIMUM_GAMMA (the criterion's optimum is
    undiscounted) and epsilon 0 (prioritized sweeping explores by optimism)."""
    values = read_params_file(CONFIG / 'agent.yaml', 'agent')
    assert values['gamma'] == OPTIMUM_GAMMA
    assert values['agent'] == 'prioritized' and values['epsilon'] == 0.0


def test_a_params_file_is_read_for_its_node(tmp_path):
    path = write(tmp_path / 'a.yaml', 'agent:\n  ros__parameters:\n    epsilon: 0.2\n    n: 5\n')
    assert read_params_file(path, 'agent') == {'epsilon': 0.2, 'n': 5}
    wildcard = write(tmp_path / 'w.yaml', '/**:\n  ros__parameters:\n    seed: 3\n')
    assert read_params_file(wildcard, 'agent') == {'seed': 3}


@pytest.mark.parametrize(
    ('text', 'message'),
    [
        ('agent: [1, 2\n', 'not valid YAML (line 2)'),
        ('', 'expected a mapping'),
        ('- 1\n', 'expected a mapping'),
        ('simulator:\n  ros__parameters: {seed: 1}\n', "no section for node 'agent' (it has: "),
        ('agent:\n  parameters: {seed: 1}\n', 'expected a mapping "agent: {ros__parameters'),
        ('agent:\n  ros__parameters: [1]\n', 'expected a mapping'),
        ('agent:\n  ros__parameters: {seed: {a: 1}}\n', 'agent.seed: nested parameters'),
        ('agent:\n  ros__parameters: {seed: [1, a]}\n', 'is not a parameter value'),
        ('agent:\n  ros__parameters: {1x: 2}\n', 'is not a parameter name'),
    ],
)
def test_a_bad_params_file_is_one_line_naming_the_file(tmp_path, text, message):
    path = write(tmp_path / 'agent.yaml', text)
    with pytest.raises(RunConfigError) as error:
        read_params_file(path, 'agent')
    assert str(error.value).startswith(f'parameter file {path}: ')
    assert message in str(error.value)
    assert '\n' not in str(error.value)


def test_a_missing_params_file_says_so(tmp_path):
    with pytest.raises(RunConfigError, match=r'cannot read it \(No such file or directory\)'):
        read_params_file(tmp_path / 'nope.yaml', 'agent')


def test_params_dir_replaces_only_the_files_it_has(tmp_path):
    write(tmp_path / 'agent.yaml', 'agent:\n  ros__parameters: {n: 1}\n')
    sources = params_sources(CONFIG, tmp_path, ['agent', 'simulator'])
    assert sources == {'agent': tmp_path / 'agent.yaml', 'simulator': CONFIG / 'simulator.yaml'}
    with pytest.raises(RunConfigError, match='--params-dir .*: no such directory'):
        params_sources(CONFIG, tmp_path / 'missing', ['agent'])


def test_set_parses_values_as_ros_does_and_refuses_what_the_run_decides():
    parsed = parse_set(
        ['agent.epsilon=0.2', 'agent.agent=sarsa', 'simulator.particles=100', 'agent.x=[1, 2]'],
        list(NODES),
    )
    assert parsed == {
        'agent': {'epsilon': 0.2, 'agent': 'sarsa', 'x': [1, 2]},
        'simulator': {'particles': 100},
    }
    for item, message in (
        ('agent.epsilon', 'expected node.parameter=value'),
        ('epsilon=0.1', 'expected node.parameter=value'),
        ('robot.speed=1', "no node 'robot'"),
        ('agent.policy_file=x.npz', 'set by the run itself'),
        ('environment.scenario=map1', 'use --scenario'),
        ('agent.a-b=1', 'is not a parameter name'),
        ('agent.x={a: 1}', 'is not a parameter value'),
    ):
        with pytest.raises(RunConfigError, match=message):
            parse_set([item], list(NODES))


def test_overrides_win_and_ints_given_for_floats_become_floats(tmp_path):
    path = write(
        tmp_path / 'agent.yaml',
        'agent:\n  ros__parameters: {epsilon: 0.1, n: 10, pose: [0.0, 1.0]}\n',
    )
    parameters = effective_parameters(
        'agent', path, {'policy_file': '/p.npz'}, {'epsilon': 1, 'n': 20, 'pose': [1, 2]}
    )
    assert parameters.values == {
        'epsilon': 1.0,
        'n': 20,
        'pose': [1.0, 2.0],
        'policy_file': '/p.npz',
    }
    assert isinstance(parameters.values['epsilon'], float)
    assert parameters.ros_args(Path('/f.yaml')) == [
        '--ros-args',
        '--params-file',
        '/f.yaml',
        '-p',
        'epsilon:=1.0',
        '-p',
        'n:=20',
        '-p',
        'pose:=[1.0, 2.0]',
    ]
    assert coerce_like(True, 0.5) is True and coerce_like('a', 0.5) == 'a'


def test_ros_arg_values_keep_their_type():
    assert ros_arg_value(True) == 'true'
    assert ros_arg_value(0.1) == '0.1'
    assert ros_arg_value('1') == '"1"'
    assert ros_arg_value(['a', 'b']) == '["a", "b"]'


def test_the_written_file_is_a_params_file_with_the_effective_values(tmp_path):
    source = write(tmp_path / 'agent.yaml', 'agent:\n  ros__parameters: {epsilon: 0.1}\n')
    parameters = effective_parameters(
        'agent', source, {'policy_file': '/a b/p.npz', 'pose': [1.0, -2.5], 'flag': True}, {}
    )
    written = write_params_file(parameters, tmp_path / 'out' / 'agent.yaml', 'line 1\nline 2')
    text = written.read_text()
    assert text.startswith('# line 1\n# line 2\nagent:\n  ros__parameters:\n')
    assert yaml.safe_load(text) == {'agent': {'ros__parameters': parameters.values}}
    assert read_params_file(written, 'agent') == parameters.values


def test_run_directories_are_new_and_made_only_when_asked(tmp_path):
    first = create_run_directory(choose_run_directory(tmp_path, None, 'maze-easy-T'))
    second = choose_run_directory(tmp_path, None, 'maze-easy-T')
    assert (first.name, second.name) == ('maze-easy-T', 'maze-easy-T-2')
    assert not second.exists()  # chosen, not made: a refused run leaves nothing
    named = create_run_directory(choose_run_directory(tmp_path, 'mine', 'x'))
    assert named.is_dir()
    with pytest.raises(RunConfigError, match='exists already'):
        choose_run_directory(tmp_path, 'mine', 'x')
    with pytest.raises(RunConfigError, match='plain directory name'):
        choose_run_directory(tmp_path, 'a/b', 'x')
