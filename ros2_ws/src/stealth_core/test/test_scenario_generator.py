"""The scenario generator: deterministic per seed, every scenario loads and is proven, the
buildings have rooms and doors the robot passes, bad options are named with their range."""

import os
import subprocess

import numpy as np
import pytest
from stealth_core.floor_plan import generate_floor_plan
from stealth_core.guard_lights import PHASE_BINS
from stealth_core.move_lattice import MoveLattice
from stealth_core.scenario import load_scenario
from stealth_core.scenario_commands import main
from stealth_core.scenario_generator import (
    SEED_RANGES,
    GenerationError,
    Options,
    generate,
    prove,
    seed_range_of,
)


def _files(directory):
    return {p.relative_to(directory).as_posix(): p.read_bytes() for p in directory.rglob('*.*')}


def test_same_seed_same_files_byte_for_byte(tmp_path):
    generate(7).write(tmp_path / 'a')
    generate(7).write(tmp_path / 'b')
    generate(8).write(tmp_path / 'c')
    assert _files(tmp_path / 'a') == _files(tmp_path / 'b')
    assert _files(tmp_path / 'a') != _files(tmp_path / 'c')


@pytest.mark.parametrize(
    'options',
    [
        Options(),
        Options(width=20, height=20, lights=2, difficulty='easy'),
        Options(width=24, height=36, lights=6, moving='sweeping', difficulty='medium'),
        Options(width=30, height=20, lights=4, moving='patrolling', difficulty='hard'),
        Options(width=30, height=24, lights=5, moving='mixed', difficulty='medium'),
    ],
)
def test_generated_scenarios_load_and_are_proven(tmp_path, options):
    generated = generate(3, options)
    scenario = load_scenario(generated.write(tmp_path))
    assert scenario.default_goal == options.difficulty
    assert len(scenario.lights) == options.lights
    proof, why = prove(scenario, options.difficulty)
    assert proof is not None, why
    assert proof.shortest_steps <= proof.covert_steps <= scenario.step_limit
    if options.moving != 'none':
        assert scenario.has_moving_lights and scenario.timing.cycle_bins == PHASE_BINS
    else:
        assert not scenario.has_moving_lights


def test_buildings_have_connected_rooms_and_doors_the_robot_passes():
    for seed in range(6):
        plan = generate_floor_plan(np.random.default_rng(seed), 30, 24)
        kinds = [room.kind for room in plan.rooms]
        assert kinds[:2] == ['hall', 'corridor'] and kinds.count('room') >= 6
        assert all(door.width >= 2 * 0.2 for door in plan.doors)
        assert min(plan.door_distances(plan.hall)) >= 0  # every room reached through doors
        start = plan.rooms[plan.hall].centre
        lattice = MoveLattice(plan.occupancy_map(), start, 0.5, 0.2)
        for room in plan.rooms:  # the robot drives from the hall into every room
            target = lattice.point_to_node(*room.centre)
            assert lattice.bfs((0, 0), goal=lambda node, t=target: node == t) is not None


def test_seed_ranges_are_disjoint():
    assert seed_range_of(0) == 'train' and seed_range_of(99_999) == 'train'
    assert seed_range_of(100_000) == 'validation'
    assert seed_range_of(500_000) is None
    assert seed_range_of(SEED_RANGES['test'][0]) == 'test'


@pytest.mark.parametrize(
    ('argv', 'message'),
    [
        (['--width', '61'], '--width: expected a whole number in [20, 60], got 61'),
        (['--height', '19'], '--height: expected a whole number in [20, 40], got 19'),
        (['--lights', '9'], '--lights: expected a whole number in [2, 8], got 9'),
        (['--moving', 'dancing'], '--moving: expected one of none, sweeping, patrolling, mixed'),
        (['--difficulty', 'brutal'], '--difficulty: expected one of easy, medium, hard'),
        (['--count', '0'], '--count: expected a whole number in [1, 100000], got 0'),
        (['--seed', '99999', '--count', '2'], 'cross a seed range boundary'),
    ],
)
def test_options_out_of_range_are_one_line_naming_the_range(tmp_path, capsys, argv, message):
    argv = [
        'generate',
        '--out',
        str(tmp_path / 'out'),
        *(['--seed', '1'] if '--seed' not in argv else []),
        *argv,
    ]
    assert main(argv) == 1
    error = capsys.readouterr().err
    assert message in error and error.count('\n') == 1
    assert not (tmp_path / 'out').exists()


