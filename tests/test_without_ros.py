"""The world model without ROS (issue 39): a clean Python 3.11 venv that holds no ROS wheel,
made from the locked versions, with only `pip install ros2_ws/src/stealth_core` (and
`ros2_ws/src/stealth_learn` for the JAX env), as the README's "without ROS" section says.

In it `gymnasium.make('StealthNav-v0')` steps, the generator builds and proves a scenario, the
planners find the covert path, `stealth_learn.jax_env` steps under jit, and `stealth render`'s
module draws a picture. The environment node's package, installed there too, refuses in one
line that says what to install, not with a traceback deep in a missing rclpy.

The packages are installed from a copy of the repository's layout (the packages, scenarios/ and
maps/), so pip's in-tree build leaves nothing in the checkout. uv installs (as `make setup`
does, from its cache after the first time); the venv is removed afterwards.
"""

import os
from pathlib import Path
import shutil
import subprocess
import sys
import textwrap

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
UV = Path(sys.prefix) / 'bin' / 'uv'
PYTHON311 = shutil.which('python3.11')
INSTALL_TIMEOUT = 900.0  # s: from uv's cache a minute; a cold cache downloads jax (~400 MB)
RUN_TIMEOUT = 600.0
STAGES = ('gym', 'value', 'generated', 'jax')  # what USE_THE_MODEL prints as it gets there

pytestmark = pytest.mark.skipif(
    PYTHON311 is None or not UV.exists(), reason='needs python3.11 and the venv uv of make setup'
)

USE_THE_MODEL = textwrap.dedent(
    """
    import importlib.util
    import sys
    import tempfile

    import gymnasium as gym
    import numpy as np

    import stealth_core

    assert importlib.util.find_spec('rclpy') is None, 'a ROS wheel in the clean venv'
    gym.register_envs(stealth_core)

    # The Gym env, by id, on its default scenario; and on a named one.
    env = gym.make('StealthNav-v0')
    observation, info = env.reset(seed=0)
    assert env.observation_space.contains(observation)
    steps = 0
    for _ in range(20):
        observation, reward, terminated, truncated, info = env.step(env.action_space.sample())
        steps += 1
        assert np.isfinite(reward)
        if terminated or truncated:
            break
    print('gym steps', steps)

    # The planners: the covert optimum of simple-maze's easy goal is undetected, A*'s is not.
    from stealth_core.lattice_model import LatticeModel
    from stealth_core.planners import astar, value_iteration, walk
    from stealth_core.reward import EpisodeOutcome
    from stealth_core.scenario import load_scenario
    from stealth_core.task import StealthTask

    model = LatticeModel.build(StealthTask(load_scenario('simple-maze'), 'easy'))
    optimum = value_iteration(model)
    assert optimum.optimal_return > 0
    assert walk(model, astar(model)).outcome == EpisodeOutcome.DETECTED
    print('value iteration', round(float(optimum.optimal_return), 3))

    # The generator: a proven building, written and read back.
    from stealth_core.scenario_generator import Options, generate

    with tempfile.TemporaryDirectory() as directory:
        path = generate(11, Options(width=20, height=20, lights=3)).write(directory)
        generated = load_scenario(path)
        assert len(generated.lights) == 3
        print('generated', generated.name)

        # A picture, as `stealth render` draws it.
        from stealth_core import render

        picture = f'{directory}/simple-maze.png'
        assert render.main(['simple-maze', '--goal', 'easy', '--output', picture]) in (0, None)
        with open(picture, 'rb') as file:
            assert file.read(8) == b'\\x89PNG\\r\\n\\x1a\\n'

    # The JAX env, jit-compiled, stepping.
    import jax

    from stealth_learn.jax_env import build

    jax_env, params = build(['simple-maze'], track='full', layout='vector')
    one = jax_env.scenario(params, 0)
    key = jax.random.PRNGKey(0)
    obs, state = jax.jit(jax_env.reset)(key, one)
    step = jax.jit(jax_env.step)
    for action in (0, 0, 3):
        obs, state, reward, done, info = step(key, state, action, one)
    assert np.isfinite(float(reward))
    print('jax steps', int(info['steps']))
    """
)


