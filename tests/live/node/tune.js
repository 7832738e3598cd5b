// Change parameters of a running graph as a Foxglove viewer does, with @foxglove/ws-protocol:
// get every parameter, subscribe to JSON TOPICs, then send each change of CHANGES at its time.
// Usage: node tune.js URL SECONDS TOPIC,TOPIC CHANGES_JSON -> one JSON line on stdout, 1.5 s
// after every change was answered (at most SECONDS after the start):
// {parameters: {name: value}, answers: {id: [{name, value}]}, statuses: [{level, message}],
//  samples: {topic: [[receiptMs, message], ...]}}
// CHANGES_JSON: [{"at": seconds after the first parameters arrived, "name": ..., "value": ...}]
"use strict";
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const [url, seconds, topics, changes] = [
  process.argv[2],
  Number(process.argv[3]),
  new Set(process.argv[4].split(",")),
  JSON.parse(process.argv[5]),
];
const client = new FoxgloveClient({ ws: new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]) });
const out = { parameters: null, answers: {}, statuses: [], samples: {} };
const topicOf = new Map();
const text = new TextDecoder();

client.on("serverInfo", () => client.getParameters([], "all"));
client.on("parameterValues", (event) => {
  if (event.id === "all" && out.parameters === null) {
    out.parameters = Object.fromEntries(event.parameters.map((p) => [p.name, p.value]));
    changes.forEach((change, i) => {
      setTimeout(() => client.setParameters([{ name: change.name, value: change.value }], `set${i}`), change.at * 1000);
    });
  } else if (event.id) {
    out.answers[event.id] = event.parameters.map((p) => ({ name: p.name, value: p.value }));
    if (Object.keys(out.answers).length === changes.length) setTimeout(finish, 1500);
  }
});
client.on("status", (status) => out.statuses.push({ level: status.level, message: status.message }));
client.on("advertise", (channels) => {
  for (const channel of channels) {
    if (!topics.has(channel.topic) || channel.encoding !== "json") continue;
    topicOf.set(client.subscribe(channel.id), channel.topic);
    out.samples[channel.topic] = [];
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const topic = topicOf.get(subscriptionId);
  if (topic === undefined) return;
  const bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
  out.samples[topic].push([Date.now(), JSON.parse(text.decode(bytes))]);
});
client.on("error", (err) => {
  out.error = String(err && err.message ? err.message : err);
});
// the report: 1.5 s after the last change was answered (samples after it), or at SECONDS
function finish() {
  client.close();
  process.stdout.write(JSON.stringify(out) + "\n", () => process.exit(0));
}
setTimeout(finish, seconds * 1000);
