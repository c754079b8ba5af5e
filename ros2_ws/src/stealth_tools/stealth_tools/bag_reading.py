"""Reading recordings: a bag's summary and `ros2 bag info`'s text.

A bag path is a .mcap file or a directory holding one recording, in one file or split over
several (bag_files: a run directory's recording.mcap, recording_1.mcap, ...), read as one bag.
The summary comes from the MCAP summary section; a recording that was never closed (SIGKILL,
power loss) has none, and its numbers come from a salvage scan instead, flagged so the caller
can suggest `bag recover`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import os
from pathlib import Path
import time

from mcap.exceptions import McapError
from mcap.reader import SeekingReader, make_reader
import yaml

from stealth_tools.bag_files import bag_files
from stealth_tools.bag_format import (
    ROSBAG2_METADATA_NAME,
    STORAGE_ID,
    BagError,
    cut_before_header,
)

INFO_INDENT = 19  # rosbag2: the longest field name ('Topic information: ') plus one


@dataclass(frozen=True)
class TopicInfo:
    name: str
    type: str
    count: int
    serialization_format: str
    offered_qos_profiles: str = ''


@dataclass(frozen=True)
class BagInfo:
    """What `ros2 bag info` shows of one MCAP file."""

    path: Path
    size: int
    ros_distro: str
    start_ns: int
    end_ns: int
    message_count: int
    topics: tuple[TopicInfo, ...]
    indexed: bool = True
    files: tuple[Path, ...] = ()  # the files of a split bag, in order (empty: just `path`)
    unindexed: tuple[Path, ...] = ()  # those of them that were never closed

    @property
    def duration_ns(self) -> int:
        return self.end_ns - self.start_ns

    @property
    def paths(self) -> tuple[Path, ...]:
        return self.files or (self.path,)


def open_indexed_reader(stream) -> SeekingReader:
    """A seeking reader over a complete MCAP; BagError if the summary is missing or broken."""
    reader = make_reader(stream)
    try:
        summary = reader.get_summary()
    except (McapError, ValueError, EOFError, OSError) as error:
        summary = None
        reason = str(error) or type(error).__name__
    else:
        reason = 'it has no summary section'
    if summary is None or summary.statistics is None:
        name = getattr(stream, 'name', 'the file')
        if isinstance(name, str) and (empty := cut_before_header(name)):
            raise BagError(empty)
        raise BagError(
            f'{name} is not a complete MCAP ({reason}): the recording was cut off; '
            f'`stealth bag recover {name}` rebuilds it'
        )
    return reader


def _distro_in(record) -> str:
    """ROS_DISTRO of one rosbag2 metadata record ('' if it has none)."""
    try:
        loaded = yaml.safe_load(record.metadata.get('serialized_metadata', '')) or {}
    except yaml.YAMLError:
        loaded = {}
    return str(loaded.get('ros_distro') or record.metadata.get('ROS_DISTRO', ''))


def ros_distro_of(metadata_records) -> str:
    """ROS_DISTRO as rosbag2 reads it: from the last rosbag2 metadata record that has one."""
    distro = ''
    for record in metadata_records:
        if record.name == ROSBAG2_METADATA_NAME:
            distro = _distro_in(record) or distro
    return distro


def _topics(channels: dict, schemas: dict, counts: dict) -> tuple[TopicInfo, ...]:
    return tuple(
        TopicInfo(
            name=channel.topic,
            type=schemas[channel.schema_id].name if channel.schema_id in schemas else '',
            count=counts.get(channel_id, 0),
            serialization_format=channel.message_encoding,
            offered_qos_profiles=channel.metadata.get('offered_qos_profiles', ''),
        )
        for channel_id, channel in sorted(channels.items())
    )


def read_bag_info(path: str | os.PathLike) -> BagInfo:
    """Info of a bag (all its files) from their summaries, or from a salvage scan of a file
    that has none."""
    files = bag_files(path)
    if len(files) == 1 and (empty := cut_before_header(files[0])):
        raise BagError(empty)  # not 0 messages from 1970: there is no recording
    infos = [_file_info(file) for file in files]
    return infos[0] if len(infos) == 1 else merge_bag_infos(Path(path), infos)


def merge_bag_infos(path: Path, infos: list[BagInfo]) -> BagInfo:
    """One info for the files of a split bag, as rosbag2 totals them."""
    topics: dict[str, TopicInfo] = {}
    for info in infos:
        for topic in info.topics:
            known = topics.get(topic.name)
            count = topic.count + (known.count if known else 0)
            topics[topic.name] = dataclasses.replace(known or topic, count=count)
    with_messages = [i for i in infos if i.message_count]
    return BagInfo(
        path=path,
        size=sum(i.size for i in infos),
        ros_distro=next((i.ros_distro for i in reversed(infos) if i.ros_distro), ''),
        start_ns=min((i.start_ns for i in with_messages), default=0),
        end_ns=max((i.end_ns for i in with_messages), default=0),
        message_count=sum(i.message_count for i in infos),
        topics=tuple(topics.values()),
        indexed=all(i.indexed for i in infos),
        files=tuple(i.path for i in infos),
        unindexed=tuple(i.path for i in infos if not i.indexed),
    )


def _file_info(mcap_path: Path) -> BagInfo:
    """Info of one .mcap file."""
    size = mcap_path.stat().st_size
    with open(mcap_path, 'rb') as stream:
        try:
            reader = open_indexed_reader(stream)
        except BagError:
            return _scanned_bag_info(mcap_path, size)
        summary = reader.get_summary()
        statistics = summary.statistics
        return BagInfo(
            path=mcap_path,
            size=size,
            ros_distro=ros_distro_of(reader.iter_metadata()),
            start_ns=statistics.message_start_time,
            end_ns=statistics.message_end_time,
            message_count=statistics.message_count,
            topics=_topics(summary.channels, summary.schemas, statistics.channel_message_counts),
        )


def _scanned_bag_info(mcap_path: Path, size: int) -> BagInfo:
    """Info of a truncated MCAP, counted record by record up to where it breaks off."""
    from mcap.records import Channel, Message, Metadata, Schema

    from stealth_tools.bag_recover import salvage_records

    channels, schemas, counts, metadata = {}, {}, {}, []
    start, end, total = None, 0, 0
    with open(mcap_path, 'rb') as stream:
        for record in salvage_records(stream):
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
                start = record.log_time if start is None else min(start, record.log_time)
                end = max(end, record.log_time)
                total += 1
            elif isinstance(record, Metadata):
                metadata.append(record)
    return BagInfo(
        path=mcap_path,
        size=size,
        ros_distro=ros_distro_of(metadata),
        start_ns=start or 0,
        end_ns=end,
        message_count=total,
        topics=_topics(channels, schemas, counts),
        indexed=False,
        unindexed=(mcap_path,),
    )


def format_file_size(size: int) -> str:
    """'1.5 MiB' as rosbag2 prints sizes (no decimals for bytes)."""
    value, unit = float(size), 0
    units = ('B', 'KiB', 'MiB', 'GiB', 'TiB')
    while value >= 1024 and unit < len(units) - 1:
        value /= 1024
        unit += 1
    return f'{value:.0f} {units[unit]}' if unit == 0 else f'{value:.1f} {units[unit]}'


def _seconds_text(nanoseconds: int) -> str:
    return f'{nanoseconds // 10**9}.{nanoseconds % 10**9:09d}'


def format_time_point(nanoseconds: int) -> str:
    """'Jan  5 2025 14:03:07.123456789 (1736085787.123456789)' in local time, as rosbag2."""
    local = time.localtime(nanoseconds // 10**9)
    fraction = f'{nanoseconds % 10**9:09d}'
    stamp = time.strftime('%b %e %Y %H:%M:%S', local)
    return f'{stamp}.{fraction} ({_seconds_text(nanoseconds)})'


def format_bag_info(info: BagInfo, shown_path: str | None = None) -> str:
    """The text `ros2 bag info` prints for the bag (rosbag2_py's format_bag_meta_data)."""
    pad = ' ' * INFO_INDENT
    topic_lines = [
        f'Topic: {t.name} | Type: {t.type} | Count: {t.count} | '
        f'Serialization Format: {t.serialization_format}'
        for t in info.topics
    ]
    topics_text = ('\n' + pad).join(topic_lines)
    if info.files:  # a split bag: each file, under the path given
        shown = [os.path.join(shown_path, f.name) if shown_path else str(f) for f in info.files]
    else:
        shown = [str(shown_path or info.path)]
    files_text = ('\n' + pad).join(shown)
    lines = [
        '',
        f'Files:             {files_text}',
        f'Bag size:          {format_file_size(info.size)}',
        f'Storage id:        {STORAGE_ID}',
        f'ROS Distro:        {info.ros_distro or "unknown"}',
        f'Duration:          {_seconds_text(info.duration_ns)}s',
        f'Start:             {format_time_point(info.start_ns)}',
        f'End:               {format_time_point(info.end_ns)}',
        f'Messages:          {info.message_count}',
        f'Topic information: {topics_text}',
        'Service:           0',
        'Service information: ',
    ]
    return '\n'.join(lines) + '\n'
