"""render --animate: an animated GIF of the lights moving and paths walked step by step."""

import numpy as np
from PIL import Image
import pytest
from stealth_core.render import animate_scenario, main
from stealth_core.scenario import load_scenario
from stealth_core.scenario_drawing import figure_pixels, scenario_figure


@pytest.fixture(scope='module')
def scenario():
    return load_scenario('simple-maze-moving')


def frames_of(path) -> list[np.ndarray]:
    with Image.open(path) as image:
        frames = []
        for k in range(image.n_frames):
            image.seek(k)
            frames.append(np.asarray(image.convert('RGB')))
    return frames


def test_the_animation_shows_the_lights_moving_and_the_path_walked(scenario, tmp_path):
    path = np.array([scenario.start[:2], (2.0, 1.5), (2.5, 1.5)])
    out = animate_scenario(
        scenario, tmp_path / 'a.gif', [path], ['walk'], frames=4, cache_dir=tmp_path
    )
    frames = frames_of(out)
    assert len(frames) == 4
    assert all(frame.shape == frames[0].shape for frame in frames)
    assert not np.array_equal(frames[0], frames[1])  # the sweep moved, the robot too
    assert not np.array_equal(frames[2], frames[3])  # the path is over: the light still moves


def drawn_whole(scenario, paths, labels, k, cache_dir) -> np.ndarray:
    """Frame k as the GIF holds it, from the figure drawn whole: no background kept, no phase
    shared (a frame at t = k steps, each path walked to its point k)."""
    timing = scenario.timing
    t = ((k * timing.bins_per_step) % timing.cycle_bins) * timing.bin_seconds
    walked = [p[: min(k, len(p) - 1) + 1] for p in paths]
    title = f'{scenario.name}: step {k}, t = {k * timing.step_seconds:g} s'
    fig = scenario_figure(
        scenario, walked, t=t, goal='hard', path_labels=labels, title=title,
        cache_dir=cache_dir, dpi=60,
    )  # fmt: skip
    image = Image.fromarray(figure_pixels(fig)).convert('P', palette=Image.ADAPTIVE)
    return np.asarray(image.convert('RGB'))


def test_each_frame_is_the_figure_drawn_whole(scenario, tmp_path):
    # Past one cycle of the lights (each phase's figure serves two frames), the learned path
    # under the goal-guard's name (drawn over it) and on to the goal beside the colour bar.
    learned = np.array([scenario.start[:2], (1.5, 2.0), (12.5, 13.5), (13.5, 13.5), (14.0, 13.0)])
    optimum = np.array([scenario.start[:2], (2.0, 1.5), (2.5, 1.5), (3.0, 1.5)])
    paths, labels = [learned, optimum], ['learned', 'optimum']
    cycle = scenario.timing.cycle_bins // scenario.timing.bins_per_step
    frames = cycle + 3
    done = []
    out = animate_scenario(
        scenario, tmp_path / 'a.gif', paths, labels, goal='hard', frames=frames,
        cache_dir=tmp_path, progress=lambda *a: done.append(a),
    )  # fmt: skip
    shown = frames_of(out)
    assert len(shown) == frames
    for k in range(frames):
        assert np.array_equal(shown[k], drawn_whole(scenario, paths, labels, k, tmp_path)), k
    assert done == [(n, frames) for n in range(1, frames + 1)]  # in order, whatever the phase


def test_the_default_is_one_cycle_or_the_longest_path(scenario, tmp_path):
    cycle = scenario.timing.cycle_bins // scenario.timing.bins_per_step
    assert len(frames_of(animate_scenario(scenario, tmp_path / 'c.gif', cache_dir=tmp_path))) == (
        cycle
    )


def test_only_gif(scenario, tmp_path):
    with pytest.raises(ValueError, match=r'expected a \.gif'):
        animate_scenario(scenario, tmp_path / 'a.mp4')


def test_the_command_animates_the_optimum(tmp_path, capsys):
    out = tmp_path / 'optimum.gif'
    argv = ['simple-maze-moving', '--animate', str(out), '--optimum', '--frames', '3']
    assert main([*argv, '--cache-dir', str(tmp_path)]) == 0
    assert len(frames_of(out)) == 3
    captured = capsys.readouterr()
    assert str(out) in captured.out and 'frame 3/3' in captured.err
    assert main(['simple-maze-moving', '--animate', str(tmp_path / 'x.png')]) == 1
    assert 'expected a .gif' in capsys.readouterr().err


@pytest.mark.parametrize('fps', ['0', '-1', 'nan', '101'])
def test_a_frame_rate_that_is_no_rate_is_one_line_before_any_frame(fps, tmp_path, capsys):
    out = tmp_path / 'x.gif'
    assert main(['simple-maze-moving', '--animate', str(out), '--fps', fps]) == 1
    err = capsys.readouterr().err
    assert err.splitlines() == [
        f'render: --fps: expected frames per second, a number > 0 and at most 100 (a GIF frame '
        f'lasts at least 10 ms), got {float(fps):g}'
    ]  # and no 'frame 1/...' progress: nothing was drawn
    assert not out.exists()


def test_the_library_checks_the_rate_before_drawing(scenario, tmp_path):
    drawn = []
    with pytest.raises(ValueError, match='^fps: expected frames per second'):
        animate_scenario(scenario, tmp_path / 'a.gif', fps=0, progress=lambda *a: drawn.append(a))
    assert drawn == []