def _run(command, **kwargs):
    return subprocess.run(command, capture_output=True, text=True, check=False, **kwargs)


@pytest.fixture(scope='module')
def clean_venv(tmp_path_factory):
    """(python of a venv with stealth_core, stealth_learn and stealth_env and no ROS, env)."""
    root = tmp_path_factory.mktemp('without_ros')
    repo = root / 'repo'
    for package in ('stealth_core', 'stealth_learn', 'stealth_env'):
        shutil.copytree(
            REPO_ROOT / 'ros2_ws' / 'src' / package,
            repo / 'ros2_ws' / 'src' / package,
            ignore=shutil.ignore_patterns('__pycache__', 'build', '*.egg-info', 'test'),
        )
    for folder in ('scenarios', 'maps'):
        shutil.copytree(REPO_ROOT / folder, repo / folder)
    venv = root / 'venv'
    made = _run([PYTHON311, '-m', 'venv', str(venv)], timeout=120)
    assert made.returncode == 0, made.stderr
    python = venv / 'bin' / 'python'
    # No ROS in reach: not the workspace's, not the ROS venv's site-packages.
    env = {
        key: value
        for key, value in os.environ.items()
        if not key.startswith(('AMENT_', 'COLCON_', 'ROS_', 'RMW_', 'PYTHON', 'VIRTUAL_ENV'))
        and key not in ('LD_LIBRARY_PATH', 'CMAKE_PREFIX_PATH')
    }
    env['VIRTUAL_ENV'] = str(venv)
    # stealth_core first (stealth_learn requires it, and it is on no index), as the README says.
    for packages in (['stealth_core'], ['stealth_learn', 'stealth_env']):
        installed = _run(
            [str(UV), 'pip', 'install', '--quiet', '--python', str(python)]
            + ['-c', str(REPO_ROOT / 'requirements.lock')]
            + [str(repo / 'ros2_ws' / 'src' / package) for package in packages],
            env=env,
            timeout=INSTALL_TIMEOUT,
        )
        assert installed.returncode == 0, installed.stderr
    yield python, env
    shutil.rmtree(root, ignore_errors=True)


def test_the_clean_venv_holds_no_ros_wheel(clean_venv):
    python, env = clean_venv
    listed = _run([str(python), '-m', 'pip', 'list', '--format=freeze'], env=env, timeout=120)
    assert listed.returncode == 0, listed.stderr
    names = [line.split('==')[0].lower() for line in listed.stdout.splitlines()]
    assert 'stealth-core' in names or 'stealth_core' in names
    assert not [name for name in names if name.startswith(('ros-', 'rclpy', 'rosidl'))]


def test_gym_generator_planners_render_and_jax_env_work_without_ros(clean_venv, tmp_path):
    python, env = clean_venv
    script = tmp_path / 'use_the_model.py'
    script.write_text(USE_THE_MODEL)
    used = _run([str(python), str(script)], env=env, cwd=tmp_path, timeout=RUN_TIMEOUT)
    assert used.returncode == 0, used.stdout + used.stderr
    reached = [line.split()[0] for line in used.stdout.splitlines()]  # render prints its file
    assert [word for word in reached if word in STAGES] == list(STAGES)


def test_the_environment_node_without_ros_says_what_to_install(clean_venv, tmp_path):
    python, env = clean_venv
    imported = _run(
        [str(python), '-c', 'import stealth_env.env_node'], env=env, cwd=tmp_path, timeout=120
    )
    assert imported.returncode != 0
    last = imported.stderr.strip().splitlines()[-1]
    assert last.startswith('ImportError: stealth_env is the ROS 2 environment node')
    assert 'pip install ros2_ws/src/stealth_core' in last
    assert 'rclpy/' not in imported.stderr  # never a traceback from inside rclpy
