#!/usr/bin/env node
// Third-party check of our MCAP recordings: opens FILE with @mcap/core, the library Foxglove and
// most MCAP tools use, and decodes EVERY message from its channel's schema: an omgidl schema with
// the Foxglove OMG IDL parser and CDR reader, a ros2msg schema (the ros2 profile) with Foxglove's
// ROS 2 message parser and CDR reader. Our own reader cannot prove the files are valid MCAP; this can.
//
//   node read_mcap.mjs FILE [--expect-topic TOPIC ...] [--min-messages N] [--allow-truncated]
//                           [--print-first TOPIC ...]
//
// A closed file is read through McapIndexedReader (footer, summary, chunk and message indexes,
// CRCs); with --allow-truncated through McapStreamReader, front to back, as far as it is whole.
// Prints one JSON line: {"messages":N,"topics":{"/pmlsm/x":count,...},"errors":[...]} and, with
// --print-first, "first":{TOPIC: decoded message} (64-bit integers as numbers when exact, else
// strings; typed arrays as arrays). Exits 1 on any read or decode error, a missing expected topic
// or too few messages; 2 on a usage error.

import { readFile } from "node:fs/promises";
import { McapStreamReader } from "@mcap/core";
import { parseIDL } from "@foxglove/omgidl-parser";
import { MessageReader } from "@foxglove/omgidl-serialization";
import { parse as parseRosMsg } from "@foxglove/rosmsg";
import { MessageReader as Ros2MessageReader } from "@foxglove/rosmsg2-serialization";
import { decompressHandlers, withIndexedReader } from "./mcap_file.mjs";

const USAGE =
  "usage: node read_mcap.mjs FILE [--expect-topic TOPIC ...] [--min-messages N] [--allow-truncated] " +
  "[--print-first TOPIC ...]";
// Enough to diagnose; a file where every message fails must not print megabytes.
const MAX_LISTED_ERRORS = 20;

function parseArguments(argv) {
  const options = { file: undefined, expectTopics: [], minMessages: 0, allowTruncated: false, printFirst: [] };
  for (let i = 0; i < argv.length; ++i) {
    const argument = argv[i];
    const value = () => {
      if (i + 1 >= argv.length) throw new Error(`${argument} needs a value`);
      return argv[++i];
    };
    if (argument === "--expect-topic") {
      options.expectTopics.push(value());
    } else if (argument === "--min-messages") {
      const text = value();
      options.minMessages = Number(text);
      if (!Number.isInteger(options.minMessages) || options.minMessages < 0) {
        throw new Error(`--min-messages needs a non-negative integer, got '${text}'`);
      }
    } else if (argument === "--allow-truncated") {
      options.allowTruncated = true;
    } else if (argument === "--print-first") {
      options.printFirst.push(value());
    } else if (argument.startsWith("--")) {
      throw new Error(`unknown option ${argument}`);
    } else if (options.file === undefined) {
      options.file = argument;
    } else {
      throw new Error(`more than one file: '${options.file}' and '${argument}'`);
    }
  }
  if (options.file === undefined) throw new Error("no FILE given");
  return options;
}

// For JSON: bigint (uint64/int64 fields) as a number when exact, else a decimal string; typed
// arrays (sequences of numbers) as plain arrays.
function jsonSafe(_key, value) {
  if (typeof value === "bigint") {
    return Number.isSafeInteger(Number(value)) ? Number(value) : value.toString();
  }
  if (ArrayBuffer.isView(value) && !(value instanceof DataView)) {
    return Array.from(value, (element) => jsonSafe("", element));
  }
  return value;
}

class Checker {
  constructor(options) {
    this.options = options;
    this.schemas = new Map(); // id -> Schema record
    this.channels = new Map(); // id -> Channel record
    this.decoders = new Map(); // channel id -> MessageReader, or an Error when it cannot be built
    this.messages = 0;
    this.topics = {};
    this.first = {};
    this.errors = [];
    this.unlistedErrors = 0;
  }

  error(text) {
    if (this.errors.length < MAX_LISTED_ERRORS) {
      this.errors.push(text);
    } else {
      ++this.unlistedErrors;
    }
  }

