"""--timeout bounds the whole of `topic echo` and `topic hz`, the discovery of the topic's type
included, however many messages arrive (no ROS graph: a fake node and a fake clock that every
wait advances)."""

import contextlib
import threading
import types

import pytest
from stealth_tools import cli, graph_tools
from stealth_tools.errors import CommandError


@pytest.fixture
def waits(monkeypatch):
    """The timeouts each wait is given, in order; each advances the clock by its timeout."""
    clock = {'now': 100.0}
    waited = []

    def spin_until(executor, stop, done=lambda: False, timeout=None):
        assert timeout is not None, 'an unbounded wait under --timeout'
        waited.append(timeout)
        clock['now'] += timeout
        return False

    class Node:
        def count_publishers(self, topic):
            return 0

        def create_subscription(self, *args, **kwargs):
            return None

    @contextlib.contextmanager
    def cli_node():
        yield Node(), None

    monkeypatch.setattr(graph_tools, 'spin_until', spin_until)
    monkeypatch.setattr(graph_tools, 'cli_node', cli_node)
    monkeypatch.setattr(graph_tools, 'topic_types', lambda node: {})
    monkeypatch.setattr(graph_tools, '_class_of', lambda name: object)
    monkeypatch.setattr(graph_tools, '_echo_qos', lambda *args: None)
    monkeypatch.setattr(graph_tools, 'time', types.SimpleNamespace(monotonic=lambda: clock['now']))
    return waited


def run(verb, *argv):
    args = cli.build_parser(added={}).parse_args(['topic', verb, *argv])
    return getattr(graph_tools, f'topic_{verb}')(args, threading.Event())


def test_echo_of_a_topic_nobody_publishes_gives_up_after_the_timeout_not_the_spin_time(waits):
    with pytest.raises(CommandError) as error:
        run('echo', '/nope', '--timeout', '2')
    assert sum(waits) == 2.0  # not the 5 s --spin-time
    assert str(error.value).startswith(
        "could not determine the type of '/nope': nothing published it within 2 s"
    )


def test_echo_with_its_type_waits_the_timeout_in_all(waits):
    with pytest.raises(CommandError, match='^no message on /nope within 2 s$'):
        run('echo', '/nope', 'std_msgs/msg/String', '--timeout', '2')
    assert sum(waits) == 2.0


def test_hz_waits_the_timeout_in_all(waits):
    with pytest.raises(CommandError, match='^nothing published /nope within 2 s$'):
        run('hz', '/nope', '--timeout', '2')
    assert sum(waits) == 2.0


def test_without_a_timeout_discovery_takes_the_spin_time(waits):
    with pytest.raises(CommandError, match='within 5 s'):
        run('echo', '/nope')
    assert waits == [5.0]


class Talker:
    """A graph with one publisher of /chatter: the node, and an executor whose every wait
    advances the clock by its timeout and, while `publishing`, delivers a message (at most
    `limit` waits)."""

    def __init__(self, monkeypatch, publishing: bool = True, limit: int = 10_000):
        self.clock = {'now': 100.0}
        self.waits = []
        self.callbacks = []
        self.publishing = publishing
        self.limit = limit
        talker = self

        class Node:
            def count_publishers(self, topic):
                return 1

            def create_subscription(self, message_type, topic, callback, *args, **kwargs):
                talker.callbacks.append(callback)

            def get_clock(self):
                return types.SimpleNamespace(
                    now=lambda: types.SimpleNamespace(nanoseconds=int(talker.clock['now'] * 1e9))
                )

        @contextlib.contextmanager
        def cli_node():
            yield Node(), self

        def spin_until(executor, stop, done=lambda: False, timeout=None):
            return done()

        monkeypatch.setattr(graph_tools, 'spin_until', spin_until)
        monkeypatch.setattr(graph_tools, 'cli_node', cli_node)
        monkeypatch.setattr(
            graph_tools, 'topic_types', lambda node: {'/chatter': ['std_msgs/msg/String']}
        )
        monkeypatch.setattr(graph_tools, '_class_of', lambda name: object)
        monkeypatch.setattr(
            graph_tools, 'time', types.SimpleNamespace(monotonic=lambda: self.clock['now'])
        )

    def spin_once(self, timeout_sec=None):
        assert len(self.waits) < self.limit, 'still listening long after --timeout'
        self.waits.append(timeout_sec)
        self.clock['now'] += timeout_sec
        for callback in self.callbacks if self.publishing else ():
            callback(b'')


def test_hz_of_a_topic_that_keeps_publishing_ends_at_the_timeout(monkeypatch, capsys):
    """--timeout N is the command's time, not N seconds without a message: ros2 topic echo's
    meaning, and what the docs say of both verbs."""
    talker = Talker(monkeypatch)
    assert run('hz', '/chatter', '--timeout', '3') == 0
    assert sum(talker.waits) == pytest.approx(3.0)
    assert capsys.readouterr().out.count('average rate: 10.000') == 2  # at 1 s and at 2 s


def test_hz_of_a_topic_that_stays_silent_is_one_line_at_the_timeout(monkeypatch):
    talker = Talker(monkeypatch, publishing=False)
    with pytest.raises(CommandError, match='^no message on /chatter within 2 s$'):
        run('hz', '/chatter', '--timeout', '2')
    assert sum(talker.waits) == pytest.approx(2.0)
