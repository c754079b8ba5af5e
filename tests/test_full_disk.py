"""`stealth train` into a small tmpfs that fills up: the run stops with one line naming the file
and the space left (exit 4), keeps the last policy saved whole, says which files are complete
and leaves no temporary file. Mounting needs root: elsewhere the tests are skipped."""

import json
import os
from pathlib import Path
import re
import subprocess

import pytest
from test_system import system  # noqa: F401 - the fixture: no process or shm left behind

EXIT_DISK_FULL = 4  # stealth_node_kit.full_disk.EXIT_DISK_FULL


@pytest.fixture
def small_disk(tmp_path, request):
    """A tmpfs of request.param KiB at tmp_path/disk, unmounted afterwards."""
    if os.geteuid() != 0:
        pytest.skip('mounting a small tmpfs (a disk that fills up) needs root')
    mount = tmp_path / 'disk'
    mount.mkdir()
    command = ['mount', '-t', 'tmpfs', '-o', f'size={request.param}k', 'tmpfs', str(mount)]
    try:
        result = subprocess.run(command, capture_output=True, text=True, timeout=30)
    except OSError as error:
        pytest.skip(f'cannot mount a tmpfs here: {error}')
    if result.returncode != 0:
        pytest.skip(f'cannot mount a tmpfs here: {result.stderr.strip()}')
    yield mount
    subprocess.run(['umount', '-l', str(mount)], capture_output=True, timeout=30, check=False)


def disk_full_line(result, mount: Path) -> str:
    """The one line that says the disk is full (exactly one), checked for its form."""
    lines = [
        line
        for line in result.stderr.splitlines()
        if line.startswith('stealth train: ') and 'the disk is full' in line
    ]
    assert len(lines) == 1, result.stderr
    pattern = (
        r'stealth train: the disk is full: could not write (\S+) '
        rf'\(\d+(\.\d)? (bytes|KiB) free on {re.escape(str(mount))}\); stopping'
    )
    assert re.fullmatch(pattern, lines[0]), lines[0]
    return lines[0]


def leftovers(run: Path) -> list[str]:
    """Temporary files (.x.partial, .x.tmp, .x.recovering) anywhere in the run directory."""
    return sorted(str(p.relative_to(run)) for p in run.rglob('.*'))


@pytest.mark.parametrize('small_disk', [120], indirect=True)
def test_a_full_disk_stops_training_and_keeps_the_last_policy(system, small_disk):  # noqa: F811
    from stealth_agent.policy_store import load_policy

    result = system.run(
        'train', '--runs-dir', str(small_disk), '--name', 't', '--no-record', '--seed', '1',
        timeout=300,
    )  # fmt: skip
    assert result.returncode == EXIT_DISK_FULL, result.stderr + result.stdout
    assert 'Traceback' not in result.stderr + result.stdout
    run = small_disk / 't'
    line = disk_full_line(result, small_disk)
    assert 'policy.npz' in line  # the agent's save is the first write that does not fit
    summary = json.loads((run / 'summary.json').read_text())
    assert summary['status'] == 'failed' and line.endswith(summary['message'] + '; stopping')
    complete = summary['complete_files']
    assert any(name.endswith('episodes.csv') for name in complete), summary
    incomplete = summary['incomplete_files']
    policy = next(name for name in incomplete if name.endswith('policy.npz'))
    assert 'saved before' in incomplete[policy], incomplete
    # The policy is the last one saved whole, and loads.
    saved = load_policy(run / 'policy.npz')
    assert 0 < saved.learner.episodes <= summary['episodes']
    # episodes.csv holds every episode counted (no row lost, none torn).
    rows = (run / 'episodes.csv').read_text().splitlines()
    assert len(rows) == 1 + summary['episodes']
    assert not leftovers(run)
    assert 'restarting' not in result.stderr  # a full disk is not a crash to retry


@pytest.mark.parametrize('small_disk', [200], indirect=True)
def test_a_full_disk_stops_the_recorder_without_restarts(system, small_disk):  # noqa: F811
    result = system.run('train', '--runs-dir', str(small_disk), '--name', 't', '--seed', '1',
                        timeout=300)  # fmt: skip
    assert result.returncode == EXIT_DISK_FULL, result.stderr + result.stdout
    assert 'Traceback' not in result.stderr + result.stdout
    disk_full_line(result, small_disk)
    assert 'restarting' not in result.stderr
    run = small_disk / 't'
    summary_path = run / 'summary.json'
    if 'summary.json not written either; complete files:' in result.stderr:
        assert not summary_path.exists() or json.loads(summary_path.read_text())
    else:
        summary = json.loads(summary_path.read_text())
        assert summary['status'] == 'failed' and 'complete_files' in summary
    if (run / 'episodes.csv').exists() and (run / 'episodes.csv').stat().st_size:
        assert (run / 'episodes.csv').read_text().startswith('episode,')
    assert not leftovers(run)
