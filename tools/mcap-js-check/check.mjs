#!/usr/bin/env node
// Reads an MCAP recording the way Foxglove Studio does and reports what it found.
//
//   node tools/mcap-js-check/check.mjs FILE.mcap [--samples]
//
// With Foxglove's own libraries: @mcap/core's indexed reader (footer, summary, summary offsets,
// chunk and message indexes; CRCs checked) and its stream reader (every record in file order,
// CRCs checked), with @mcap/support's decompressors (the WebAssembly zstd/lz4 Foxglove uses);
// @foxglove/rosmsg parses every ros2msg schema text; @foxglove/rosmsg2-serialization decodes
// every message's CDR from nothing but that text. Prints one JSON object (per topic: schema
// name, message count, decode errors; with --samples also the first and last decoded message)
// and exits 1 if anything is wrong, 2 on bad usage.

import { open } from 'node:fs/promises';
import { McapIndexedReader, McapStreamReader } from '@mcap/core';
import { FileHandleReadable } from '@mcap/nodejs';
import { loadDecompressHandlers } from '@mcap/support';
import { parse } from '@foxglove/rosmsg';
import { MessageReader } from '@foxglove/rosmsg2-serialization';
import { plain } from '../shared/plain.mjs';

const STREAM_READ_SIZE = 1 << 20;
const MAX_PROBLEMS = 50;

function usage() {
  process.stderr.write('usage: check.mjs FILE.mcap [--samples]\n');
  process.exit(2);
}

class Report {
  constructor(file) {
    this.file = file;
    this.problems = [];
    this.topics = new Map();
  }

  problem(text) {
    if (this.problems.includes(text)) return; // both passes see the same fault
    if (this.problems.length < MAX_PROBLEMS) this.problems.push(text);
    else if (this.problems.length === MAX_PROBLEMS) this.problems.push('... (more problems)');
  }

  topic(channel) {
    if (!this.topics.has(channel.topic)) {
      this.topics.set(channel.topic, {
        schema: null,
        schema_encoding: null,
        message_encoding: channel.messageEncoding,
        count: 0,
        streamed_count: 0,
        decode_errors: 0,
        trailing_bytes: 0,
        end_padded: 0,
        first: undefined,
        last: undefined,
      });
    }
    return this.topics.get(channel.topic);
  }
}

// A decoder per channel, built as Foxglove Studio's parseChannel does for cdr + ros2msg.
function makeDecoder(report, channel, schema) {
  const entry = report.topic(channel);
  if (!schema) {
    report.problem(`${channel.topic}: channel ${channel.id} has no schema (id ${channel.schemaId})`);
    return null;
  }
  entry.schema = schema.name;
  entry.schema_encoding = schema.encoding;
  if (channel.messageEncoding !== 'cdr') {
    report.problem(`${channel.topic}: message encoding '${channel.messageEncoding}', not cdr`);
    return null;
  }
  if (schema.encoding !== 'ros2msg') {
    report.problem(`${channel.topic}: schema encoding '${schema.encoding}', not ros2msg`);
    return null;
  }
  if (!/^[A-Za-z0-9_]+\/msg\/[A-Za-z0-9_]+$/.test(schema.name)) {
    report.problem(`${channel.topic}: schema name '${schema.name}' is not pkg/msg/Type`);
  }
  if (!channel.metadata.has('offered_qos_profiles')) {
    report.problem(`${channel.topic}: channel metadata has no offered_qos_profiles`);
  }
  try {
    const definitions = parse(new TextDecoder().decode(schema.data), { ros2: true });
    return new MessageReader(definitions);
  } catch (error) {
    report.problem(`${channel.topic}: schema ${schema.name} does not parse: ${error.message}`);
    return null;
  }
}

// Fast CDR (rmw_fastrtps) pads a serialized message to a multiple of 4 bytes without noting it
// in the encapsulation options, so up to 3 bytes after the last field are normal ROS 2 data
// (rosbag2 records them the same); anything more means the schema does not match the data.
function isEndPadding(data, consumed) {
  const trailing = data.byteLength - consumed;
  return trailing > 0 && trailing < 4 && data.byteLength % 4 === 0;
}

// Decode one message; only the indexed pass (`counted`) adds to the per-topic numbers.
function decode(report, channel, reader, message, { counted, keepSamples }) {
  const entry = report.topic(channel);
  if (!reader) {
    if (counted) entry.decode_errors += 1;
    return;
  }
  try {
    const decoded = reader.readMessage(message.data);
    if (reader.lastReadHadTrailingBytes()) {
      const consumed = reader.lastReadByteLength();
      if (isEndPadding(message.data, consumed)) {
        if (counted) entry.end_padded += 1;
      } else {
        if (counted) entry.trailing_bytes += 1;
        report.problem(
          `${channel.topic}: message at ${message.logTime} has bytes after the decoded fields ` +
            `(${message.data.byteLength - consumed} of ${message.data.byteLength}): ` +
            'the schema does not match the data',
        );
      }
    }
    if (keepSamples) {
      if (entry.first === undefined) entry.first = plain(decoded);
      entry.last = plain(decoded);
    }
  } catch (error) {
    if (counted) entry.decode_errors += 1;
    report.problem(`${channel.topic}: message at ${message.logTime} does not decode: ${error}`);
  }
}

