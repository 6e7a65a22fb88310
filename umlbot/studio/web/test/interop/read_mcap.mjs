// An independent reader of umlbot's recordings (tests/test_record_interop.py runs it):
// Foxglove's own npm packages, no umlbot code. Reads the MCAP file given as the argument with
// @mcap/core's stream reader, decodes every CDR message with @foxglove/rosmsg2-serialization from
// the ros2msg schema the file carries, and prints one JSON object: the file's profile, per topic
// its schema and count, and the decoded messages of the topics named by the following arguments.

import { readFileSync } from "node:fs";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { McapStreamReader } from "@mcap/core";

const [file, ...wanted] = process.argv.slice(2);
const reader = new McapStreamReader({ validateCrcs: true });
reader.append(readFileSync(file));

const schemas = new Map();
const channels = new Map();
const topics = {};
const decoded = {};
let profile = null;
let metadata = {};
for (let record = reader.nextRecord(); record !== undefined; record = reader.nextRecord()) {
  if (record.type === "Header") {
    profile = record.profile;
  } else if (record.type === "Schema") {
    const text = new TextDecoder().decode(record.data);
    schemas.set(record.id, {
      name: record.name,
      encoding: record.encoding,
      reader: new MessageReader(parse(text, { ros2: true })),
    });
  } else if (record.type === "Channel") {
    channels.set(record.id, record);
  } else if (record.type === "Metadata") {
    metadata = { ...metadata, [record.name]: Object.fromEntries(record.metadata) };
  } else if (record.type === "Message") {
    const channel = channels.get(record.channelId);
    const schema = schemas.get(channel.schemaId);
    topics[channel.topic] = topics[channel.topic] ?? { schema: schema.name, encoding: schema.encoding, count: 0 };
    const entry = topics[channel.topic];
    entry.count += 1;
    const message = schema.reader.readMessage(record.data); // decodes every message: a bad one throws
    if (wanted.includes(channel.topic)) {
      decoded[channel.topic] = decoded[channel.topic] ?? [];
      decoded[channel.topic].push({ log_time_ns: record.logTime.toString(), message });
    }
  }
}
const json = JSON.stringify({ profile, done: reader.done(), topics, decoded, metadata }, (_key, value) =>
  typeof value === "bigint" ? value.toString() : value instanceof Uint8Array ? Array.from(value) : value,
);
process.stdout.write(`${json}\n`);
