// The ws-protocol reference client (npm @foxglove/ws-protocol) against forcemap's live view.
// usage: node client.mjs ws://127.0.0.1:PORT [SUBPROTOCOL] [TIMEOUT_S]
// Subscribes to every advertised channel, decodes each message's JSON, and prints one JSON line:
// the subprotocol the server agreed, the messages per topic, and the decoding errors. It ends when
// it has /fix and every /map/<target>, or at the timeout.
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [url, protocol = FoxgloveClient.SUPPORTED_SUBPROTOCOL, timeoutS = "600"] = process.argv.slice(2);
const WANTED = ["/fix", "/map/current", "/map/wind", "/map/depth"];
const ws = new WebSocket(url, [protocol]);
const client = new FoxgloveClient({ ws });
const channels = new Map();
const counts = {};
const errors = [];
let serverInfo = null;
let subscription = 0;

function finish(code) {
  console.log(JSON.stringify({ offered: protocol, agreed: ws.protocol, serverInfo, counts, errors: errors.slice(0, 5) }));
  client.close();
  process.exit(code);
}

client.on("open", () => console.error(`connected, subprotocol ${ws.protocol}`));
client.on("serverInfo", (info) => (serverInfo = info.name));
client.on("error", (err) => errors.push(String(err?.message ?? err)));
client.on("close", () => finish(1));
client.on("advertise", (advertised) => {
  for (const ch of advertised) {
    channels.set(ch.id, ch);
    const id = client.subscribe(ch.id);
    channels.set(`sub${id}`, ch);
    subscription += 1;
  }
});
const decoder = new TextDecoder();
client.on("message", ({ subscriptionId, data }) => {
  const ch = channels.get(`sub${subscriptionId}`);
  const topic = ch ? ch.topic : `?${subscriptionId}`;
  try {
    JSON.parse(decoder.decode(data));
  } catch (err) {
    errors.push(`${topic}: ${err.message}`);
  }
  counts[topic] = (counts[topic] ?? 0) + 1;
  if (WANTED.every((t) => counts[t] > 0)) finish(0);
});
setTimeout(() => finish(2), Number(timeoutS) * 1000);
