"""Node processes: started in their own groups, watched, stopped in order (plain processes)."""

import os
import signal
import sys
import time

import pytest
from stealth_bringup.supervisor import Supervisor, exit_description, last_line

POLITE = """
import signal, sys, time
def bye(*_):
    print('stopping', flush=True)
    sys.exit(0)
signal.signal(signal.SIGINT, bye)
print('[INFO] [1700000000.5] [polite]: up', flush=True)
while True:
    time.sleep(0.05)
"""
STUBBORN = """
import signal, time
signal.signal(signal.SIGINT, signal.SIG_IGN)
print('ignoring SIGINT', flush=True)
while True:
    time.sleep(0.05)
"""
CRASH = """
import sys
print('[FATAL] [1700000000.25] [crash]: not starting: parameter x: bad', flush=True)
sys.exit(2)
"""


@pytest.fixture
def supervisor(tmp_path):
    supervisor = Supervisor(dict(os.environ), tmp_path / 'logs')
    yield supervisor
    supervisor.kill_all()


def wait_for(predicate, timeout=10.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


def test_a_crash_is_told_with_its_exit_code_and_last_log_line(supervisor):
    node = supervisor.start('crash', [sys.executable, '-c', CRASH])
    assert wait_for(lambda: supervisor.dead() == [node])
    assert node.why('during startup').startswith('crash exited with code 2 during startup after ')
    assert node.why().endswith(': [FATAL] not starting: parameter x: bad')
    assert node.log_path.name == 'crash.log'


def test_stop_goes_in_order_and_kills_only_what_does_not_listen(supervisor):
    polite = supervisor.start('polite', [sys.executable, '-c', POLITE])
    stubborn = supervisor.start('stubborn', [sys.executable, '-c', STUBBORN])
    assert wait_for(lambda: 'up' in polite.log_path.read_text())
    assert wait_for(lambda: 'ignoring' in stubborn.log_path.read_text())
    assert os.getpgid(polite.pid) == polite.pid  # a process group of its own
    stopped = []
    supervisor.stop(['stubborn', 'polite'], timeout=0.5, on_stop=stopped.append)
    assert stopped == ['stubborn', 'polite']
    assert stubborn.killed and stubborn.process.returncode == -signal.SIGKILL
    assert not polite.killed and polite.process.returncode == 0
    assert 'stopping' in polite.log_path.read_text()
    assert supervisor.any_killed
    assert supervisor.unclean() == [stubborn]
    assert supervisor.dead() == []  # stopped on request is not dead


def test_hurry_kills_at_once(supervisor):
    stubborn = supervisor.start('stubborn', [sys.executable, '-c', STUBBORN])
    assert wait_for(lambda: 'ignoring' in stubborn.log_path.read_text())
    started = time.monotonic()
    supervisor.stop(['stubborn'], timeout=30.0, hurry=lambda: True)
    assert time.monotonic() - started < 5.0
    assert stubborn.killed


def test_last_line_and_exit_descriptions(tmp_path):
    log = tmp_path / 'x.log'
    log.write_text('first\n[ERROR] [1700000000.123456] [agent]: it broke\n\n  \n')
    assert last_line(log) == '[ERROR] it broke'
    assert last_line(tmp_path / 'missing.log') == ''
    assert exit_description(2) == 'exited with code 2'
    assert exit_description(-signal.SIGSEGV) == 'was killed by SIGSEGV'


def test_a_restarted_node_keeps_the_dead_ones_log_and_counts_as_killed(supervisor):
    first = supervisor.start('crash', [sys.executable, '-c', CRASH])
    assert wait_for(lambda: supervisor.dead() == [first])
    second = supervisor.start('crash', [sys.executable, '-c', CRASH])
    assert supervisor.nodes['crash'] is second and supervisor.retired == [first]
    assert wait_for(lambda: second in supervisor.dead())
    lines = second.log_path.read_text().splitlines()
    assert sum(line.startswith('[FATAL]') for line in lines) == 2
    assert any(line.startswith('--- crash started again: ') for line in lines)
    assert not supervisor.any_killed
    killed = supervisor.start('polite', [sys.executable, '-c', POLITE])
    killed.signal_group(signal.SIGKILL)
    assert wait_for(lambda: not killed.alive)
    supervisor.start('polite', [sys.executable, '-c', POLITE])
    assert supervisor.any_killed  # an earlier process of a node counts too


def test_a_restart_cause_is_a_message_never_a_traceback_marker(tmp_path):
    log = tmp_path / 'recorder.log'
    log.write_text(
        'Traceback (most recent call last):\n'
        '  File "/x/recorder.py", line 12, in record\n'
        '    spin_until(executor, stop)\n'
        '    ~~~~~~~~~~^^^^^^^^^^^^^^^^\n'
        'OSError: [Errno 28] No space left on device\n'
        '          ^^^^^^^^\n'
    )
    assert last_line(log) == 'OSError: [Errno 28] No space left on device'
    # Cut short (the disk filled as it was written): said so, with the last frame.
    log.write_text(
        'Traceback (most recent call last):\n'
        '  File "/x/recorder.py", line 12, in record\n'
        '    spin_until(executor, stop)\n'
        '    ~~~~~~~~~~^^^^^^^^^^^^^^^^\n'
    )
    assert last_line(log) == (
        'its log ends inside a Python traceback (cut short) at '
        'File "/x/recorder.py", line 12, in record'
    )


def test_a_restart_cause_comes_from_the_latest_process_only(tmp_path):
    log = tmp_path / 'agent.log'
    log.write_text(
        '[ERROR] [1700000000.1] [agent]: the first one broke\n'
        '--- agent started again: agent --ros-args\n'
    )
    assert last_line(log) == ''  # not the line of the process before
    with log.open('a') as stream:
        stream.write('[INFO] [1700000001.2] [agent]: the second one\n')
    assert last_line(log) == '[INFO] the second one'