  decoderFor(channelId) {
    if (this.decoders.has(channelId)) return this.decoders.get(channelId);
    let decoder;
    try {
      const channel = this.channels.get(channelId);
      if (channel === undefined) throw new Error(`channel ${channelId} has no Channel record`);
      if (channel.messageEncoding !== "cdr") {
        throw new Error(`channel ${channel.topic}: message encoding '${channel.messageEncoding}', not 'cdr'`);
      }
      const schema = this.schemas.get(channel.schemaId);
      if (schema === undefined) throw new Error(`channel ${channel.topic}: schema ${channel.schemaId} is missing`);
      const text = new TextDecoder().decode(schema.data);
      if (schema.encoding === "omgidl") {
        decoder = new MessageReader(schema.name, parseIDL(text));
      } else if (schema.encoding === "ros2msg") {
        // MCAP's ros2 profile: the .msg definition with its dependencies, as rosbag2 writes it.
        decoder = new Ros2MessageReader(parseRosMsg(text, { ros2: true }));
      } else {
        throw new Error(`schema ${schema.name}: encoding '${schema.encoding}', not 'omgidl' or 'ros2msg'`);
      }
    } catch (error) {
      decoder = new Error(`cannot build a decoder for channel ${channelId}: ${error.message}`);
      this.error(decoder.message);
    }
    this.decoders.set(channelId, decoder);
    return decoder;
  }

  onMessage(message) {
    ++this.messages;
    const channel = this.channels.get(message.channelId);
    const topic = channel?.topic ?? `(channel ${message.channelId})`;
    this.topics[topic] = (this.topics[topic] ?? 0) + 1;
    const decoder = this.decoderFor(message.channelId);
    if (decoder instanceof Error) return; // reported once, when building it failed
    try {
      const decoded = decoder.readMessage(message.data);
      if (decoded === undefined || decoded === null) throw new Error("decoded to nothing");
      if (this.options.printFirst.includes(topic) && !(topic in this.first)) this.first[topic] = decoded;
    } catch (error) {
      this.error(`${topic} message sequence ${message.sequence}: ${error.message}`);
    }
  }

  async readIndexed(file) {
    await withIndexedReader(file, async (reader) => {
      for (const [id, schema] of reader.schemasById) this.schemas.set(id, schema);
      for (const [id, channel] of reader.channelsById) this.channels.set(id, channel);
      for await (const message of reader.readMessages({ validateCrcs: true })) this.onMessage(message);
      const counted = reader.statistics?.messageCount;
      if (counted !== undefined && counted !== BigInt(this.messages)) {
        this.error(`the Statistics record counts ${counted} messages, the indexes gave ${this.messages}`);
      }
    });
  }

  async readStream(file) {
    const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
    stream.append(await readFile(file));
    for (let record; (record = stream.nextRecord()); ) {
      if (record.type === "Schema") {
        this.schemas.set(record.id, record);
      } else if (record.type === "Channel") {
        this.channels.set(record.id, record);
      } else if (record.type === "Message") {
        this.onMessage(record);
      }
    }
  }

  result() {
    for (const topic of this.options.expectTopics) {
      if (!(topic in this.topics)) this.error(`expected topic ${topic} has no messages`);
    }
    if (this.messages < this.options.minMessages) {
      this.error(`${this.messages} messages, fewer than the expected ${this.options.minMessages}`);
    }
    for (const topic of this.options.printFirst) {
      if (!(topic in this.first) && topic in this.topics) this.error(`no decoded message of ${topic} to print`);
    }
    const errors = [...this.errors];
    if (this.unlistedErrors > 0) errors.push(`... and ${this.unlistedErrors} further errors`);
    const output = { messages: this.messages, topics: this.topics, errors };
    if (this.options.printFirst.length > 0) output.first = this.first;
    return output;
  }
}

async function main() {
  let options;
  try {
    options = parseArguments(process.argv.slice(2));
  } catch (error) {
    console.error(`read_mcap: ${error.message}\n${USAGE}`);
    return 2;
  }
  const checker = new Checker(options);
  try {
    if (options.allowTruncated) {
      await checker.readStream(options.file);
    } else {
      await checker.readIndexed(options.file);
    }
  } catch (error) {
    checker.error(`reading ${options.file}: ${error.message}`);
  }
  const output = checker.result();
  console.log(JSON.stringify(output, jsonSafe));
  return output.errors.length > 0 ? 1 : 0;
}

process.exitCode = await main();
