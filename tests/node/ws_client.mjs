// A third-party client of foxglove_bridge: the Foxglove WebSocket client library
// (@foxglove/ws-protocol) over the `ws` package, with Foxglove's own IDL parser and CDR reader
// (@foxglove/omgidl-parser, @foxglove/omgidl-serialization) to decode what it receives, as the
// Foxglove app does. Prints one JSON summary line last; exit 0 when every check passed.
//
//   node ws_client.mjs --url ws://127.0.0.1:8765 [--mode check|garbage|stall] [options]
//
// check (default): checks the advertised channels (encoding cdr, schemaEncoding omgidl, a
//   schema Foxglove parses), subscribes to --topics (comma separated, or "all"; default
//   /pmlsm/motor_feedback,/pmlsm/force_command), decodes every message, checks that
//   stamp.tick increases (per node, and never decreases, for /pmlsm/node_status) and that
//   every number is finite.
//   Passes once each topic has --min-messages (default 100) and --duration-s (default 0) has
//   passed; fails on a bad message, an error status, a closed connection, or at --timeout-s
//   (default 20) with too few messages. Prints "ws_client: subscribed ..." once subscribed.
// garbage: sends what a broken or hostile client would, one connection per case, and checks
//   that the server answers with an error status where the spec has one and closes the
//   connection on malformed input, keeps it after requests it merely cannot honour, and
//   refuses handshakes that are not Foxglove WebSocket ones. --expect-data: also checks that
//   the connection that got non-fatal errors still receives data afterwards.
// stall: subscribes to --topics and then stops reading for --duration-s (a slow client: the
//   server must drop its frames, not slow down).
import net from "node:net";

import wsProtocol from "@foxglove/ws-protocol";
import omgidlParser from "@foxglove/omgidl-parser";
import omgidlSerialization from "@foxglove/omgidl-serialization";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;
const { parseIDL } = omgidlParser;
const { MessageReader } = omgidlSerialization;

function parseArgs(argv) {
  const options = {
    url: "",
    mode: "check",
    topics: "/pmlsm/motor_feedback,/pmlsm/force_command",
    minMessages: 100,
    durationS: 0,
    timeoutS: 20,
    expectData: false,
  };
  const numeric = { "--min-messages": "minMessages", "--duration-s": "durationS", "--timeout-s": "timeoutS" };
  const text = { "--url": "url", "--mode": "mode", "--topics": "topics" };
  for (let i = 0; i < argv.length; ++i) {
    const arg = argv[i];
    if (arg === "--expect-data") {
      options.expectData = true;
    } else if (arg in numeric || arg in text) {
      const value = argv[++i];
      if (value === undefined) usage(`${arg} needs a value`);
      if (arg in numeric) {
        const n = Number(value);
        if (!Number.isFinite(n) || n < 0) usage(`${arg}: not a non-negative number: '${value}'`);
        options[numeric[arg]] = n;
      } else {
        options[text[arg]] = value;
      }
    } else {
      usage(`unknown argument '${arg}'`);
    }
  }
  if (!options.url) usage("--url is required");
  if (!["check", "garbage", "stall"].includes(options.mode)) usage(`--mode: check, garbage or stall, not '${options.mode}'`);
  return options;
}

function usage(problem) {
  console.error(`ws_client: ${problem}\nusage: node ws_client.mjs --url ws://HOST:PORT [--mode check|garbage|stall] ` +
                `[--topics a,b|all] [--min-messages N] [--duration-s S] [--timeout-s T] [--expect-data]`);
  process.exit(2);
}

const options = parseArgs(process.argv.slice(2));
const startMs = Date.now();
const elapsedS = () => (Date.now() - startMs) / 1000;

function finish(summary) {
  summary.elapsed_s = Number(elapsedS().toFixed(3));
  console.log(JSON.stringify(summary, (_key, value) => (typeof value === "bigint" ? value.toString() : value)));
  // Let stdout drain, then leave even if a socket lingers.
  process.exitCode = summary.ok ? 0 : 1;
  setTimeout(() => process.exit(process.exitCode), 200).unref();
}

