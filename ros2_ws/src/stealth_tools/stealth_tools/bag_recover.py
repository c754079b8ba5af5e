"""Salvage of MCAP files that were never closed: read what is there, write a complete file.

As the mcap CLI's `recover`: scan the records linearly without trusting the (missing) summary,
open every chunk, and re-write schemas, channels, messages, metadata and attachments through a
fresh writer, which rebuilds chunks, message indexes, statistics and the summary. The scan
stops where the file breaks off; a chunk cut in the middle still yields the messages that
decompress completely (zstd and lz4 decode block by block).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
import io
import os
from pathlib import Path
import struct

import lz4.frame
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.writer import Writer
import zstandard

from stealth_tools.bag_format import (
    COMPRESSIONS,
    DEFAULT_CHUNK_SIZE,
    MCAP_MAGIC,
    PROFILE,
    BagError,
    cut_before_header,
    resolve_bag_file,
)

RECORD_LENGTH_LIMIT = 1 << 30  # a longer top-level record means garbage, not data
_RECORD_HEAD = struct.Struct('<BQ')
_CHUNK_HEAD = struct.Struct('<QQQI')  # start, end, uncompressed size, uncompressed crc
_KEPT_RECORDS = {
    Opcode.HEADER: Header,
    Opcode.SCHEMA: Schema,
    Opcode.CHANNEL: Channel,
    Opcode.MESSAGE: Message,
    Opcode.METADATA: Metadata,
    Opcode.ATTACHMENT: Attachment,
}
_PARSE_ERRORS = (struct.error, McapError, UnicodeDecodeError, ValueError, EOFError)


@dataclass
class SalvageReport:
    """How a scan went: did it reach the end of the data section, and what was lost."""

    complete: bool = False
    reason: str = ''
    cut_chunk_records: int = 0
    discarded_chunks: int = 0


def _parse_record(opcode: int, body: bytes):
    """The mcap record object for a kept record type, None for indexes and summaries."""
    record_type = _KEPT_RECORDS.get(opcode)
    if record_type is None:
        return None
    stream = ReadDataStream(io.BytesIO(body))
    if record_type is Message:
        return Message.read(stream, len(body))
    return record_type.read(stream)


def _framed_records(buffer: bytes) -> Iterator[tuple[int, bytes]]:
    """(opcode, body) of every complete record in a buffer; stops at a cut one."""
    offset = 0
    while offset + _RECORD_HEAD.size <= len(buffer):
        opcode, length = _RECORD_HEAD.unpack_from(buffer, offset)
        start = offset + _RECORD_HEAD.size
        if start + length > len(buffer):
            return
        yield opcode, buffer[start : start + length]
        offset = start + length


def _decompress(data: bytes, compression: str, size: int, complete: bool) -> bytes:
    """A chunk's records; of a cut chunk, as much as decodes."""
    if compression == '':
        return data
    if compression == 'zstd':
        if complete:
            return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        return zstandard.ZstdDecompressor().decompressobj().decompress(data)
    if compression == 'lz4':
        if complete:
            return lz4.frame.decompress(data)
        return lz4.frame.LZ4FrameDecompressor().decompress(data)
    raise McapError(f'unsupported chunk compression {compression!r}')


def _chunk_records(body: bytes, complete: bool) -> bytes:
    """The (decompressed) record bytes inside a chunk record's body, possibly cut."""
    if len(body) < _CHUNK_HEAD.size + 4:
        return b''
    _, _, uncompressed_size, _ = _CHUNK_HEAD.unpack_from(body)
    (name_length,) = struct.unpack_from('<I', body, _CHUNK_HEAD.size)
    offset = _CHUNK_HEAD.size + 4
    compression = body[offset : offset + name_length].decode()
    offset += name_length
    if len(body) < offset + 8:
        return b''
    (records_length,) = struct.unpack_from('<Q', body, offset)
    data = body[offset + 8 : offset + 8 + records_length]
    return _decompress(data, compression, uncompressed_size, complete)


def salvage_records(stream, report: SalvageReport | None = None) -> Iterator:
    """Every header, schema, channel, message, metadata and attachment record, in file order."""
    report = report if report is not None else SalvageReport()
    if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
        raise BagError(f'{getattr(stream, "name", "input")} is not an MCAP file (bad magic)')
    while True:
        head = stream.read(_RECORD_HEAD.size)
        if len(head) < _RECORD_HEAD.size:
            report.reason = 'the file ends without a footer'
            return
        opcode, length = _RECORD_HEAD.unpack(head)
        if length > RECORD_LENGTH_LIMIT:
            report.reason = f'a record claims {length} bytes: the data is corrupt from here'
            return
        body = stream.read(length)
        complete = len(body) == length
        if opcode in (Opcode.DATA_END, Opcode.FOOTER) and complete:
            report.complete = True
            return
        if opcode == Opcode.CHUNK:
            yield from _salvage_chunk(body, complete, report)
        elif complete:
            try:
                record = _parse_record(opcode, body)
            except _PARSE_ERRORS as error:
                report.reason = f'unreadable record (opcode 0x{opcode:02x}): {error}'
                return
            if record is not None:
                yield record
        if not complete:
            report.reason = 'the file ends in the middle of a record'
            return


