"""`make setup`'s guards: missing tools stop it with one line; a broken .msg fails at rosidl."""

import os
import pathlib
import shutil
import subprocess
import sys

import pytest
from ros_support import REPO_ROOT

CHECK = str(REPO_ROOT / 'scripts' / 'check_prereqs.sh')
NEEDED_TOOLS = ('bash', 'cat', 'dirname', 'gcc', 'g++', 'cmake')


def path_without(tmp_path: pathlib.Path, missing: str) -> str:
    """A PATH holding links to the needed tools, except `missing`."""
    bin_dir = tmp_path / 'bin'
    bin_dir.mkdir()
    for tool in NEEDED_TOOLS:
        if tool != missing and shutil.which(tool):
            (bin_dir / tool).symlink_to(shutil.which(tool))
    return str(bin_dir)


@pytest.mark.parametrize('missing', ['gcc', 'g++', 'cmake'])
def test_missing_tool_stops_setup_with_one_line(tmp_path, missing):
    result = subprocess.run(
        ['/bin/bash', CHECK, sys.executable],
        env={'PATH': path_without(tmp_path, missing)},
        capture_output=True,
        text=True,
    )
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith(f'setup: missing {missing} ')
    assert 'apt-get install' in lines[0]


def test_wrong_python_version_is_named(tmp_path):
    fake = tmp_path / 'python3.11'
    fake.write_text('#!/bin/sh\necho 3.9\n')
    fake.chmod(0o755)
    result = subprocess.run(
        ['/bin/bash', CHECK, str(fake)], capture_output=True, text=True, env=os.environ
    )
    assert result.returncode == 1
    assert result.stderr.count('\n') == 1
    assert 'Python 3.11' in result.stderr and 'Python 3.9' in result.stderr


def test_no_python_is_named(tmp_path):
    result = subprocess.run(
        ['/bin/bash', CHECK, 'python3.11-does-not-exist'],
        capture_output=True,
        text=True,
        env=os.environ,
    )
    assert result.returncode == 1
    assert "setup: missing Python 3.11 (no 'python3.11-does-not-exist' on PATH" in result.stderr


def test_this_machine_passes_the_check():
    result = subprocess.run(['/bin/bash', CHECK, sys.executable], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_broken_msg_fails_the_build_with_rosidls_message(tmp_path):
    """A typo in a .msg stops colcon at rosidl's parser, at configure time, not at an import."""
    source = tmp_path / 'src' / 'stealth_interfaces'
    shutil.copytree(REPO_ROOT / 'ros2_ws' / 'src' / 'stealth_interfaces', source)
    (source / 'msg' / 'RLAction.msg').write_text('int32 action\nfloat3 broken_field\n')
    result = subprocess.run(
        [
            'bash',
            '-c',
            f'source {REPO_ROOT}/scripts/ros_env.sh && colcon build --build-base build '
            '--install-base install --cmake-args -DBUILD_TESTING=OFF',
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode != 0
    log = tmp_path / 'log' / 'latest_build' / 'stealth_interfaces' / 'stdout_stderr.log'
    text = log.read_text()
    assert 'rosidl_adapter.parser.InvalidResourceName' in text
    assert "'float3' is an invalid message" in text
    assert 'Configuring incomplete' in text
    assert not (tmp_path / 'install' / 'stealth_interfaces' / 'lib').exists()


def load_fix_ros_wheels():
    """scripts/fix_ros_wheels.py as a module (it is a script, not a package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        'fix_ros_wheels', REPO_ROOT / 'scripts' / 'fix_ros_wheels.py'
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_wheel_fix_repoints_any_foreign_prefix():
    fix = load_fix_ros_wheels()
    exported = (
        'INTERFACE_INCLUDE_DIRECTORIES "/opt/python/cp311-cp311/include/python3.11;'
        '/tmp/other/.venv/lib/python3.11/site-packages/numpy/_core/include;'
        '${_IMPORT_PREFIX}/include/builtin_interfaces"'
    )
    text = fix.repoint(exported, '/here/numpy/_core/include', '/here/include/python3.11')
    assert text == (
        'INTERFACE_INCLUDE_DIRECTORIES "/here/include/python3.11;/here/numpy/_core/include;'
        '${_IMPORT_PREFIX}/include/builtin_interfaces"'
    )
    assert fix.repoint(text, '/here/numpy/_core/include', '/here/include/python3.11') == text


def test_wheel_fix_leaves_the_installers_hard_linked_cache_alone(tmp_path):
    fix = load_fix_ros_wheels()
    cached = tmp_path / 'cache.cmake'
    cached.write_text('from the wheel\n')
    installed = tmp_path / 'installed.cmake'
    os.link(cached, installed)
    fix.replace_file_text(installed, 'for this venv\n')
    assert installed.read_text() == 'for this venv\n'
    assert cached.read_text() == 'from the wheel\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['cache.cmake', 'installed.cmake']
