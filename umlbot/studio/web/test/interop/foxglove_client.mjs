// An independent client of `umlbot sim --foxglove` (tests/test_record_foxglove.py runs it):
// Foxglove's own @foxglove/ws-protocol client, opened with the subprotocol foxglove-sdk's server
// accepts (foxglove.sdk.v1), subscribes to every channel advertised for the given milliseconds,
// decodes each message (CDR with @foxglove/rosmsg2-serialization from the ros2msg schema,
// protobuf with protobufjs from the FileDescriptorSet the channel carries) and prints one JSON
// object: the channels, the messages per topic, and the decoded messages of the topics named.

import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import wsProtocol from "@foxglove/ws-protocol";
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol; // a CommonJS package
const [url, millis, ...wanted] = process.argv.slice(2);
const client = new FoxgloveClient({ ws: new WebSocket(url, ["foxglove.sdk.v1"]) });
const channels = [];
const decoders = new Map(); // subscription id -> { topic, decode }
const counts = {};
const decoded = {};
const errors = [];

function decoderFor(channel) {
  if (channel.encoding === "cdr" && channel.schemaEncoding === "ros2msg") {
    const reader = new MessageReader(parse(channel.schema, { ros2: true }));
    return (bytes) => reader.readMessage(bytes);
  }
  if (channel.encoding === "protobuf") {
    const set = descriptor.FileDescriptorSet.decode(Buffer.from(channel.schema, "base64"));
    const type = protobuf.Root.fromDescriptor(set).lookupType(channel.schemaName);
    return (bytes) => type.toObject(type.decode(bytes), { longs: String, defaults: true });
  }
  if (channel.encoding === "json") {
    return (bytes) => JSON.parse(new TextDecoder().decode(bytes));
  }
  throw new Error(`no decoder for ${channel.topic}: ${channel.encoding}/${channel.schemaEncoding}`);
}

client.on("advertise", (advertised) => {
  for (const channel of advertised) {
    channels.push({ topic: channel.topic, encoding: channel.encoding, schemaName: channel.schemaName });
    try {
      decoders.set(client.subscribe(channel.id), { topic: channel.topic, decode: decoderFor(channel) });
    } catch (error) {
      errors.push(String(error));
    }
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const entry = decoders.get(subscriptionId);
  if (entry === undefined) return;
  counts[entry.topic] = (counts[entry.topic] ?? 0) + 1;
  try {
    const bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
    const message = entry.decode(bytes);
    if (wanted.includes(entry.topic)) {
      decoded[entry.topic] = decoded[entry.topic] ?? [];
      decoded[entry.topic].push(message);
    }
  } catch (error) {
    errors.push(`${entry.topic}: ${error}`);
  }
});
client.on("error", (error) => errors.push(`connection: ${error?.message ?? error}`));

// Listens at least `millis`, and on until each wanted topic has brought 10 messages (a loaded
// machine starts the run late), at most 60 s.
const started = Date.now();
function finish() {
  const waiting = wanted.some((topic) => (counts[topic] ?? 0) < 10);
  if (waiting && Date.now() - started < 60000) {
    setTimeout(finish, 250);
    return;
  }
  client.close();
  const json = JSON.stringify({ channels, counts, decoded, errors }, (_key, value) =>
    typeof value === "bigint" ? value.toString() : value,
  );
  process.stdout.write(`${json}\n`, () => process.exit(0)); // a pipe takes it in parts: wait for all
}
setTimeout(finish, Number(millis));
