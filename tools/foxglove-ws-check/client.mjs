#!/usr/bin/env node
// A Foxglove WebSocket client, as the Foxglove app connects to a live server, that reports what
// it received.
//
//   node tools/foxglove-ws-check/client.mjs ws://localhost:8765 --topics /map,/amcl_pose=5 \
//        [--min N] [--timeout S] [--samples FILE]
//
// It follows the protocol spec (github.com/foxglove/ws-protocol, docs/spec.md) on `ws`, with
// the subprotocol foxglove-sdk's server speaks (foxglove.sdk.v1; npm's @foxglove/ws-protocol
// 0.8.0 only offers foxglove.websocket.v1): serverInfo, advertise, subscribe, binary message
// data (opcode 1: uint32 subscription id, uint64 log time, payload) and time (opcode 2). Every
// advertised channel of the wanted topics must be `cdr` with a `ros2msg` schema; the schema text
// is parsed with @foxglove/rosmsg and every message decoded with
// @foxglove/rosmsg2-serialization from nothing but that text, as the Foxglove app does. It
// stops once every wanted topic has its messages (TOPIC=N: N, else --min, default 1) or at
// --timeout (default 60 s), prints one JSON object (server info; per topic: channel with its
// schema text, count, decode errors, first and last log time; the server times) and exits 0
// when every wanted topic got its messages without a problem, 1 otherwise, 2 on bad usage;
// SIGINT or SIGTERM ends it the same way with what arrived so far. --samples FILE writes the
// last decoded message of each topic.

import { writeFileSync } from 'node:fs';
import { parse } from '@foxglove/rosmsg';
import { MessageReader } from '@foxglove/rosmsg2-serialization';
import WebSocket from 'ws';
import { plain } from '../shared/plain.mjs';

const SUBPROTOCOL = 'foxglove.sdk.v1';
const OP_MESSAGE_DATA = 1;
const OP_TIME = 2;

function usage(text) {
  process.stderr.write(`client.mjs: ${text}\n`);
  process.stderr.write(
    'usage: client.mjs ws://HOST:PORT --topics T1,T2 [--min N] [--timeout S] [--samples FILE]\n',
  );
  process.exit(2);
}

function options(argv) {
  const result = { url: null, topics: [], min: 1, timeout: 60, samples: null };
  for (let i = 0; i < argv.length; i++) {
    const arg = argv[i];
    const value = () => argv[++i] ?? usage(`${arg} needs a value`);
    if (arg === '--topics') result.topics = value().split(',').filter(Boolean);
    else if (arg === '--min') result.min = Number(value());
    else if (arg === '--timeout') result.timeout = Number(value());
    else if (arg === '--samples') result.samples = value();
    else if (!result.url && arg.startsWith('ws')) result.url = arg;
    else usage(`unexpected argument ${arg}`);
  }
  if (!result.url || !result.topics.length) usage('give the server URL and --topics');
  if (!(result.min >= 1) || !(result.timeout > 0)) usage('--min and --timeout must be positive');
  return result;
}

const opts = options(process.argv.slice(2));
const report = { url: opts.url, server: null, topics: {}, times: 0, last_time: null, problems: [] };
const samples = {};
const bySubscription = new Map(); // subscription id -> { topic, reader }
let nextSubscription = 1;
let closing = false;
const wanted = {}; // topic -> messages to wait for
for (const item of opts.topics) {
  const [topic, count] = item.split('=');
  wanted[topic] = count === undefined ? opts.min : Number(count);
  if (!(wanted[topic] >= 1)) usage(`${item}: the count must be a positive number`);
  report.topics[topic] = { advertised: false, count: 0, decode_errors: 0, log_times: [] };
}

function problem(text) {
  if (!report.problems.includes(text) && report.problems.length < 50) report.problems.push(text);
}

function done() {
  return Object.entries(wanted).every(([t, n]) => report.topics[t].count >= n);
}

