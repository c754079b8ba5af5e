"""Writing MCAP the way rosbag2's MCAP storage plugin does, with a bound on what a crash loses.

Layout as rosbag2: profile `ros2`; one schema per type (encoding `ros2msg`, full definition
text); one channel per topic (message encoding `cdr`, metadata `offered_qos_profiles` and
`topic_type_hash`); a `rosbag2` metadata record with the serialized BagMetadata written at open
and again at close; log and publish times in ns. Chunks are zstd (or lz4, or none) and indexed.

The mcap writer keeps its open chunk in memory, so a SIGKILL loses that chunk. BagWriter closes
the chunk (Writer.flush, which also flushes the file to the OS) once it is `max_chunk_duration`
old or `chunk_size` bytes big, whichever comes first: `write` checks the age on every message
and `flush_if_due` is for a timer, so a quiet topic is bounded too.

Which .mcap a bag path names (`resolve_bag_file`) is here too, below both bag_reading and
bag_recover, because reading falls back on recovery's salvage scan.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import os
from pathlib import Path
import time

from mcap.opcode import Opcode
from mcap.writer import CompressionType, IndexType, Writer
import yaml

from stealth_tools.qos_text import QosDescription, offered_qos_yaml, qos_node

PROFILE = 'ros2'
MESSAGE_ENCODING = 'cdr'
ROSBAG2_METADATA_NAME = 'rosbag2'
METADATA_VERSION = 9  # rosbag2_storage::BagMetadata version in Jazzy
STORAGE_ID = 'mcap'
LIBRARY = 'stealth_tools recorder (mcap-python)'
DEFAULT_CHUNK_SIZE = 256 * 1024
DEFAULT_MAX_CHUNK_DURATION = 0.5  # s
COMPRESSIONS = {
    'zstd': CompressionType.ZSTD,
    'lz4': CompressionType.LZ4,
    'none': CompressionType.NONE,
}
MCAP_MAGIC = b'\x89MCAP0\r\n'
_RECORD_HEAD_SIZE = 9  # opcode (1 byte) and length (8 bytes, little-endian)
_NEVER = 2**63 - 1  # rosbag2's starting_time before the first message


class BagError(Exception):
    """A bag that cannot be written or read; the message says which file and why."""


def resolve_bag_file(path: str | os.PathLike) -> Path:
    """The .mcap a bag path names: the file itself, or the one .mcap in a bag directory."""
    path = Path(path)
    if path.is_dir():
        files = sorted(path.glob('*.mcap'))
        if not files:
            raise BagError(f'{path} is a directory without an .mcap file')
        if len(files) > 1:
            names = ', '.join(f.name for f in files)
            raise BagError(f'{path} holds several .mcap files ({names}); name one of them')
        return files[0]
    if not path.exists():
        raise BagError(f'{path}: no such file or directory')
    with open(path, 'rb') as stream:
        if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise BagError(
                f'{path}: not an MCAP file ({path.stat().st_size} bytes, no MCAP magic): nothing '
                'to play or recover'
            )
    return path


def cut_before_header(path: str | os.PathLike) -> str | None:
    """The one line to say of an MCAP file that ends before its header record is complete (a
    recorder stopped as it began): no messages in it, nothing to play, info or recover agree.
    None for any other file."""
    path = Path(path)
    with open(path, 'rb') as stream:
        head = stream.read(len(MCAP_MAGIC) + _RECORD_HEAD_SIZE)
    if not head.startswith(MCAP_MAGIC):
        return None
    size = path.stat().st_size
    if len(head) == len(MCAP_MAGIC) + _RECORD_HEAD_SIZE and head[len(MCAP_MAGIC)] == Opcode.HEADER:
        length = int.from_bytes(head[len(MCAP_MAGIC) + 1 :], 'little')
        if size >= len(head) + length:
            return None
    return (
        f'{path}: an MCAP file that ends before its header is complete ({size} bytes): it holds '
        'no messages; nothing to play or recover'
    )


@dataclass(frozen=True)
class BagPaths:
    """Where a recording goes: a lone .mcap, or a rosbag2 directory with metadata.yaml."""

    mcap: Path
    directory: Path | None = None

    @property
    def metadata_yaml(self) -> Path | None:
        return self.directory / 'metadata.yaml' if self.directory else None


def bag_paths(output: str | os.PathLike) -> BagPaths:
    """'run.mcap' is written as is; 'run' becomes run/run_0.mcap + run/metadata.yaml (rosbag2)."""
    output = Path(output)
    if output.suffix == '.mcap':
        return BagPaths(mcap=output)
    return BagPaths(mcap=output / f'{output.name}_0.mcap', directory=output)


@dataclass
class TopicEntry:
    """What the writer knows of one recorded topic."""

    name: str
    type: str
    offered_qos: list[QosDescription]
    type_hash: str
    channel_id: int
    message_count: int = 0


@dataclass
class _Span:
    """First and last log time seen, and the message count."""

    start: int = _NEVER
    end: int = 0
    count: int = 0

    def add(self, log_time: int) -> None:
        self.start = min(self.start, log_time)
        self.end = max(self.end, log_time)
        self.count += 1

    @property
    def duration(self) -> int:
        return self.end - self.start if self.count else 0


@dataclass
class _ChunkAge:
    """When the chunk now in memory got its first message (monotonic s), or None if empty."""

    opened: float | None = None
    clock: object = field(default=time.monotonic)

    def touch(self) -> None:
        if self.opened is None:
            self.opened = self.clock()

    def older_than(self, seconds: float) -> bool:
        return self.opened is not None and self.clock() - self.opened >= seconds


def bag_metadata(
    *,
    file_name: str,
    topics: list[TopicEntry],
    span_start: int,
    span_duration: int,
    message_count: int,
    ros_distro: str,
) -> dict:
    """rosbag2's BagMetadata (version 9) as the mapping its YAML encoder writes."""
    return {
        'version': METADATA_VERSION,
        'storage_identifier': STORAGE_ID,
        'duration': {'nanoseconds': span_duration},
        'starting_time': {'nanoseconds_since_epoch': span_start},
        'message_count': message_count,
        'topics_with_message_count': [
            {
                'topic_metadata': {
                    'name': topic.name,
                    'type': topic.type,
                    'serialization_format': MESSAGE_ENCODING,
                    'offered_qos_profiles': [qos_node(p) for p in topic.offered_qos],
                    'type_description_hash': topic.type_hash,
                },
                'message_count': topic.message_count,
            }
            for topic in topics
        ],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [
            {
                'path': file_name,
                'starting_time': {'nanoseconds_since_epoch': span_start},
                'duration': {'nanoseconds': span_duration},
                'message_count': message_count,
            }
        ],
        'custom_data': {},
        'ros_distro': ros_distro,
    }


