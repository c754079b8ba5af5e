"""The one line of a full disk, and the context that turns ENOSPC into it."""

import errno
import os
from pathlib import Path
import shutil

import pytest
from stealth_node_kit import full_disk
from stealth_node_kit.full_disk import (
    DiskFullError,
    checked_write,
    disk_full_message,
    free_space,
    is_disk_full,
    mount_point,
    size_text,
)


def test_sizes_read_as_people_read_them():
    assert size_text(0) == '0 bytes'
    assert size_text(1023) == '1023 bytes'
    assert size_text(12 * 1024) == '12 KiB'
    assert size_text(1536) == '1.5 KiB'
    assert size_text(3.4 * 1024**2) == '3.4 MiB'
    assert size_text(200 * 1024**3) == '200 GiB'


def test_the_line_names_the_file_the_space_left_and_the_mount_point(tmp_path, monkeypatch):
    usage = shutil.disk_usage(tmp_path)._replace(free=12 * 1024)
    monkeypatch.setattr(full_disk.shutil, 'disk_usage', lambda path: usage)
    where = mount_point(tmp_path)
    assert os.path.ismount(where) and Path(tmp_path).resolve().is_relative_to(where)
    assert free_space(tmp_path / 'not' / 'yet') == f'12 KiB free on {where}'
    line = disk_full_message(tmp_path / 'episodes.csv', 'runs/x/episodes.csv')
    assert line == (
        f'the disk is full: could not write runs/x/episodes.csv (12 KiB free on {where})'
    )


def test_a_full_disk_in_the_block_becomes_one_line_naming_the_file(tmp_path):
    target = tmp_path / 'policy.npz'
    with pytest.raises(DiskFullError) as raised, checked_write(target, 'runs/x/policy.npz'):
        raise OSError(errno.ENOSPC, 'No space left on device')
    error = raised.value
    assert error.path == target and error.errno == errno.ENOSPC and is_disk_full(error)
    assert str(error).startswith('the disk is full: could not write runs/x/policy.npz (')
    assert 'free on' in str(error) and '\n' not in str(error)
    with pytest.raises(DiskFullError), checked_write(target):  # a quota is as full
        raise OSError(errno.EDQUOT, 'Disk quota exceeded')


def test_other_errors_pass_unchanged(tmp_path):
    with pytest.raises(PermissionError), checked_write(tmp_path / 'x'):
        raise PermissionError(errno.EACCES, 'Permission denied')
    assert not is_disk_full(OSError(errno.EIO, 'I/O error')) and not is_disk_full(ValueError())
