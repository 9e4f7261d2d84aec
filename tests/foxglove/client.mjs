// A Foxglove client for node/tests/integration/foxglove_client.rs, built only from Foxglove's
// own npm packages: the WebSocket protocol client of @foxglove/ws-protocol (on the `ws`
// WebSocket), and the message definitions of @foxglove/schemas, from which protobufjs decodes
// every protobuf message. Each message is also decoded with the schema the server advertised
// (its FileDescriptorSet), and the two decodings must agree.
//
// It subscribes to every channel advertised and prints one JSON line per event on stdout:
//   {"event":"subscribed","channels":[...]}          once every channel it saw is subscribed
//   {"event":"message","topic":...,"kind":...,...}   per message (clouds with their points)
//   {"event":"summary","received":{topic:count},"errors":[...]}  when stdin closes
// Modes (--mode): `read` reads everything; `stall` subscribes, then stops reading the socket
// (its TCP window fills and the server must drop for it) until stdin closes, then reads
// until nothing has come for --drain-ms and prints only the summary; `leave` disconnects
// after its first message.
//
// Usage: node client.mjs --url ws://127.0.0.1:PORT [--mode read|stall|leave] [--drain-ms 2000]

import { createHash } from "node:crypto";
import { parseArgs } from "node:util";

import wsProtocol from "@foxglove/ws-protocol";
import schemas from "@foxglove/schemas/internal.js";
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";
import WebSocket from "ws";

const { values: args } = parseArgs({
  options: {
    url: { type: "string" },
    mode: { type: "string", default: "read" },
    "drain-ms": { type: "string", default: "2000" },
  },
});
const mode = args.mode;
const { FoxgloveClient } = wsProtocol;
const { foxgloveEnumSchemas, foxgloveMessageSchemas, generateProto } = schemas;

// Every Foxglove schema, from @foxglove/schemas' own definitions, in one protobufjs root.
function foxgloveRoot() {
  const root = new protobuf.Root();
  for (const file of ["google/protobuf/timestamp.proto", "google/protobuf/duration.proto"]) {
    root.addJSON(protobuf.common.get(file).nested);
  }
  const enums = Object.values(foxgloveEnumSchemas);
  for (const schema of Object.values(foxgloveMessageSchemas)) {
    if (schema.name === "Timestamp" || schema.name === "Duration") {
      continue; // google.protobuf's, as in the generated files
    }
    const nested = enums.filter((e) => e.parentSchemaName === schema.name);
    protobuf.parse(generateProto(schema, nested), root, { keepCase: true });
  }
  root.resolveAll();
  return root;
}
const schemasRoot = foxgloveRoot();

const toObject = { longs: Number, enums: Number, bytes: Array, defaults: true };
const print = (o) => process.stdout.write(JSON.stringify(o) + "\n");
const errors = [];
const received = {};
const channels = new Map(); // channel id -> { topic, decode(bytes) -> object }
const subscribed = new Map(); // subscription id -> channel id

function decoderOf(channel) {
  if (channel.encoding === "json") {
    return { kind: "json", decode: (bytes) => JSON.parse(new TextDecoder().decode(bytes)) };
  }
  if (channel.encoding !== "protobuf" || channel.schemaEncoding !== "protobuf") {
    throw new Error(`${channel.topic}: encoding ${channel.encoding}/${channel.schemaEncoding}`);
  }
  const ours = schemasRoot.lookupType(channel.schemaName);
  const set = descriptor.FileDescriptorSet.decode(Buffer.from(channel.schema, "base64"));
  const advertised = protobuf.Root.fromDescriptor(set).lookupType(channel.schemaName);
  return {
    kind: channel.schemaName,
    decode: (bytes) => {
      const a = ours.toObject(ours.decode(bytes), toObject);
      const b = advertised.toObject(advertised.decode(bytes), toObject);
      if (JSON.stringify(a) !== JSON.stringify(b)) {
        throw new Error(`${channel.topic}: @foxglove/schemas and the advertised schema disagree`);
      }
      return a;
    },
  };
}

