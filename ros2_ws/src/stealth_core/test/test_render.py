"""Scenario pictures: PNGs are written, paths drawn, inputs checked; the CLI answers."""

import math
from types import SimpleNamespace

import matplotlib.image
import numpy as np
import pytest
from stealth_core import render
from stealth_core.occupancy_map import OccupancyMap
from stealth_core.planners import optimal_path
from stealth_core.render import read_path_csv, render_scenario
from stealth_core.scenario import load_scenario
from stealth_core.scenario_drawing import goal_marks, scenario_figure
from stealth_core.searchlight import PatrolMotion, Searchlight, SweepMotion

PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'


def fake_scenario():
    data = np.zeros((80, 120), dtype=np.int8)
    data[:2, :] = data[-2:, :] = data[:, :2] = data[:, -2:] = 100
    data[40:42, :70] = 100
    data[10:25, 90:110] = -1
    lights = [
        Searchlight('L1', 1.0, 1.0, math.radians(45), math.radians(60), 3.0),
        Searchlight(
            'L2', 5.0, 3.0, math.pi, 1.2, 2.5, soft_edge=0.3,
            motion=SweepMotion(math.pi - 0.5, math.pi + 0.5, 0.2),
        ),
        Searchlight('L3', 3.0, 3.0, 0.0, 2 * math.pi, 1.0, motion=PatrolMotion(((4, 3),), 0.5)),
    ]  # fmt: skip
    goal = SimpleNamespace
    return SimpleNamespace(
        name='fake',
        map=OccupancyMap(data, 0.05, (0.0, 0.0, 0.0)),
        lights=lights,
        start=(0.5, 0.5, 0.0),
        detection_threshold=0.5,
        goals={'easy': goal(x=2.0, y=1.0, radius=0.2), 'hard': goal(x=5.5, y=3.5, radius=0.2)},
    )


def read_png(path):
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    return matplotlib.image.imread(path)


def test_render_writes_a_png_with_content(tmp_path):
    out = render_scenario(fake_scenario(), tmp_path / 'sub' / 'fake.png', cache_dir=tmp_path)
    pixels = read_png(out)
    assert pixels.shape[0] > 300 and pixels.shape[1] > 500
    assert len(np.unique(pixels.reshape(-1, pixels.shape[-1]), axis=0)) > 50


def test_paths_times_and_goals_change_the_picture(tmp_path):
    scenario = fake_scenario()
    field = np.zeros(scenario.map.data.shape)
    plain = read_png(render_scenario(scenario, tmp_path / 'plain.png', field=field))
    path = [(0.5, 0.5), (0.5, 2.0), (5.5, 3.5)]
    with_path = read_png(
        render_scenario(scenario, tmp_path / 'path.png', paths=[path, path[:2]], field=field)
    )
    later = read_png(render_scenario(scenario, tmp_path / 'later.png', field=field, t=4.0))
    one_goal = read_png(render_scenario(scenario, tmp_path / 'goal.png', field=field, goal='hard'))
    for other in (with_path, later, one_goal):
        assert other.shape != plain.shape or not np.array_equal(other, plain)


def test_a_field_of_the_wrong_shape_is_refused(tmp_path):
    with pytest.raises(ValueError, match='field: expected shape'):
        render_scenario(fake_scenario(), tmp_path / 'x.png', field=np.zeros((3, 3)))


def test_goal_marks_from_a_mapping_or_a_sequence():
    named = SimpleNamespace(name='g', x=1, y=2, radius=0.5)
    assert goal_marks(SimpleNamespace(goals=[named])) == [('g', 1.0, 2.0, 0.5)]
    assert goal_marks(fake_scenario())[1] == ('hard', 5.5, 3.5, 0.2)


def test_read_path_csv(tmp_path):
    good = tmp_path / 'good.csv'
    good.write_text('x,y\n0.5,0.5\n1.0, 2.0\n\n# comment\n3,4\n')
    np.testing.assert_array_equal(read_path_csv(good), [[0.5, 0.5], [1.0, 2.0], [3.0, 4.0]])
    for name, text, message in [
        ('bad.csv', '0,0\n1,x\n', 'line 2'),
        ('nan.csv', '0,0\nnan,1\n', 'finite'),
        ('empty.csv', 'x,y\n', 'no "x,y" rows'),
        ('short.csv', '0,0\n1\n', 'line 2'),
    ]:
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(ValueError, match=message):
            read_path_csv(path)


def test_cli_help(capsys):
    with pytest.raises(SystemExit) as finished:
        render.main(['--help'])
    assert finished.value.code == 0
    usage = capsys.readouterr().out
    assert '--path' in usage and '--time' in usage and '--all' in usage


def test_cli_needs_a_scenario(capsys):
    with pytest.raises(SystemExit) as finished:
        render.main([])
    assert finished.value.code == 2
    assert 'scenario' in capsys.readouterr().err