def dump_yaml(data) -> str:
    """Block-style YAML in the given key order."""
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=False)


class BagWriter:
    """An open MCAP recording: topics are added as discovered, messages written as received."""

    def __init__(
        self,
        output: str | os.PathLike,
        *,
        compression: str = 'zstd',
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        max_chunk_duration: float = DEFAULT_MAX_CHUNK_DURATION,
        ros_distro: str | None = None,
        clock=time.monotonic,
    ):
        if compression not in COMPRESSIONS:
            raise BagError(f"unknown compression '{compression}' (choose from zstd, lz4, none)")
        if chunk_size <= 0 or max_chunk_duration <= 0:
            raise BagError('chunk_size and max_chunk_duration must be positive')
        self.paths = bag_paths(output)
        self.max_chunk_duration = max_chunk_duration
        self.ros_distro = ros_distro or os.environ.get('ROS_DISTRO') or 'jazzy'
        self.topics: dict[str, TopicEntry] = {}
        self._schema_ids: dict[str, int] = {}
        self._span = _Span()
        self._chunk = _ChunkAge(clock=clock)
        self._stream = self._open_file()
        self._writer = Writer(
            self._stream,
            chunk_size=chunk_size,
            compression=COMPRESSIONS[compression],
            index_types=IndexType.ALL,
        )
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._write_metadata_record()
        self._writer.flush()
        self.closed = False

    def _open_file(self):
        target = self.paths.directory or self.paths.mcap
        if target.exists():
            raise BagError(f'{target} already exists; choose another output')
        try:
            if self.paths.directory:
                self.paths.directory.mkdir(parents=False)
            return open(self.paths.mcap, 'xb')  # noqa: SIM115 - closed in close()
        except OSError as error:
            raise BagError(f'cannot create {target}: {error.strerror}') from None

    @property
    def message_count(self) -> int:
        return self._span.count

    def add_topic(
        self,
        name: str,
        type_name: str,
        definition: str,
        offered_qos: list[QosDescription],
        type_hash: str = '',
    ) -> None:
        """Register a topic (and its type's schema, once per type) before its first message."""
        if name in self.topics:
            return
        if type_name not in self._schema_ids:
            self._schema_ids[type_name] = self._writer.register_schema(
                name=type_name, encoding='ros2msg', data=definition.encode()
            )
        channel_id = self._writer.register_channel(
            topic=name,
            message_encoding=MESSAGE_ENCODING,
            schema_id=self._schema_ids[type_name],
            metadata={
                'offered_qos_profiles': offered_qos_yaml(offered_qos),
                'topic_type_hash': type_hash,
            },
        )
        self.topics[name] = TopicEntry(name, type_name, list(offered_qos), type_hash, channel_id)

    def write(self, topic: str, data: bytes, log_time: int, publish_time: int) -> None:
        """Append one serialized message; close the chunk if it has grown old."""
        entry = self.topics[topic]
        self._writer.add_message(
            channel_id=entry.channel_id, log_time=log_time, data=data, publish_time=publish_time
        )
        entry.message_count += 1
        self._span.add(log_time)
        self._chunk.touch()
        self.flush_if_due()

    def flush_if_due(self) -> None:
        """Write out the open chunk if it is older than max_chunk_duration."""
        if self._chunk.older_than(self.max_chunk_duration):
            self.flush()

    def flush(self) -> None:
        """Close the open chunk (with its message index) and hand everything to the OS."""
        self._writer.flush()
        self._chunk.opened = None

    def metadata(self) -> dict:
        """The rosbag2 BagMetadata of what has been written so far."""
        return bag_metadata(
            file_name=self.paths.mcap.name,
            topics=list(self.topics.values()),
            span_start=self._span.start,
            span_duration=self._span.duration,
            message_count=self._span.count,
            ros_distro=self.ros_distro,
        )

    def _write_metadata_record(self) -> None:
        self._writer.add_metadata(
            ROSBAG2_METADATA_NAME, {'serialized_metadata': dump_yaml(self.metadata())}
        )

    def abandon(self) -> None:
        """Close the file without finishing it, after a write failed (a full disk): the chunks
        written before stay for `stealth bag recover`; a failing close says nothing new."""
        if self.closed:
            return
        self.closed = True
        with contextlib.suppress(OSError):
            self._stream.close()

    def close(self) -> None:
        """Final metadata, summary, indexes and footer; metadata.yaml for a bag directory."""
        if self.closed:
            return
        self.closed = True
        self.flush()
        self._write_metadata_record()
        self._writer.finish()
        self._stream.close()
        if self.paths.metadata_yaml:
            self.paths.metadata_yaml.write_text(
                dump_yaml({'rosbag2_bagfile_information': self.metadata()})
            )
