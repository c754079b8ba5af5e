"""The recorder on a full disk: one line, the exit code that stops its restarts, and the file
left as it was for `stealth bag recover`."""

import errno
import io

from stealth_node_kit.full_disk import EXIT_DISK_FULL
from stealth_tools import recorder
from stealth_tools.bag_format import BagWriter


def test_a_full_disk_is_one_line_and_the_exit_code_that_is_not_restarted(tmp_path, capsys):
    path = tmp_path / 'recording.mcap'
    full = OSError(errno.ENOSPC, 'No space left on device')
    assert recorder._write_failed(path, 'writing', full) == EXIT_DISK_FULL
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and err.startswith(
        f'recorder: the disk is full: could not write {path} ('
    )
    assert err.rstrip().endswith('; stopping')
    assert recorder._write_failed(path, 'closing', OSError(errno.EIO, 'I/O error')) == 1
    assert capsys.readouterr().err == f'recorder: closing {path} failed: [Errno 5] I/O error\n'


def test_a_log_on_the_same_full_disk_does_not_turn_it_into_a_traceback(tmp_path, monkeypatch):
    class FullStream(io.StringIO):
        def write(self, text):
            raise OSError(errno.ENOSPC, 'No space left on device')

    monkeypatch.setattr(recorder.sys, 'stderr', FullStream())
    full = OSError(errno.ENOSPC, 'No space left on device')
    assert recorder._write_failed(tmp_path / 'r.mcap', 'writing', full) == EXIT_DISK_FULL


def test_an_abandoned_recording_keeps_what_was_written(tmp_path):
    writer = BagWriter(tmp_path / 'r.mcap')
    written = (tmp_path / 'r.mcap').read_bytes()
    assert written.startswith(b'\x89MCAP0\r\n')

    def full(*args):
        raise OSError(errno.ENOSPC, 'No space left on device')

    writer._stream.flush = full  # the close's flush fails as the writes did
    writer.abandon()  # no error: what the disk holds stays for `stealth bag recover`
    assert writer.closed and (tmp_path / 'r.mcap').read_bytes() == written
    writer.close()  # closed already: nothing more