def test_cli_renders_a_shipped_scenario_with_paths(tmp_path, capsys):
    route = tmp_path / 'route.csv'
    route.write_text('x,y\n2.5,2.5\n2.5,10.5\n4.0,10.5\n')
    out = tmp_path / 'map1.png'
    arguments = ['map1', '-o', str(out), '--path', str(route), '--path', str(route)]
    code = render.main(
        [*arguments, '--goal', 'hard', '--time', '1.5', '--cache-dir', str(tmp_path)]
    )
    assert code == 0 and capsys.readouterr().out.strip() == str(out)
    read_png(out)


def test_the_legend_gives_the_optimums_scores_and_each_paths_length_against_it(
    tmp_path, monkeypatch
):
    route = tmp_path / 'route.csv'
    route.write_text('x,y\n2.5,2.5\n2.5,10.5\n4.0,10.5\n')  # 8 m + 1.5 m
    drawn = {}

    def capture(scenario, out, **kwargs):
        drawn.update(kwargs)
        return out

    monkeypatch.setattr(render, 'render_scenario', capture)
    assert (
        render.main(['map1', '--path', str(route), '--optimum', '-o', str(tmp_path / 'a.png')])
        == 0
    )
    optimum = optimal_path(load_scenario('map1'), None)[1]
    assert drawn['path_labels'] == [
        f"route: 9.5 m ({9.5 / optimum.path_length:.2f}x the optimum's)",
        f'optimum (value iteration): success, {optimum.steps} steps, {optimum.path_length:.1f} m, '
        'exposure 0.00, peak 0.00',
    ]


def test_cli_renders_every_scenario(tmp_path, capsys):
    assert render.main(['--all', '--out-dir', str(tmp_path), '--cache-dir', str(tmp_path)]) == 0
    written = sorted(path.name for path in tmp_path.glob('*.png'))
    maps = ['floorplan', 'lgfloor', 'map1', 'simple-maze']
    expected = [f'{name}{kind}.png' for name in maps for kind in ('', '-moving')]
    expected += ['map1-exposure.png', 'simple-maze-exposure.png']
    assert written == sorted([*expected, 'lgfloor-bounce.png', 'map1-bounce.png'])


def test_an_exposure_optimum_is_drawn_with_the_robots_footprint_at_each_pose(tmp_path):
    scenario = load_scenario('simple-maze-exposure')
    poses, _ = optimal_path(scenario, None, poses=True)
    assert poses.shape[1] == 3 and set(np.round(poses[:, 2] / (np.pi / 2)) % 4) <= {0, 1, 2, 3}
    assert np.array_equal(poses[:, :2], optimal_path(scenario, None)[0])
    figure = scenario_figure(scenario, [poses], cache_dir=tmp_path)
    rectangles = [p for p in figure.axes[0].patches if type(p).__name__ == 'Rectangle']
    assert len(rectangles) == len(poses)
    # facing north up the column: the rectangle's long side is along y
    north = [
        r for r, yaw in zip(rectangles, poses[:, 2], strict=True) if np.isclose(yaw, np.pi / 2)
    ]
    assert north and all(r.get_angle() == pytest.approx(90.0) for r in north)
    out = tmp_path / 'exposure.png'
    assert (
        render.main(
            ['simple-maze-exposure', '--optimum', '-o', str(out), '--cache-dir', str(tmp_path)]
        )
        == 0
    )
    assert out.stat().st_size > 0


def test_cli_draws_direct_light_beside_direct_and_bounce(tmp_path, capsys):
    out = tmp_path / 'compare.png'
    arguments = ['map1-bounce', '--bounce-compare', '--optimum', '-o', str(out)]
    assert render.main([*arguments, '--cache-dir', str(tmp_path)]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    pair = read_png(out)
    render.main(['map1-bounce', '-o', str(tmp_path / 'one.png'), '--cache-dir', str(tmp_path)])
    one = read_png(tmp_path / 'one.png')
    assert pair.shape[1] >= 1.9 * one.shape[1]
    left, right = pair[:, : pair.shape[1] // 2], pair[:, pair.shape[1] // 2 :]
    assert not np.array_equal(left[: right.shape[0], : right.shape[1]], right[:, : left.shape[1]])
    assert render.main(['map1', '--bounce-compare', '--cache-dir', str(tmp_path)]) == 1
    assert 'no one-bounce light to compare' in capsys.readouterr().err


def test_cli_reports_bad_input(tmp_path, capsys):
    with pytest.raises(SystemExit) as finished:
        render.main(['map1', '--goal', 'impossible', '--cache-dir', str(tmp_path)])
    assert finished.value.code == 2 and 'no such goal' in capsys.readouterr().err
    assert render.main(['no-such-scenario', '--cache-dir', str(tmp_path)]) == 1
    assert 'not found' in capsys.readouterr().err
    missing = str(tmp_path / 'missing.csv')
    assert render.main(['map1', '--path', missing, '--cache-dir', str(tmp_path)]) == 1
    assert 'missing.csv' in capsys.readouterr().err