def test_an_output_directory_with_other_files_is_refused(tmp_path, capsys):
    (tmp_path / 'notes.txt').write_text('mine')
    assert main(['generate', '--seed', '1', '--out', str(tmp_path)]) == 1
    assert 'exists and is not an empty directory' in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ['notes.txt']


def test_a_seed_without_a_proven_scenario_says_so_and_stops(monkeypatch):
    import stealth_core.scenario_generator as generator

    monkeypatch.setattr(generator, 'MAX_TRIES', 2)
    monkeypatch.setitem(generator.DIFFICULTY_RULES, 'hard', (0.0, 1.0, 100.0))  # unreachable
    with pytest.raises(
        GenerationError, match=r'seed 5: no proven scenario in 2 tries \(.*x\) with'
    ):
        generate(5, Options(difficulty='hard'))


def test_generate_writes_the_batch_and_a_contact_sheet(tmp_path, capsys):
    out, sheet = tmp_path / 'gen', tmp_path / 'sheet.png'
    argv = ['generate', '--seed', '100000', '--count', '2', '--out', str(out)]
    assert main([*argv, '--width', '20', '--height', '20', '--contact-sheet', str(sheet)]) == 0
    assert sorted(p.name for p in out.glob('*.yaml')) == ['gen-0100000.yaml', 'gen-0100001.yaml']
    assert 'validation seed range' in capsys.readouterr().out
    assert sheet.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_the_gym_env_steps_through_a_generated_scenario(tmp_path):
    from stealth_core.gym_env import StealthNavEnv

    path = generate(2, Options(width=20, height=20, lights=3, moving='mixed')).write(tmp_path)
    env = StealthNavEnv(path)
    state, _ = env.reset(seed=0)
    assert len(state) == 3  # x, y and the phase of the moving lights
    _, _, terminated, truncated, _ = env.step(3)
    assert not truncated


@pytest.mark.parametrize('name', ['map1', 'lgfloor', 'simple-maze'])
def test_the_successor_table_is_successor_for_every_node(name):
    lattice = MoveLattice.from_scenario(load_scenario(name))
    nodes = list(lattice.valid_nodes())
    index = {node: i for i, node in enumerate(nodes)}
    expected = [
        [i if (t := lattice.successor(node, a)) is None else index[t] for a in range(4)]
        for i, node in enumerate(nodes)
    ]
    assert lattice.successor_table().tolist() == expected


@pytest.mark.parametrize('name', ['map1', 'lgfloor', 'floorplan'])
def test_reachable_is_what_bfs_reaches(name):
    lattice = MoveLattice.from_scenario(load_scenario(name))
    reach = lattice.reachable((0, 0))
    found = set()
    lattice.bfs((0, 0), goal=lambda node: found.add(node) and False)  # visits every node
    expected = np.zeros(lattice.shape, dtype=bool)
    for i, j in found:
        expected[i - lattice.i_min, j - lattice.j_min] = True
    assert (reach == expected).all() and reach.sum() > 100
    assert not lattice.reachable((10**6, 0)).any()


def test_sheet_draws_a_directory_and_names_why_there_is_nothing_to_draw(tmp_path, capsys):
    generate(4, Options(width=20, height=20, lights=2)).write(tmp_path / 'gen')
    assert main(['sheet', str(tmp_path / 'gen'), '--out', str(tmp_path / 'sheet.png')]) == 0
    assert (tmp_path / 'sheet.png').stat().st_size > 1000
    capsys.readouterr()
    (tmp_path / 'empty').mkdir()
    (tmp_path / 'file').write_text('')
    for directory, problem in [
        ('empty', 'no scenario YAMLs (*.yaml) in it'),
        ('missing', 'no such directory'),
        ('file', 'is not a directory (give a directory of scenarios)'),
    ]:
        assert main(['sheet', str(tmp_path / directory), '--out', str(tmp_path / 'x.png')]) == 1
        assert capsys.readouterr().err == f'stealth scenarios: {tmp_path / directory}: {problem}\n'
    assert not (tmp_path / 'x.png').exists()


