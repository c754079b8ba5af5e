"""The project's one linter, run as a test: ruff (99 columns, single quotes), check and format."""

import subprocess

from ros_support import REPO_ROOT, VENV

RUFF = str(VENV / 'bin' / 'ruff')


def test_ruff_check_is_clean():
    result = subprocess.run(
        [RUFF, 'check', '--no-cache', '.'], cwd=REPO_ROOT, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_ruff_format_is_clean():
    result = subprocess.run(
        [RUFF, 'format', '--no-cache', '--check', '.'],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stdout + result.stderr
