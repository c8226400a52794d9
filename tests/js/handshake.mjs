// Opens a WebSocket to a live fleet-emu run asking for one subprotocol, as a viewer would, and prints one JSON line:
// the subprotocol the server chose, or the HTTP status it refused the handshake with.
// usage: node handshake.mjs ws://HOST:PORT SUBPROTOCOL
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;
const [url, subprotocol] = process.argv.slice(2);
const done = (out) => { process.stdout.write(JSON.stringify(out) + "\n"); process.exit(0); };
// the call the watching guide shows, with the subprotocol given
const ws = new WebSocket(url, [subprotocol]);
const client = new FoxgloveClient({ ws });
ws.on("unexpected-response", (_req, res) => done({ status: res.statusCode }));
client.on("error", (err) => done({ error: String(err?.message ?? err) }));
client.on("serverInfo", (info) => done({ protocol: ws.protocol, server: info.name }));
setTimeout(() => done({ error: "timeout" }), 20000);