@pytest.fixture
def read_only_dir(tmp_path):
    """A directory no file can be made in: mode 555 for a user; for root, who writes there all
    the same, a read-only tmpfs (skipped where it cannot be mounted)."""
    directory = tmp_path / 'read-only'
    directory.mkdir()
    if os.geteuid() != 0:
        directory.chmod(0o555)
        yield directory
        directory.chmod(0o755)
        return
    command = ['mount', '-t', 'tmpfs', '-o', 'ro,size=16k', 'tmpfs', str(directory)]
    try:
        mounted = subprocess.run(command, capture_output=True, text=True, timeout=30)
    except OSError as error:
        pytest.skip(f'cannot mount a read-only tmpfs here: {error}')
    if mounted.returncode != 0:
        pytest.skip(f'cannot mount a read-only tmpfs here: {mounted.stderr.strip()}')
    try:
        yield directory
    finally:
        subprocess.run(['umount', '-l', str(directory)], capture_output=True, timeout=30)


def generate_into(out, sheet):
    return main(['generate', '--seed', '0', '--out', str(out), '--contact-sheet', str(sheet)])


def test_an_unwritable_contact_sheet_is_named_before_anything_is_generated(
    tmp_path, read_only_dir, capsys
):
    """It wrote the scenarios, then blamed the extension."""
    out, sheet = tmp_path / 'gen', read_only_dir / 'x.png'
    assert generate_into(out, sheet) == 1
    captured = capsys.readouterr()
    assert captured.err.startswith(
        f'stealth scenarios: --contact-sheet {sheet}: directory {read_only_dir} is not writable ('
    )
    assert captured.out == '' and not out.exists()
    assert main(['generate', '--seed', '0', '--out', str(read_only_dir / 'gen')]) == 1
    assert f'directory {read_only_dir} is not writable' in capsys.readouterr().err


def test_a_contact_sheet_path_that_is_no_png_file_is_named_before_generating(tmp_path, capsys):
    (tmp_path / 'file').write_text('')
    (tmp_path / 'dir.png').mkdir()
    for sheet, problem in [
        (tmp_path / 'sheet.jpg', 'expected a .png file name'),
        (tmp_path / 'sheet', 'expected a .png file name'),
        (tmp_path / 'dir.png', 'is a directory (give a .png file name)'),
        (tmp_path / 'file' / 'x.png', f'{tmp_path / "file"} is not a directory'),
    ]:
        assert generate_into(tmp_path / 'gen', sheet) == 1
        captured = capsys.readouterr()
        assert captured.err == f'stealth scenarios: --contact-sheet {sheet}: {problem}\n'
        assert captured.out == '' and not (tmp_path / 'gen').exists()
    # A missing directory of the sheet is made, as --out's is.
    assert generate_into(tmp_path / 'gen', tmp_path / 'new' / 'sheet.png') == 0
    assert (tmp_path / 'new' / 'sheet.png').is_file()


def test_rewards_are_well_posed_in_the_largest_building_with_most_lights(tmp_path):
    from stealth_core.scenario_generator import _penalty

    assert _penalty(Options()) == 1000.0  # map1's where it suffices
    big = Options(width=60, height=40, lights=8, difficulty='easy')
    assert _penalty(big) > 1000.0
    load_scenario(generate(1_000_000, big).write(tmp_path))  # load_scenario checks it


def test_a_patrol_on_a_short_rail_keeps_the_cycle_exact(tmp_path):
    # seed 1,000,001's hall is too narrow for a 6 m rail: its patrol takes the 3 m one
    generated = generate(1_000_001, Options(lights=4, moving='patrolling', difficulty='easy'))
    scenario = load_scenario(generated.write(tmp_path))
    speeds = {light.motion.speed for light in scenario.lights if light.motion is not None}
    assert speeds and speeds <= {0.5, 0.25}
    assert scenario.timing.cycle == 24.0