async function readIndexed(report, handle, decompressHandlers, keepSamples) {
  const reader = await McapIndexedReader.Initialize({
    readable: new FileHandleReadable(handle),
    decompressHandlers,
  });
  report.profile = reader.header.profile;
  report.library = reader.header.library;
  report.chunks = reader.chunkIndexes.length;
  if (reader.chunkIndexes.length === 0) report.problem('no chunk indexes in the summary');
  if (!reader.statistics) report.problem('no statistics record in the summary');
  const decoders = new Map();
  for (const channel of reader.channelsById.values()) {
    decoders.set(channel.id, makeDecoder(report, channel, reader.schemasById.get(channel.schemaId)));
  }
  const counts = new Map();
  let previous = -1n;
  for await (const message of reader.readMessages({ validateCrcs: true })) {
    const channel = reader.channelsById.get(message.channelId);
    if (!channel) {
      report.problem(`message on unknown channel ${message.channelId}`);
      continue;
    }
    if (message.logTime < previous) report.problem('indexed messages out of log-time order');
    previous = message.logTime;
    counts.set(channel.id, (counts.get(channel.id) ?? 0) + 1);
    report.topic(channel).count += 1;
    decode(report, channel, decoders.get(channel.id), message, { counted: true, keepSamples });
  }
  const statistics = reader.statistics;
  if (statistics) {
    const total = [...counts.values()].reduce((a, b) => a + b, 0);
    if (BigInt(total) !== statistics.messageCount) {
      report.problem(`statistics say ${statistics.messageCount} messages, index has ${total}`);
    }
    for (const [id, channel] of reader.channelsById) {
      const stated = statistics.channelMessageCounts.get(id) ?? 0n;
      if (stated !== BigInt(counts.get(id) ?? 0)) {
        report.problem(`${channel.topic}: statistics say ${stated}, index has ${counts.get(id)}`);
      }
    }
    report.message_start_time = statistics.messageStartTime.toString();
    report.message_end_time = statistics.messageEndTime.toString();
  }
  report.metadata = [];
  for await (const record of reader.readMetadata()) report.metadata.push(record.name);
  if (report.profile !== 'ros2') report.problem(`header profile '${report.profile}', not ros2`);
  return counts;
}

async function readStreamed(report, handle, decompressHandlers) {
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  const schemas = new Map();
  const channels = new Map();
  const decoders = new Map();
  const counts = new Map();
  let position = 0;
  const buffer = new Uint8Array(STREAM_READ_SIZE);
  let sawFooter = false;
  for (;;) {
    const { bytesRead } = await handle.read(buffer, 0, buffer.length, position);
    if (bytesRead === 0) break;
    position += bytesRead;
    stream.append(buffer.slice(0, bytesRead));
    for (let record; (record = stream.nextRecord()); ) {
      if (record.type === 'Schema') schemas.set(record.id, record);
      else if (record.type === 'Channel') {
        channels.set(record.id, record);
        decoders.set(record.id, makeDecoder(report, record, schemas.get(record.schemaId)));
      } else if (record.type === 'Message') {
        const channel = channels.get(record.channelId);
        if (!channel) {
          report.problem(`streamed message before its channel ${record.channelId}`);
          continue;
        }
        counts.set(channel.id, (counts.get(channel.id) ?? 0) + 1);
        report.topic(channel).streamed_count += 1;
        decode(report, channel, decoders.get(channel.id), record, { counted: false });
      } else if (record.type === 'Footer') sawFooter = true;
    }
  }
  if (!stream.done() || !sawFooter) report.problem('the stream reader did not reach the footer');
  return counts;
}

async function main() {
  const args = process.argv.slice(2);
  const keepSamples = args.includes('--samples');
  const files = args.filter((a) => a !== '--samples');
  if (files.length !== 1 || files[0].startsWith('-')) usage();
  const report = new Report(files[0]);
  const decompressHandlers = await loadDecompressHandlers();
  let handle;
  try {
    handle = await open(files[0], 'r');
  } catch (error) {
    process.stderr.write(`check.mjs: cannot open ${files[0]}: ${error.message}\n`);
    process.exit(1);
  }
  try {
    let indexed = new Map();
    try {
      indexed = await readIndexed(report, handle, decompressHandlers, keepSamples);
    } catch (error) {
      report.problem(`indexed reader: ${error.message}`);
    }
    let streamed = new Map();
    try {
      streamed = await readStreamed(report, handle, decompressHandlers);
    } catch (error) {
      report.problem(`stream reader: ${error.message}`);
    }
    for (const [topic, entry] of report.topics) {
      if (entry.count !== entry.streamed_count) {
        report.problem(`${topic}: ${entry.count} indexed, ${entry.streamed_count} streamed`);
      }
    }
    report.messages = [...indexed.values()].reduce((a, b) => a + b, 0);
    report.streamed_messages = [...streamed.values()].reduce((a, b) => a + b, 0);
  } finally {
    await handle.close();
  }
  const topics = Object.fromEntries(
    [...report.topics].map(([topic, entry]) => {
      if (!keepSamples) {
        delete entry.first;
        delete entry.last;
      }
      return [topic, entry];
    }),
  );
  const { problems, ...rest } = report;
  process.stdout.write(`${JSON.stringify({ ...rest, topics, ok: problems.length === 0, problems })}\n`);
  process.exit(problems.length === 0 ? 0 : 1);
}

main().catch((error) => {
  process.stderr.write(`check.mjs: ${error.stack ?? error}\n`);
  process.exit(1);
});