// [seconds, nanoseconds]: a stamp in ns since 1970 is beyond a double's exact integers.
const stampNs = (t) => (t ? [t.seconds, t.nanos] : [0, 0]);

function cloudOf(m) {
  const field = Object.fromEntries(m.fields.map((f) => [f.name, f]));
  const data = Buffer.from(m.data);
  const n = m.point_stride > 0 ? data.length / m.point_stride : 0;
  const xyz = [];
  const rgba = [];
  for (let i = 0; i < n; i++) {
    const at = i * m.point_stride;
    for (const c of ["x", "y", "z"]) {
      xyz.push(data.readFloatLE(at + field[c].offset));
    }
    for (const c of ["red", "green", "blue", "alpha"]) {
      rgba.push(data.readUInt8(at + field[c].offset));
    }
  }
  const p = m.pose?.position ?? { x: 0, y: 0, z: 0 };
  return {
    frame_id: m.frame_id,
    stamp_ns: stampNs(m.timestamp),
    origin: [p.x, p.y, p.z],
    fields: m.fields.map((f) => [f.name, f.offset, f.type]),
    count: n,
    xyz,
    rgba,
  };
}

function describe(topic, kind, m) {
  switch (kind) {
    case "foxglove.PointCloud":
      return { kind: "cloud", ...cloudOf(m) };
    case "foxglove.RawImage":
      return {
        kind: "image",
        frame_id: m.frame_id,
        stamp_ns: stampNs(m.timestamp),
        width: m.width,
        height: m.height,
        encoding: m.encoding,
        step: m.step,
        sha256: createHash("sha256").update(Buffer.from(m.data)).digest("hex"),
      };
    case "foxglove.FrameTransforms":
      return {
        kind: "tf",
        transforms: m.transforms.map((t) => ({
          parent: t.parent_frame_id,
          child: t.child_frame_id,
          stamp_ns: stampNs(t.timestamp),
          t: [t.translation.x, t.translation.y, t.translation.z],
          q: [t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w],
        })),
      };
    case "json":
      return { kind: "json", value: m };
    default:
      throw new Error(`${topic}: unexpected schema ${kind}`);
  }
}

const ws = new WebSocket(args.url, ["foxglove.sdk.v1"]);
const client = new FoxgloveClient({ ws });
let left = false;

client.on("error", (e) => errors.push(String(e?.message ?? e)));
client.on("advertise", (advertised) => {
  for (const channel of advertised) {
    try {
      channels.set(channel.id, { topic: channel.topic, ...decoderOf(channel) });
      subscribed.set(client.subscribe(channel.id), channel.id);
    } catch (e) {
      errors.push(String(e.message));
    }
  }
  print({
    event: "subscribed",
    channels: [...channels.values()].map((c) => [c.topic, c.kind]),
  });
  if (mode === "stall") {
    // Stop reading the socket: the kernel's buffers fill, then the server's queue for us.
    ws.pause();
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const channel = channels.get(subscribed.get(subscriptionId));
  if (!channel) {
    errors.push(`message on unknown subscription ${subscriptionId}`);
    return;
  }
  received[channel.topic] = (received[channel.topic] ?? 0) + 1;
  try {
    const bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
    const m = describe(channel.topic, channel.kind, channel.decode(bytes));
    if (mode !== "stall") {
      print({ event: "message", topic: channel.topic, ...m });
    }
  } catch (e) {
    errors.push(String(e.message));
  }
  if (mode === "leave" && !left) {
    left = true;
    client.close();
  }
});

function finish() {
  print({ event: "summary", mode, received, errors });
  if (!left) {
    client.close();
  }
  process.exit(0);
}

process.stdin.resume();
process.stdin.on("end", () => {
  if (mode === "stall") {
    // Read what the server still holds for us, until nothing has come for --drain-ms.
    ws.resume();
    let seen = -1;
    const quiet = () => {
      const now = Object.values(received).reduce((a, b) => a + b, 0);
      if (now === seen) {
        finish();
      } else {
        seen = now;
        setTimeout(quiet, Number(args["drain-ms"]));
      }
    };
    quiet();
  } else {
    finish();
  }
});