function finish(code) {
  if (opts.samples) writeFileSync(opts.samples, JSON.stringify(samples));
  for (const entry of Object.values(report.topics)) {
    entry.first_log_time = entry.log_times[0] ?? null;
    entry.last_log_time = entry.log_times.at(-1) ?? null;
    delete entry.log_times;
  }
  process.stdout.write(JSON.stringify(report, null, 1) + '\n');
  process.exit(code);
}

function advertise(socket, channels) {
  const subscriptions = [];
  for (const channel of channels) {
    const entry = report.topics[channel.topic];
    if (!entry || entry.advertised) continue;
    entry.advertised = true;
    entry.channel = {
      id: channel.id,
      encoding: channel.encoding,
      schemaName: channel.schemaName,
      schemaEncoding: channel.schemaEncoding,
      schema: channel.schema,
    };
    if (channel.encoding !== 'cdr' || channel.schemaEncoding !== 'ros2msg') {
      problem(`${channel.topic}: encoding ${channel.encoding}/${channel.schemaEncoding}`);
      continue;
    }
    let reader;
    try {
      reader = new MessageReader(parse(channel.schema, { ros2: true }));
    } catch (error) {
      problem(`${channel.topic}: schema does not parse: ${error.message}`);
      continue;
    }
    const id = nextSubscription++;
    bySubscription.set(id, { topic: channel.topic, reader });
    subscriptions.push({ id, channelId: channel.id });
  }
  if (subscriptions.length) socket.send(JSON.stringify({ op: 'subscribe', subscriptions }));
}

function binary(data) {
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const opcode = view.getUint8(0);
  if (opcode === OP_TIME) {
    report.times += 1;
    report.last_time = view.getBigUint64(1, true).toString();
    return;
  }
  if (opcode !== OP_MESSAGE_DATA) return;
  const subscription = bySubscription.get(view.getUint32(1, true));
  if (!subscription) {
    problem(`message for unknown subscription ${view.getUint32(1, true)}`);
    return;
  }
  const entry = report.topics[subscription.topic];
  entry.count += 1;
  entry.log_times.push(view.getBigUint64(5, true).toString());
  try {
    const message = subscription.reader.readMessage(data.subarray(13));
    samples[subscription.topic] = plain(message);
  } catch (error) {
    entry.decode_errors += 1;
    problem(`${subscription.topic}: message ${entry.count} does not decode: ${error.message}`);
  }
}

const socket = new WebSocket(opts.url, [SUBPROTOCOL]);
socket.binaryType = 'nodebuffer';
const timer = setTimeout(() => {
  problem(`timed out after ${opts.timeout} s`);
  finish(1);
}, opts.timeout * 1000);

// Stopped from outside (a bench measuring a window): report what arrived so far.
for (const signal of ['SIGINT', 'SIGTERM']) {
  process.on(signal, () => {
    clearTimeout(timer);
    finish(done() && report.problems.length === 0 ? 0 : 1);
  });
}

socket.on('error', (error) => {
  clearTimeout(timer);
  problem(`connection: ${error.message}`);
  finish(1);
});
socket.on('message', (data, isBinary) => {
  if (isBinary) {
    binary(data);
  } else {
    const message = JSON.parse(data.toString());
    if (message.op === 'serverInfo') {
      report.server = {
        name: message.name,
        capabilities: message.capabilities,
        supportedEncodings: message.supportedEncodings,
        subprotocol: socket.protocol,
      };
    } else if (message.op === 'advertise') {
      advertise(socket, message.channels);
    } else if (message.op === 'status' && message.level >= 1) {
      problem(`server status: ${message.message}`);
    }
  }
  if (!closing && done()) {
    closing = true;
    clearTimeout(timer);
    const clean = report.problems.length === 0;
    const decoded = Object.keys(wanted).every((t) => report.topics[t].decode_errors === 0);
    socket.on('close', () => finish(clean && decoded ? 0 : 1));
    socket.close(1000);
  }
});
