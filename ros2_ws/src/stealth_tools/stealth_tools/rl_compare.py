"""Comparing two recordings' RL episodes message for message (issue 15: determinism). No rclpy.

Two runs with the same seed and settings must hand the agent the same states and rewards, get
the same actions back and report the same episodes, whatever the load on the machine. This
reads the RL topics of two recordings and finds the first message in which they differ.

What is compared: every message's fields, except the header stamps (the wall-clock time a
message was received is the recording's, not the episode's). A recording may hold the start of
an episode after the last one the run counted (the agent had begun it when the run stopped),
so only the first ``count`` complete episodes of each are compared: the states and rewards up
to the ``count``-th terminal state, the actions that answered the non-terminal ones, and the
episode reports numbered below ``count``. `stealth bag compare A B` is the command line.

    first = read_rl_topics('runs/a/recording.mcap')
    problem = first_difference(first, read_rl_topics('runs/b/recording.mcap'), count=20)
    assert problem is None, problem     # 'rl_agent/rl_action, message 812 (episode 30, ...'
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
import math
import numbers
import os
from typing import Any

from stealth_node_kit import rl_contract

from stealth_tools.bag_format import BagError, resolve_bag_file

# As a recording names them, in the order the loop produces them within a step: a difference
# is named in the first.
RL_TOPICS = tuple(rl_contract.absolute(name) for name in rl_contract.RL_TOPICS)
STATE, ACTION, STEP_INFO, SUMMARY, EXPERIMENT_INFO, EPISODE_INFO = RL_TOPICS
# The fields that place a report in the episode sequence, by topic: (episode, step).
PLACE_FIELDS = {
    STEP_INFO: ('episode', 'step'),
    SUMMARY: ('episode', 'steps'),
    EXPERIMENT_INFO: ('episode_number', 'number_actions'),
    EPISODE_INFO: ('episode', 'steps'),
}


@dataclass(frozen=True)
class Located:
    """One message as plain data, with where it is in the episode sequence."""

    fields: Any  # plain dicts, lists and numbers (no stamps)
    episode: int
    step: int  # 0: the first state of an episode; k: after the k-th action (reports: the last)


def plain(message: Any) -> Any:
    """A decoded ROS message (mcap_ros2's or rclpy's) as nested dicts and lists, header stamps
    left out and NaN made comparable ('nan')."""
    if isinstance(message, str | bytes | bool) or message is None:
        return message
    if isinstance(message, numbers.Integral):
        return int(message)
    if isinstance(message, numbers.Real):  # float, and numpy's float32 of rclpy's arrays
        value = float(message)
        return 'nan' if math.isnan(value) else value
    names = _field_names(message)
    if isinstance(message, Mapping) or names is not None:
        items = message.items() if names is None else ((n, getattr(message, n)) for n in names)
        fields = {name: plain(value) for name, value in items}
        if 'stamp' in fields and 'frame_id' in fields:  # a std_msgs/Header
            del fields['stamp']
        return fields
    if isinstance(message, Iterable):
        return [plain(value) for value in message]
    raise TypeError(f'cannot compare a {type(message).__name__}')


def _field_names(message: Any) -> list[str] | None:
    slots = getattr(type(message), '__slots__', None)
    if slots is None:
        return None
    if hasattr(message, 'get_fields_and_field_types'):  # rclpy: slots are '_name'
        return list(message.get_fields_and_field_types())
    return list(slots)


def locate(topics: Mapping[str, list], count: int | None = None) -> dict[str, list[Located]]:
    """The RL topics' messages (plain data, in recorded order) placed in their episodes, cut to
    the first ``count`` complete episodes (None: everything, the last episode maybe partial)."""
    states = [plain(m) for m in topics.get(STATE, ())]
    actions = [plain(m) for m in topics.get(ACTION, ())]
    located: dict[str, list[Located]] = {STATE: [], ACTION: []}
    episode = step = 0
    acted = 0  # actions answering the non-terminal states so far
    for state in states:
        if count is not None and episode >= count:
            break
        located[STATE].append(Located(state, episode, step))
        if state.get('terminal'):
            episode, step = episode + 1, 0
        else:
            if acted < len(actions):
                located[ACTION].append(Located(actions[acted], episode, step + 1))
            acted += 1
            step += 1
    for topic, (episode_field, step_field) in PLACE_FIELDS.items():
        messages = [plain(m) for m in topics.get(topic, ())]
        located[topic] = [
            Located(m, int(m[episode_field]), int(m[step_field]))
            for m in messages
            if count is None or int(m[episode_field]) < count
        ]
    return located


def complete_episodes(topics: Mapping[str, list]) -> int:
    """How many episodes a recording holds to the end (terminal state and summary both)."""
    terminals = sum(1 for m in topics.get(STATE, ()) if plain(m).get('terminal'))
    summaries = len(topics.get(SUMMARY, ()))
    return min(terminals, summaries)


def first_difference(
    first: Mapping[str, list], second: Mapping[str, list], count: int
) -> str | None:
    """None when the first ``count`` episodes of two recordings' RL topics are the same message
    for message; else one line naming the earliest message that differs (topic, index,
    episode, step) and how."""
    for name, topics in (('the first', first), ('the second', second)):
        have = complete_episodes(topics)
        if have < count:
            return (
                f'{name} recording holds {have} complete episodes, fewer than the {count} compared'
            )
    a, b = locate(first, count), locate(second, count)
    found = []
    for order, topic in enumerate(RL_TOPICS):
        problem = _topic_difference(topic, a[topic], b[topic])
        if problem is not None:
            where, text = problem
            found.append(((where.episode, where.step, order), text))
    if not found:
        return None
    found.sort(key=lambda item: item[0])
    others = len(found) - 1
    topics = '1 other topic differs' if others == 1 else f'{others} other topics differ'
    tail = f' ({topics} too)' if others else ''
    return found[0][1] + tail


def _topic_difference(topic: str, a: list[Located], b: list[Located]):
    for index, (x, y) in enumerate(zip(a, b, strict=False)):
        if x.fields != y.fields:
            field, left, right = _differing_field(x.fields, y.fields)
            return x, (
                f'{topic.lstrip("/")}, message {index} (episode {x.episode}, step {x.step}): '
                f'{field or "the message"} is {left!r} in the first recording, {right!r} in '
                'the second'
            )
    if len(a) != len(b):
        shorter, longer = (a, b) if len(a) < len(b) else (b, a)
        extra = longer[len(shorter)]
        which = 'first' if longer is a else 'second'
        return extra, (
            f'{topic.lstrip("/")}: {len(a)} messages in the first recording, {len(b)} in the '
            f'second; message {len(shorter)} (episode {extra.episode}, step {extra.step}) is '
            f'only in the {which}'
        )
    return None


def _differing_field(a: Any, b: Any, path: str = '') -> tuple[str, Any, Any]:
    """The first field (dotted path, [i] for list items) in which two plain values differ."""
    if isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys():
        for key in a:
            if a[key] != b[key]:
                return _differing_field(a[key], b[key], f'{path}.{key}' if path else key)
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            if x != y:
                return _differing_field(x, y, f'{path}[{i}]')
    return path, a, b


def read_rl_topics(path: str | os.PathLike) -> dict[str, list]:
    """{topic: [decoded message, ...]} of a recording's RL topics, in recorded order.
    BagError (one line) for a path that is no readable recording."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    mcap_path = resolve_bag_file(path)
    topics: dict[str, list] = {topic: [] for topic in RL_TOPICS}
    try:
        with open(mcap_path, 'rb') as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            for _, channel, _, decoded in reader.iter_decoded_messages(topics=list(RL_TOPICS)):
                topics[channel.topic].append(decoded)
    except (McapError, OSError, ValueError, EOFError) as error:
        raise BagError(
            f'{mcap_path}: cannot be read as an MCAP recording ({error}); if it was cut off, '
            f'`stealth bag recover {mcap_path}` writes a complete copy'
        ) from None
    return topics
