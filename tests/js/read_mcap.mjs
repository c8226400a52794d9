// Reads a fleet-emu run.mcap with the official MCAP reader (@mcap/core, zstd chunks through fzstd) and checks every
// JSON message against its channel's JSON schema (ajv, draft 2020-12). Prints one JSON summary on stdout: the
// scenario metadata, per topic its schema, message count and first/last log time, and the invalid messages.
// usage: node read_mcap.mjs PATH/run.mcap
import { McapIndexedReader } from "@mcap/core";
import Ajv2020 from "ajv/dist/2020.js";
import { decompress } from "fzstd";
import { open } from "node:fs/promises";

const path = process.argv[2];
const file = await open(path, "r");
const readable = {
  size: async () => BigInt((await file.stat()).size),
  read: async (offset, size) => {
    const buf = new Uint8Array(Number(size));
    await file.read(buf, 0, Number(size), Number(offset));
    return buf;
  },
};
const reader = await McapIndexedReader.Initialize({
  readable,
  decompressHandlers: { zstd: (buf, size) => decompress(buf, new Uint8Array(Number(size))) },
});
const ajv = new Ajv2020({ strict: false, allErrors: true });
const validators = new Map(); // schema id -> validate
const topics = {};
const invalid = [];
for await (const message of reader.readMessages()) {
  const channel = reader.channelsById.get(message.channelId);
  const t = (topics[channel.topic] ??= { encoding: channel.messageEncoding, schema: null, count: 0, first: null, last: null });
  t.count += 1;
  const time = Number(message.logTime);
  t.first ??= time;
  t.last = time;
  if (channel.messageEncoding !== "json") continue;
  const schema = reader.schemasById.get(channel.schemaId);
  t.schema = `${schema.name} (${schema.encoding})`;
  if (!validators.has(schema.id)) {
    validators.set(schema.id, ajv.compile(JSON.parse(new TextDecoder().decode(schema.data))));
  }
  const validate = validators.get(schema.id);
  const obj = JSON.parse(new TextDecoder().decode(message.data));
  if (!validate(obj) && invalid.length < 20) invalid.push({ topic: channel.topic, errors: validate.errors });
}
const metadata = {};
for await (const m of reader.readMetadata({ name: "scenario" })) Object.assign(metadata, Object.fromEntries(m.metadata));
delete metadata.scenario;
process.stdout.write(JSON.stringify({ metadata, topics, invalid }) + "\n");
await file.close();