/// A number anywhere in a decoded message that is not finite, as "path=value", or null.
function firstNonFinite(value, path) {
  if (typeof value === "number") return Number.isFinite(value) ? null : `${path}=${value}`;
  if (ArrayBuffer.isView(value) && !(value instanceof DataView)) {
    for (let i = 0; i < value.length; ++i) {
      if (typeof value[i] === "number" && !Number.isFinite(value[i])) return `${path}[${i}]=${value[i]}`;
    }
    return null;
  }
  if (Array.isArray(value)) {
    for (let i = 0; i < value.length; ++i) {
      const bad = firstNonFinite(value[i], `${path}[${i}]`);
      if (bad) return bad;
    }
    return null;
  }
  if (value !== null && typeof value === "object") {
    for (const [key, member] of Object.entries(value)) {
      const bad = firstNonFinite(member, path ? `${path}.${key}` : key);
      if (bad) return bad;
    }
  }
  return null;
}

/// The reader of one advertised channel, or throws saying what is wrong with it.
function readerFor(channel) {
  if (channel.encoding !== "cdr") throw new Error(`encoding '${channel.encoding}', expected 'cdr'`);
  if (channel.schemaEncoding !== "omgidl") throw new Error(`schemaEncoding '${channel.schemaEncoding}', expected 'omgidl'`);
  if (!channel.schemaName) throw new Error("no schemaName");
  if (!channel.schema) throw new Error("empty schema");
  return new MessageReader(channel.schemaName, parseIDL(channel.schema));
}

// ---------------------------------------------------------------------------------- check / stall