def _salvage_chunk(body: bytes, complete: bool, report: SalvageReport) -> Iterator:
    """The records of one chunk; a chunk that does not decode is skipped, not fatal."""
    try:
        inner = _chunk_records(body, complete)
    except (*_PARSE_ERRORS, zstandard.ZstdError, RuntimeError):
        report.discarded_chunks += 1
        return
    for opcode, record_body in _framed_records(inner):
        try:
            record = _parse_record(opcode, record_body)
        except _PARSE_ERRORS:
            report.discarded_chunks += 1
            return
        if record is not None:
            if not complete:
                report.cut_chunk_records += 1
            yield record


@dataclass
class RecoveryReport:
    """What `recover` wrote, and what it had to leave behind."""

    messages: int = 0
    channels: int = 0
    schemas: int = 0
    metadata: int = 0
    attachments: int = 0
    dropped_messages: int = 0
    first_log_time: int | None = None
    last_log_time: int | None = None
    salvage: SalvageReport | None = None

    def summary(self) -> str:
        """One line for the user."""
        salvage = self.salvage or SalvageReport()
        parts = [
            f'recovered {self.messages} messages on {self.channels} topics, '
            f'{self.metadata} metadata records, {self.attachments} attachments'
        ]
        if salvage.complete:
            parts.append('the input was complete')
        else:
            parts.append(f'the input was cut off ({salvage.reason})')
        if salvage.cut_chunk_records:
            parts.append(f'{salvage.cut_chunk_records} records came from a cut chunk')
        if salvage.discarded_chunks or self.dropped_messages:
            parts.append(
                f'lost {salvage.discarded_chunks} undecodable chunks and '
                f'{self.dropped_messages} messages of unknown channels'
            )
        return '; '.join(parts)


class _Rewriter:
    """Feeds salvaged records to a new writer, renumbering schemas and channels."""

    def __init__(self, writer: Writer):
        self.writer = writer
        self.started = False
        self.schema_ids: dict[int, int] = {0: 0}
        self.channel_ids: dict[int, int] = {}
        self.report = RecoveryReport()

    def start(self, profile: str) -> None:
        if not self.started:
            self.writer.start(profile=profile, library='stealth_tools bag recover')
            self.started = True

    def add(self, record) -> None:
        if isinstance(record, Header):
            self.start(record.profile)
            return
        self.start(PROFILE)
        if isinstance(record, Schema) and record.id not in self.schema_ids:
            self.schema_ids[record.id] = self.writer.register_schema(
                record.name, record.encoding, record.data
            )
            self.report.schemas += 1
        elif isinstance(record, Channel) and record.id not in self.channel_ids:
            self.channel_ids[record.id] = self.writer.register_channel(
                record.topic,
                record.message_encoding,
                self.schema_ids.get(record.schema_id, 0),
                dict(record.metadata),
            )
            self.report.channels += 1
        elif isinstance(record, Message):
            self._add_message(record)
        elif isinstance(record, Metadata):
            self.writer.add_metadata(record.name, dict(record.metadata))
            self.report.metadata += 1
        elif isinstance(record, Attachment):
            self.writer.add_attachment(
                record.create_time, record.log_time, record.name, record.media_type, record.data
            )
            self.report.attachments += 1

    def _add_message(self, message: Message) -> None:
        channel_id = self.channel_ids.get(message.channel_id)
        if channel_id is None:
            self.report.dropped_messages += 1
            return
        self.writer.add_message(
            channel_id,
            message.log_time,
            bytes(message.data),
            message.publish_time,
            message.sequence,
        )
        report = self.report
        report.messages += 1
        first = report.first_log_time
        report.first_log_time = message.log_time if first is None else min(first, message.log_time)
        report.last_log_time = max(report.last_log_time or 0, message.log_time)


def default_recovered_path(source: Path) -> Path:
    """run.mcap -> run.recovered.mcap, next to the input."""
    return source.with_name(f'{source.stem}.recovered.mcap')


def recover(
    source: str | os.PathLike,
    output: str | os.PathLike | None = None,
    *,
    compression: str = 'zstd',
    chunk_size: int = DEFAULT_CHUNK_SIZE,
) -> tuple[Path, RecoveryReport]:
    """Write a complete, indexed copy of everything salvageable in `source`."""
    if compression not in COMPRESSIONS:
        raise BagError(f"unknown compression '{compression}' (choose from zstd, lz4, none)")
    source_path = resolve_bag_file(source)
    if empty := cut_before_header(source_path):
        raise BagError(empty)
    output_path = Path(output) if output else default_recovered_path(source_path)
    if output_path.exists():
        raise BagError(f'{output_path} already exists; choose another output with -o')
    salvage = SalvageReport()
    try:
        with open(source_path, 'rb') as src, open(output_path, 'xb') as dst:
            rewriter = _Rewriter(
                Writer(dst, chunk_size=chunk_size, compression=COMPRESSIONS[compression])
            )
            for record in salvage_records(src, salvage):
                rewriter.add(record)
            if not rewriter.started:
                raise BagError(f'{source_path}: nothing to recover (no MCAP header)')
            rewriter.writer.finish()
    except OSError as error:
        output_path.unlink(missing_ok=True)
        raise BagError(f'cannot recover into {output_path}: {error.strerror or error}') from None
    except BaseException:
        output_path.unlink(missing_ok=True)
        raise
    rewriter.report.salvage = salvage
    return output_path, rewriter.report
