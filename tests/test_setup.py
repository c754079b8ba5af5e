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