function runCheck() {
  const summary = { ok: false, mode: options.mode, url: options.url, topics: {}, node_status: {}, statuses: [] };
  let done = false;
  const fail = (error) => {
    if (done) return;
    done = true;
    summary.error = error;
    console.error(`ws_client: FAILED: ${error}`);
    client.close();
    finish(summary);
  };
  const pass = () => {
    if (done) return;
    done = true;
    summary.ok = true;
    client.close();
    finish(summary);
  };

  const ws = new WebSocket(options.url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  const client = new FoxgloveClient({ ws });
  const bySubscription = new Map();
  let subscribed = false;

  const deadline = setTimeout(() => {
    const counts = Object.entries(summary.topics).map(([t, s]) => `${t}: ${s.messages}`).join(", ");
    fail(`deadline of ${options.timeoutS} s passed with ${counts || "no subscription"} (want ${options.minMessages} each)`);
  }, options.timeoutS * 1000);
  deadline.unref();

  const checkDone = () => {
    if (!subscribed || options.mode !== "check") return;
    if (elapsedS() < options.durationS) return;
    if ([...bySubscription.values()].every((s) => s.summary.messages >= options.minMessages)) {
      clearTimeout(deadline);
      pass();
    }
  };
  if (options.durationS > 0) {
    const durationTimer = setTimeout(() => {
      if (options.mode === "stall") {
        ws.resume();
        clearTimeout(deadline);
        pass();
      } else {
        checkDone();
      }
    }, options.durationS * 1000);
    // A paused socket does not keep Node.js running: in stall mode this timer has to.
    if (options.mode !== "stall") durationTimer.unref();
  }

  client.on("error", (error) => fail(`client error: ${error?.message ?? error}`));
  client.on("close", (event) => fail(`the server closed the connection (code ${event.code}, '${event.reason}')`));
  client.on("serverInfo", (info) => {
    summary.server = { name: info.name, capabilities: info.capabilities, sessionId: info.sessionId };
  });
  client.on("status", (status) => {
    summary.statuses.push(status);
    if (status.level >= 2) fail(`error status from the server: ${status.message}`);
  });
  client.on("advertise", (channels) => {
    summary.channels_advertised = (summary.channels_advertised ?? 0) + channels.length;
    const byTopic = new Map();
    for (const channel of channels) {
      try {
        byTopic.set(channel.topic, { channel, reader: readerFor(channel) });
      } catch (error) {
        fail(`channel ${channel.id} (${channel.topic}): ${error.message}`);
        return;
      }
    }
    if (subscribed) return;
    const wanted = options.topics === "all" ? [...byTopic.keys()] : options.topics.split(",").filter((t) => t);
    for (const topic of wanted) {
      const found = byTopic.get(topic);
      if (!found) {
        fail(`topic ${topic} not advertised; advertised: ${[...byTopic.keys()].join(", ")}`);
        return;
      }
      const state = {
        topic,
        reader: found.reader,
        lastTick: new Map(),  // per node_name: /pmlsm/node_status has one writer per node
        summary: { channel_id: found.channel.id, schema_name: found.channel.schemaName, messages: 0 },
      };
      summary.topics[topic] = state.summary;
      bySubscription.set(client.subscribe(found.channel.id), state);
    }
    subscribed = true;
    console.log(`ws_client: subscribed to ${wanted.join(", ")}`);
    if (options.mode === "stall") {
      ws.pause();  // stop reading: the socket's buffers fill and the server has to drop
      console.log(`ws_client: stalled for ${options.durationS} s`);
    }
  });
  client.on("message", ({ subscriptionId, timestamp, data }) => {
    if (done) return;
    const state = bySubscription.get(subscriptionId);
    if (!state) {
      fail(`message for unknown subscription ${subscriptionId}`);
      return;
    }
    let message;
    try {
      message = state.reader.readMessage(data);
    } catch (error) {
      fail(`${state.topic}: cannot decode a ${data.byteLength}-byte message: ${error.message}`);
      return;
    }
    const bad = firstNonFinite(message, "");
    if (bad) {
      fail(`${state.topic}: non-finite value ${bad}`);
      return;
    }
    if (typeof timestamp !== "bigint" || timestamp <= 0n) {
      fail(`${state.topic}: receive timestamp ${timestamp} is not a positive time`);
      return;
    }
    const tick = message?.stamp?.tick;
    if (tick === undefined) {
      fail(`${state.topic}: decoded message has no stamp.tick`);
      return;
    }
    // NodeStatus comes from every node, and a node may report two state changes at one tick.
    const key = message.node_name ?? "";
    const last = state.lastTick.get(key);
    if (last !== undefined && (key ? tick < last : tick <= last)) {
      fail(`${state.topic}${key ? ` (${key})` : ""}: tick ${tick} after ${last}: ticks must increase`);
      return;
    }
    state.lastTick.set(key, tick);
    const s = state.summary;
    if (s.messages === 0) {
      s.first_tick = tick;
      if (Object.values(summary.topics).every((t) => t.messages === 0)) console.log("ws_client: receiving");
    }
    s.messages += 1;
    s.last_tick = tick;
    if (key) {
      summary.node_status[key] = {
        state: message.state, ticks: message.ticks, late: message.late, rejected: message.rejected,
        message: message.message,
      };
    }
    checkDone();
  });
}

// ---------------------------------------------------------------------------------- garbage

const kCaseTimeoutMs = 5000;

/// Opens a WebSocket and collects what the server says until it closes.
function connect(protocols) {
  return new Promise((resolve, reject) => {
    const ws = new WebSocket(options.url, protocols);
    const conn = { ws, statuses: [], channels: [], binaryMessages: 0 };
    conn.closed = new Promise((resolveClosed) => {
      ws.on("close", (code, reason) => resolveClosed({ code, reason: reason.toString() }));
    });
    ws.on("error", (error) => {
      conn.error = error.message;
      reject(error);
    });
    ws.on("message", (data, isBinary) => {
      if (isBinary) {
        conn.binaryMessages += 1;
        return;
      }
      const message = JSON.parse(data.toString());
      if (message.op === "status") conn.statuses.push(message);
      if (message.op === "advertise") {
        conn.channels.push(...message.channels);
        resolve(conn);  // greeted: serverInfo came first
      }
    });
  });
}

function within(promise, ms, what) {
  let timer;
  return Promise.race([
    promise,
    new Promise((_, reject) => {
      timer = setTimeout(() => reject(new Error(`${what}: nothing within ${ms} ms`)), ms);
    }),
  ]).finally(() => clearTimeout(timer));
}

/// Sends `payload` and expects an error status (when `wantStatus`) and a close with `wantCode`.
async function expectClosed(payload, sendOptions, wantCode, wantStatus) {
  const conn = await within(connect([FoxgloveClient.SUPPORTED_SUBPROTOCOL]), kCaseTimeoutMs, "connect");
  conn.ws.on("error", () => {});  // the server may close while we still send
  conn.ws.send(payload, sendOptions);
  const { code, reason } = await within(conn.closed, kCaseTimeoutMs, "close");
  const errorStatus = conn.statuses.find((s) => s.level === 2);
  const ok = code === wantCode && (!wantStatus || errorStatus !== undefined);
  return { ok, code, reason, status: errorStatus?.message ?? null };
}

/// Requests the server cannot honour: a status each, and the connection stays usable.
async function expectKept() {
  const conn = await within(connect([FoxgloveClient.SUPPORTED_SUBPROTOCOL]), kCaseTimeoutMs, "connect");
  const requests = [
    { request: { op: "frobnicate" }, level: 2 },
    { request: { op: "subscribe", subscriptions: [{ id: 1, channelId: 999999 }] }, level: 1 },
    { request: { op: "unsubscribe", subscriptionIds: [42] }, level: 1 },
    { request: { op: "getParameters", parameterNames: [] }, level: 2 },
  ];
  for (const { request } of requests) conn.ws.send(JSON.stringify(request));
  const deadline = Date.now() + kCaseTimeoutMs;
  while (conn.statuses.length < requests.length && Date.now() < deadline) await new Promise((r) => setTimeout(r, 10));
  const levels = conn.statuses.map((s) => s.level);
  let ok = levels.length === requests.length && requests.every((r, i) => r.level === levels[i]);
  let detail = { levels, statuses: conn.statuses.map((s) => s.message) };
  if (ok && options.expectData) {
    const feedback = conn.channels.find((c) => c.topic === "/pmlsm/motor_feedback") ?? conn.channels[0];
    conn.ws.send(JSON.stringify({ op: "subscribe", subscriptions: [{ id: 2, channelId: feedback.id }] }));
    while (conn.binaryMessages === 0 && Date.now() < deadline + kCaseTimeoutMs) await new Promise((r) => setTimeout(r, 10));
    detail.messages_after_errors = conn.binaryMessages;
    ok = conn.binaryMessages > 0;
  }
  ok = ok && conn.ws.readyState === WebSocket.OPEN;
  conn.ws.close(1000, "done");
  await within(conn.closed, kCaseTimeoutMs, "close");
  return { ok, ...detail };
}

/// A WebSocket handshake without our subprotocol: refused with HTTP 400.
function expectRefusedWithoutSubprotocol() {
  return within(new Promise((resolve) => {
    const ws = new WebSocket(options.url);
    ws.on("open", () => {
      ws.close();
      resolve({ ok: false, detail: "handshake accepted without the subprotocol" });
    });
    ws.on("unexpected-response", (_request, response) => {
      resolve({ ok: response.statusCode === 400, http_status: response.statusCode });
      response.destroy();
    });
    ws.on("error", (error) => resolve({ ok: false, detail: error.message }));
  }), kCaseTimeoutMs, "handshake");
}

/// Bytes that are not HTTP at all: the server must answer or hang up, not wait.
function expectRawJunkHungUp() {
  const { hostname, port } = new URL(options.url);
  return within(new Promise((resolve) => {
    const socket = net.connect(Number(port), hostname);
    let answer = "";
    socket.on("connect", () => socket.write(Buffer.from("\x16\x03\x01\x00\xff junk that is not HTTP\r\n\r\n", "latin1")));
    socket.on("data", (data) => { answer += data.toString("latin1"); });
    socket.on("error", () => {});
    socket.on("close", () => resolve({ ok: true, answer: answer.split("\r\n")[0] }));
  }), kCaseTimeoutMs, "raw TCP");
}

async function runGarbage() {
  const cases = {
    not_json: () => expectClosed("this is not json {", { binary: false }, 1007, true),
    not_an_object: () => expectClosed("[1,2,3]", { binary: false }, 1007, true),
    no_op: () => expectClosed(JSON.stringify({ subscriptions: [] }), { binary: false }, 1007, true),
    bad_field_types: () => expectClosed(JSON.stringify({ op: "subscribe", subscriptions: [{ id: "x", channelId: 1 }] }),
                                        { binary: false }, 1007, true),
    binary_frame: () => expectClosed(Buffer.from([0x01, 0, 0, 0, 0, 1, 2, 3]), { binary: true }, 1003, true),
    invalid_utf8_text: () => expectClosed(Buffer.from([0x7b, 0xff, 0xfe, 0x7d]), { binary: false }, 1007, false),
    oversized_text: () => expectClosed("x".repeat(128 * 1024), { binary: false }, 1009, false),
    unhonourable_requests_keep_connection: () => expectKept(),
    no_subprotocol: () => expectRefusedWithoutSubprotocol(),
    raw_tcp_junk: () => expectRawJunkHungUp(),
  };
  const summary = { ok: true, mode: "garbage", url: options.url, cases: {} };
  for (const [name, run] of Object.entries(cases)) {
    let result;
    try {
      result = await run();
    } catch (error) {
      result = { ok: false, detail: error.message };
    }
    summary.cases[name] = result;
    if (!result.ok) {
      summary.ok = false;
      console.error(`ws_client: garbage case ${name} FAILED: ${JSON.stringify(result)}`);
    }
  }
  finish(summary);
}

if (options.mode === "garbage") {
  runGarbage();
} else {
  runCheck();
}
