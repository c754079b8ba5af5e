"""The orphan watch: a process asked to die with its parent ends, with its stacks in its log,
even when its main thread is stuck; one not asked is left alone."""

from pathlib import Path
import signal
import subprocess
import sys
import time

from stealth_node_kit.orphan_watch import parent_death_signal, watch_for_orphaning

LIMIT = 1.0  # s: the watch's limit in these tests

# A node whose stop signal is noticed but never acted on: its main thread waits on a pipe no one
# writes (os.read retries after the handler, PEP 475). With 'pdeath' it asks for SIGTERM when
# its parent dies, as the orchestrator's nodes do.
NODE = f"""
import ctypes, os, signal, sys
from stealth_node_kit.orphan_watch import watch_for_orphaning
if sys.argv[1] == 'pdeath':
    ctypes.CDLL(None).prctl(1, signal.SIGTERM)
signal.signal(signal.SIGTERM, lambda *_: None)
watch_for_orphaning(limit={LIMIT}, poll=0.05)
print(os.getpid(), flush=True)
reading, _ = os.pipe()
os.read(reading, 1)
"""

# Starts the node, passes its pid on once it is set up, then dies.
PARENT = """
import subprocess, sys
with open(sys.argv[2], 'w') as log:
    node = subprocess.Popen(
        [sys.executable, '-c', sys.argv[1], sys.argv[3]], stdout=subprocess.PIPE, stderr=log
    )
    print(node.stdout.readline().decode().strip(), flush=True)
"""


def orphan(mode: str, log: Path) -> int:
    """The pid of a NODE in `mode` whose parent has died."""
    parent = subprocess.run(
        [sys.executable, '-c', PARENT, NODE, str(log), mode],
        capture_output=True,
        text=True,
        timeout=30,
        check=True,
    )
    return int(parent.stdout.strip())


def running(pid: int) -> bool:
    """Whether `pid` lives (a zombie no one reaps has ended)."""
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return False
    return stat.rsplit(')', 1)[1].split()[0] != 'Z'


def wait_gone(pid: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while running(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not running(pid)


def kill(pid: int) -> None:
    if running(pid):
        subprocess.run(['kill', '-9', str(pid)], check=False)


def test_a_stuck_orphan_ends_after_the_limit_with_its_stacks_in_its_log(tmp_path):
    log = tmp_path / 'node.log'
    pid = orphan('pdeath', log)
    try:
        started = time.monotonic()
        assert wait_gone(pid, LIMIT + 20.0), 'the stuck orphan still runs'
        assert time.monotonic() - started >= LIMIT * 0.5  # the limit, not at once
    finally:
        kill(pid)
    text = log.read_text()
    assert 'most recent call first' in text, text  # faulthandler's dump of every thread
    stuck_at = NODE.splitlines().index('os.read(reading, 1)') + 1
    assert f'line {stuck_at} in <module>' in text, text  # where the main thread was stuck


def test_a_process_not_asked_to_die_with_its_parent_is_left_alone(tmp_path):
    pid = orphan('nohup', tmp_path / 'node.log')
    try:
        time.sleep(LIMIT + 2.0)
        assert running(pid), 'a process run under nohup was ended'
    finally:
        kill(pid)
    assert (tmp_path / 'node.log').read_text() == ''


def test_only_a_process_asked_to_die_with_its_parent_is_watched():
    assert parent_death_signal() == 0  # pytest is not
    assert watch_for_orphaning() is None


# Starts a sleeper with die_with_parent (its `first` writing a mark the sleeper reads back, and
# the sleeper reporting its parent-death signal), passes its pid and that line on, then dies.
STARTER = """
import os, subprocess, sys
from stealth_node_kit.orphan_watch import die_with_parent
sleeper = subprocess.Popen(
    [sys.executable, '-c',
     'import os, time; from stealth_node_kit.orphan_watch import parent_death_signal; '
     'print(os.getpid(), os.environ.get("FIRST_RAN", "-"), parent_death_signal(), flush=True); '
     'time.sleep(60)'],
    stdout=subprocess.PIPE,
    preexec_fn=die_with_parent(lambda: os.environ.__setitem__('FIRST_RAN', 'yes')),
)
print(sleeper.stdout.readline().decode().strip(), flush=True)
"""


def test_a_child_started_to_die_with_its_parent_ends_when_the_parent_dies():
    starter = subprocess.run(
        [sys.executable, '-c', STARTER], capture_output=True, text=True, timeout=30, check=True
    )
    pid, first_ran, death_signal = starter.stdout.split()
    try:
        assert first_ran == 'yes'  # `first` ran in the child, before exec
        assert int(death_signal) == signal.SIGTERM
        assert wait_gone(int(pid), 10.0), 'the child outlived its parent'
    finally:
        kill(int(pid))
