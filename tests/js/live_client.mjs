// Connects the official Foxglove WebSocket client (@foxglove/ws-protocol) to a live fleet-emu run, subscribes to
// every channel it advertises, decodes each message with the channel's own schema (protobuf descriptors through
// protobufjs, JSON as is) and, once the server closes the connection (the run ended) or after TIMEOUT seconds,
// prints `connected` once the server greeted it, then one JSON summary on stdout: the channels, and per topic the messages seen and a few decoded fields.
// usage: node live_client.mjs ws://HOST:PORT [TIMEOUT]
import wsProtocol from "@foxglove/ws-protocol";
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [url, timeout = "60"] = process.argv.slice(2);
const channels = new Map(); // channel id -> {topic, schemaName, encoding, decode}
const bySub = new Map(); // subscription id -> channel id
const topics = {}; // topic -> {count, first, last, ...}
let serverInfo = null;

function decoder(ch) {
  if (ch.encoding === "json") {
    return (data) => JSON.parse(new TextDecoder().decode(data));
  }
  if (ch.encoding === "protobuf") {
    const set = descriptor.FileDescriptorSet.decode(Buffer.from(ch.schema, "base64"));
    const type = protobuf.Root.fromDescriptor(set).lookupType(ch.schemaName);
    return (data) => type.toObject(type.decode(data), { longs: Number, bytes: Array });
  }
  throw new Error(`unexpected encoding ${ch.encoding} on ${ch.topic}`);
}

// a protobuf Timestamp (protobufjs: {seconds, nanos}) or a JSON one ({sec, nsec}), in whole seconds
const seconds = (t) => (t ? Number(t.seconds ?? t.sec ?? 0) : null);

function summary(msg) {
  // the fields the test checks, per schema (protobufjs names the fields in camelCase)
  if (msg.tick !== undefined) {
    return { tick: msg.tick, coverage: msg.coverage, robots: Object.keys(msg.robots ?? {}), sec: seconds(msg.timestamp) };
  }
  if (msg.columnCount !== undefined) {
    return { column_count: msg.columnCount, bytes: msg.data.length, cell_stride: msg.cellStride, sec: seconds(msg.timestamp) };
  }
  if (msg.entities !== undefined) {
    return { entities: msg.entities.map((e) => e.id), sec: seconds(msg.entities[0]?.timestamp) };
  }
  if (msg.message !== undefined) return { message: msg.message, level: msg.level, sec: seconds(msg.timestamp) };
  return {};
}

// the SDK's server speaks the ws-protocol spec under the subprotocol name "foxglove.sdk.v1" (as the Foxglove app
// and the SDK's own clients ask for it); the client takes any compatible subprotocol
const client = new FoxgloveClient({ ws: new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]) });
const done = (why) => {
  const out = { why, serverInfo, channels: [...channels.values()].map(({ decode, ...c }) => c), topics };
  process.stdout.write(JSON.stringify(out) + "\n");
  process.exit(0);
};
client.on("serverInfo", (info) => {
  serverInfo = { name: info.name, capabilities: info.capabilities };
  process.stdout.write("connected\n"); // a test may hold its run's start until here
});
client.on("advertise", (list) => {
  for (const ch of list) {
    channels.set(ch.id, { topic: ch.topic, schemaName: ch.schemaName, encoding: ch.encoding,
                          schemaEncoding: ch.schemaEncoding, decode: decoder(ch) });
    bySub.set(client.subscribe(ch.id), ch.id);
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const ch = channels.get(bySub.get(subscriptionId));
  let msg;
  try {
    msg = ch.decode(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
  } catch (err) {
    process.stderr.write(`cannot decode a message on ${ch.topic}: ${err}\n`);
    (topics[ch.topic] ??= { count: 0, first: null, last: null }).errors = String(err);
    return;
  }
  const t = (topics[ch.topic] ??= { count: 0, first: null, last: null });
  t.count += 1;
  t.first ??= summary(msg);
  t.last = summary(msg);
});
client.on("error", (err) => { process.stderr.write(`client error: ${err}\n`); });
client.on("close", (ev) => done(`closed ${ev?.code ?? ""}`));
setTimeout(() => done("timeout"), Number(timeout) * 1000);
