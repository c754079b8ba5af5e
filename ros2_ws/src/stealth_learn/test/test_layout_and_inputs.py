"""Bad input and the layouts: a policy's layout checked by name, dims too small refused in one
line, the missing learning extra said in one line, probabilistic detection drawn from the key."""

import dataclasses
import os
from pathlib import Path
import subprocess
import sys

import jax
import numpy as np
import pytest
from stealth_core.scenario import load_scenario
from stealth_learn.env_tables import Dims, TableError, TaskArrays
from stealth_learn.jax_env import build
from stealth_learn.obs_layout import CHANNELS, VECTOR, LayoutError, check_layout, layout_id


def test_layout_ids_name_layout_track_and_size():
    env, params = build(['map1'], track='full', layout='grid')
    assert env.layout_id == 'stealth-grid-v1/full/40x40'
    obs, _ = env.reset(jax.random.key(0), env.scenario(params, 0))
    assert obs.grid.shape == (40, 40, len(CHANNELS)) and obs.vector.shape == (len(VECTOR),)
    assert layout_id('vector', 'full', 40, 40) == 'stealth-vector-v1/full'
    with pytest.raises(LayoutError, match="track 'sensed' needs layout 'grid'"):
        layout_id('vector', 'sensed', 40, 40)
    with pytest.raises(LayoutError, match="expected one of vector, grid, got 'image'"):
        layout_id('image', 'full', 40, 40)


def test_a_policy_for_another_layout_is_refused_naming_both():
    check_layout('stealth-grid-v1/sensed/40x40', 'stealth-grid-v1/sensed/40x40', 'p.msgpack')
    with pytest.raises(LayoutError) as caught:
        check_layout('stealth-grid-v1/full/40x40', 'stealth-grid-v1/sensed/40x40', 'p.msgpack')
    message = str(caught.value)
    assert '\n' not in message and message.startswith('p.msgpack: ')
    assert (
        "'stealth-grid-v1/full/40x40'" in message and "'stealth-grid-v1/sensed/40x40'" in message
    )


def test_dims_too_small_are_refused_in_one_line():
    arrays = TaskArrays('map1')
    with pytest.raises(TableError, match=r"scenario 'map1' needs Dims\(rows=40.*Dims.union"):
        arrays.tables(Dims(30, 40, 1, 4, 16))
    with pytest.raises(TableError, match=r'slip: expected a probability in \[0, 1\], got 2'):
        arrays.tables(slip=2)
    with pytest.raises(TableError, match="track: expected one of full, sensed, got 'x'"):
        TaskArrays('map1', track='x')


def test_full_track_grid_shows_the_lights_as_they_stand():
    """Layout 'grid' on track 'full': the light channel is the lattice model's light at the
    robot's bin, the free and goal channels its nodes."""
    env, params = build(['map1-moving'], track='full', layout='grid')
    one = env.scenario(params, 0)
    arrays = TaskArrays('map1-moving')
    model, sensing = arrays.model, arrays.sensing
    obs, state = env.reset(jax.random.key(0), one)
    for k in range(1, 4):  # waits: the lights move, the robot does not
        expected = sensing.grid(model.visibility[(k - 1) * sensing.n : k * sensing.n])
        np.testing.assert_array_equal(np.asarray(obs.grid)[:, :, 3], expected)
        assert np.asarray(obs.grid)[:, :, 0].sum() == sensing.n
        assert np.asarray(obs.grid)[:, :, 1].sum() == 1.0
        obs, state, *_ = env.step(jax.random.key(k), state, 4, one)


def test_probabilistic_detection_draws_from_the_key():
    """A step's detection probability ``1 - 2**(-v / threshold)``: the share detected over many
    keys matches it (a seeded draw: the same keys, the same count every run)."""
    from stealth_core.scenario import find_scenario

    scenario = load_scenario(find_scenario('map1'))
    scenario = dataclasses.replace(scenario, detection_mode='probabilistic')
    env, params = build([scenario], layout='vector')
    assert env.stochastic
    one = env.scenario(params, 0)
    detect_p = np.asarray(one.detect_p)
    place, action = np.unravel_index(np.argmin(np.abs(detect_p - 0.5)), detect_p.shape)
    p = float(detect_p[place, action])
    assert 0.2 < p < 0.8
    _, state = env.reset(jax.random.key(0), one)
    state = state.replace(place=jax.numpy.int32(place))
    keys = jax.random.split(jax.random.key(4), 4000)
    outcome = jax.vmap(lambda k: env.step_env(k, state, int(action), one)[4]['outcome'])(keys)
    share = float(np.mean(np.asarray(outcome) == 1))
    assert abs(share - p) < 5 * np.sqrt(p * (1 - p) / len(keys))


def test_without_jax_one_line_says_how_to_install():
    """Importing the JAX environment without jax: MissingExtraError, one line, `make learn`."""
    code = (
        'import sys; sys.modules["jax"] = None\n'
        'try:\n'
        '    import stealth_learn.jax_env\n'
        'except ImportError as error:\n'
        '    print(type(error).__name__ + ": " + str(error))\n'
    )
    path = os.pathsep.join([str(Path(__file__).resolve().parents[1]), *sys.path])
    done = subprocess.run(
        [sys.executable, '-c', code], capture_output=True, text=True, check=True,
        env={**os.environ, 'PYTHONPATH': path},
    )  # fmt: skip
    lines = done.stdout.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith('MissingExtraError: stealth_learn needs the learning extra')
    assert 'make learn' in lines[0] and 'jax is missing' in lines[0]
