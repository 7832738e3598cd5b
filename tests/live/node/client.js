// Subscribe to every channel a Foxglove WebSocket server advertises and decode each message with
// the channel's own schema: protobuf from its FileDescriptorSet (protobufjs), JSON with JSON.parse.
// Usage: node client.js URL SECONDS [SUBPROTOCOL [TOPIC,TOPIC...]] -> one JSON line on stdout
// (with TOPICs: only those channels, as a viewer subscribes to what its panels show):
// {serverInfo, channels: {topic: {schemaName, encoding}}, topics: {topic: {count, errors, first,
//  receiptMs: [...] (wall clock), logTimeNs: [...], stampNs: [...] (the message's own timestamp)}},
//  parameters, triedSet, afterSet}
"use strict";
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");
const protobuf = require("protobufjs");
const descriptor = require("protobufjs/ext/descriptor");

const [url, seconds, subprotocol] = [process.argv[2], Number(process.argv[3]), process.argv[4]];
const only = process.argv[5] ? new Set(process.argv[5].split(",")) : null;
const ws = new WebSocket(url, [subprotocol || FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const out = { serverInfo: null, channels: {}, topics: {}, parameters: null, afterSet: null };
const decoders = new Map(); // subscription id -> {topic, decode}

function decoderFor(channel) {
  if (channel.encoding === "json") {
    const text = new TextDecoder();
    return (data, _plain) => JSON.parse(text.decode(data));
  }
  if (channel.encoding === "protobuf") {
    const bytes = Buffer.from(channel.schema, "base64");
    const set = descriptor.FileDescriptorSet.decode(bytes);
    const root = protobuf.Root.fromDescriptor(set);
    const type = root.lookupType(channel.schemaName);
    // decoded every time; turned into a plain object (bytes as base64) only for the first
    return (data, plain) => {
      const msg = type.decode(data);
      return plain ? type.toObject(msg, { longs: String, bytes: String, defaults: true }) : msg;
    };
  }
  throw new Error(`no decoder for ${channel.encoding}`);
}

client.on("serverInfo", (info) => {
  out.serverInfo = info;
  client.getParameters([], "all");
});
client.on("parameterValues", (event) => {
  if (event.id === "all") {
    out.parameters = event.parameters.length;
    // a hostile client tries to change a parameter: the values must come back unchanged
    const first = event.parameters.find((p) => typeof p.value === "number");
    if (first) {
      out.triedSet = { name: first.name, value: first.value };
      client.setParameters([{ name: first.name, value: first.value + 1000 }], "set");
    }
  } else if (event.id === "set") {
    out.afterSet = event.parameters.map((p) => ({ name: p.name, value: p.value }));
  }
});
client.on("advertise", (channels) => {
  for (const channel of channels) {
    out.channels[channel.topic] = { schemaName: channel.schemaName, encoding: channel.encoding };
    if (only && !only.has(channel.topic)) continue;
    let decode;
    try {
      decode = decoderFor(channel);
    } catch (err) {
      out.topics[channel.topic] = { count: 0, errors: 1, error: String(err) };
      continue;
    }
    const id = client.subscribe(channel.id);
    decoders.set(id, { topic: channel.topic, decode });
  }
});
const { performance } = require("perf_hooks");
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const receipt = performance.timeOrigin + performance.now(); // wall-clock ms, sub-ms resolution
  const entry = decoders.get(subscriptionId);
  if (!entry) return;
  const t = (out.topics[entry.topic] ||= {
    count: 0,
    errors: 0,
    receiptMs: [],
    logTimeNs: [],
    stampNs: [],
  });
  try {
    const msg = entry.decode(new Uint8Array(data.buffer, data.byteOffset, data.byteLength), !t.first);
    t.count += 1;
    t.receiptMs.push(receipt);
    t.logTimeNs.push(String(timestamp));
    const ts = msg.timestamp; // a Foxglove message's own time: the sample's stamp (wall clock)
    t.stampNs.push(ts ? String(BigInt(String(ts.seconds)) * 1000000000n + BigInt(ts.nanos)) : null);
    if (!t.first) {
      if (msg.data && typeof msg.data === "string" && msg.data.length > 64) msg.data = `<${msg.data.length} b64>`;
      t.first = msg;
    }
  } catch (err) {
    t.errors += 1;
    t.error = String(err);
  }
});
client.on("error", (err) => {
  out.error = String(err && err.message ? err.message : err);
});
setTimeout(() => {
  client.close();
  // a pipe takes the report in pieces: exit once it is all written
  process.stdout.write(JSON.stringify(out) + "\n", () => process.exit(0));
}, seconds * 1000);
