#!/usr/bin/env node
// An independent ROS 2 node on our domain: Foxglove's standalone TypeScript implementation of the
// ROS 2 protocol (@foxglove/ros2 on @foxglove/rtps), no ROS 2 installation, no Fast DDS. It is
// given the generated interface package's .msg files (as a ROS 2 user's node would be built
// against pmlsm_msgs), subscribes to one topic under its ROS 2 name and type, decodes every
// sample, and lists what it discovered: the topics, and the nodes each process announces on
// ros_discovery_info (rmw_dds_common's ParticipantEntitiesInfo, decoded with Jazzy's definition
// as `ros2 node list` reads it).
//
//   node ros2_listener.mjs --package DIR --domain N [--topic /pmlsm/motor_feedback]
//        [--type MotorFeedback] [--count N] [--expect-topic NAME]... [--expect-node NAME]...
//        [--listen-s S] [--timeout-s S]
//
// --count N: done once ticks 0..N-1 have all arrived, in order, each decoded (stamp.tick); every
// --expect-topic must have been seen published, with its ROS 2 type; every --expect-node announced
// with at least one writer or reader. Without --count, done as soon as those were seen.
// --listen-s S: stays subscribed S seconds first (a load on a run, for the benchmarks). Prints "ros2_listener: started" once its participant runs,
// then one JSON line {"received":N,"in_order":bool,"first_tick":N,"last_tick":N,"topics":{...},
// "nodes":{NAME:{"participant":GID,"writers":N,"readers":N}},"participants":N,"errors":[...]};
// exits 0 when everything asked for was met, 1 otherwise (timeout included), 2 on a usage error.

import { parse } from "@foxglove/rosmsg";
import ros2 from "@foxglove/ros2"; // CommonJS: its names through the default export
import ros2Nodejs from "@foxglove/ros2/nodejs.js";
import rtps from "@foxglove/rtps";
import { PACKAGE, definitionOf, readPackageTexts } from "./ros2_definitions.mjs";

const { RosNode, Subscription } = ros2;

// rmw_dds_common/msg/ParticipantEntitiesInfo and what it uses, as ROS 2 Jazzy ships them.
const GRAPH_DEFINITION = [
  "Gid gid",
  "NodeEntitiesInfo[] node_entities_info_seq",
  `${"=".repeat(80)}`,
  "MSG: rmw_dds_common/Gid",
  "char[16] data",
  `${"=".repeat(80)}`,
  "MSG: rmw_dds_common/NodeEntitiesInfo",
  "string<=256 node_namespace",
  "string<=256 node_name",
  "Gid[] reader_gid_seq",
  "Gid[] writer_gid_seq",
].join("\n");
const { getNetworkInterfaces, UdpSocketNode } = ros2Nodejs;

function usage(message) {
  console.error(`ros2_listener: ${message}`);
  process.exit(2);
}

function parseArgs(argv) {
  const o = { topic: "/pmlsm/motor_feedback", type: "MotorFeedback", count: 0, expectTopics: [], expectNodes: [],
              listenS: 0, timeoutS: 60 };
  for (let i = 0; i < argv.length; ++i) {
    const value = () => (i + 1 < argv.length ? argv[++i] : usage(`${argv[i]} needs a value`));
    switch (argv[i]) {
      case "--package": o.packageDir = value(); break;
      case "--domain": o.domain = Number(value()); break;
      case "--topic": o.topic = value(); break;
      case "--type": o.type = value(); break;
      case "--count": o.count = Number(value()); break;
      case "--expect-topic": o.expectTopics.push(value()); break;
      case "--expect-node": o.expectNodes.push(value()); break;
      case "--listen-s": o.listenS = Number(value()); break;
      case "--timeout-s": o.timeoutS = Number(value()); break;
      default: usage(`unknown argument '${argv[i]}'`);
    }
  }
  if (!o.packageDir) usage("--package DIR is required");
  if (!Number.isInteger(o.domain) || o.domain < 0 || o.domain > 232) usage("--domain must be 0..232");
  if (!Number.isInteger(o.count) || o.count < 0) usage("--count must be a whole number");
  if (!(o.timeoutS > 0)) usage("--timeout-s must be positive");
  if (!(o.listenS >= 0)) usage("--listen-s must not be negative");
  return o;
}

async function main() {
  const o = parseArgs(process.argv.slice(2));
  const { texts } = await readPackageTexts(o.packageDir);
  if (!texts.has(o.type)) usage(`no message ${o.type} in ${o.packageDir}/msg`);
  const msgDefinition = parse(definitionOf(o.type, texts), { ros2: true });

  const errors = [];
  const participants = new Set();
  const ros = new RosNode({ name: "pmlsm_ros2_listener", domainId: o.domain, udpSocketCreate: UdpSocketNode.Create,
                            getNetworkInterfaces });
  ros.on("discoveredParticipant", (p) => participants.add(JSON.stringify(p.guidPrefix)));
  // Every publication seen over the run under its ROS 2 name and type (the library's own demangling;
  // a participant that left takes its own out of getPublishedTopics(), so they are gathered as
  // they come).
  const topics = {};
  const gather = () => { for (const [name, type] of ros.getPublishedTopics()) topics[name] = type; };
  ros.on("discoveredPublication", gather);
  await ros.start();
  // @foxglove/rtps announces its participant (SPDP DATA(p)) once to multicast, then only once to
  // each participant it discovers, by unicast. Fast DDS drops what reaches a participant between
  // its first announcement and the start of its reception (RTPSParticipantImpl::enable), a window
  // of milliseconds that a loaded host widens: a participant whose one reply fell in it never
  // learned of this listener and never sent it its endpoints. RTPS has SPDP announce periodically;
  // this does, every 0.2 s: a lockstep run's nodes may leave 2 s after they start, so the node that
  // missed the reply must find this listener well within that.
  const announcer = setInterval(() => void ros._participant.broadcastParticipant(ros._participant.attributes), 200);

  // ros_discovery_info has no "rt/" prefix, which RosNode.subscribe() would add: its reader is
  // made on the participant underneath, as rclcpp makes its own (reliable, transient local).
  const nodes = {};
  const graphOpts = { topicName: "ros_discovery_info", typeName: "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_",
                      durability: rtps.Durability.TransientLocal,
                      reliability: { kind: rtps.Reliability.Reliable, maxBlockingTime: { sec: 0x7fffffff, nsec: 0xffffffff } },
                      history: { kind: rtps.HistoryKind.KeepLast, depth: 1 } };
  const graphParticipant = ros._participant;
  const graph = new Subscription({ subscribeOpts: graphOpts, readerEntityId: graphParticipant.subscribe(graphOpts),
                                   participant: graphParticipant,
                                   msgDefinition: parse(GRAPH_DEFINITION, { ros2: true }) });
  graph.on("message", (_timestamp, info) => {
    const participant = Buffer.from(info.gid.data).toString("hex");
    for (const node of info.node_entities_info_seq) {
      nodes[node.node_name] = { participant, writers: node.writer_gid_seq.length, readers: node.reader_gid_seq.length };
    }
  });
  console.log("ros2_listener: started");

  let received = 0;
  let inOrder = true;
  let firstTick = null;
  let lastTick = null;
  let resolveDone;
  const done = new Promise((resolve) => { resolveDone = resolve; });
  const subscription = ros.subscribe({ topic: o.topic, dataType: `${PACKAGE}/msg/${o.type}`, msgDefinition });
  subscription.on("message", (_timestamp, msg) => {
    const tick = msg?.stamp?.tick;
    if (typeof tick !== "bigint" && typeof tick !== "number") {
      if (errors.length < 10) errors.push(`sample ${received}: no stamp.tick decoded`);
      return;
    }
    const t = Number(tick);
    if (lastTick !== null && t !== lastTick + 1) inOrder = false;
    if (firstTick === null) firstTick = t;
    lastTick = t;
    ++received;
    if (o.count > 0 && firstTick === 0 && lastTick === o.count - 1) resolveDone();
  });
  const deadline = Date.now() + o.timeoutS * 1000;
  const timer = setTimeout(resolveDone, o.timeoutS * 1000);
  if (o.listenS > 0) await new Promise((resolve) => setTimeout(resolve, o.listenS * 1000));
  if (o.count > 0) await done;
  clearTimeout(timer);
  // The samples may be in before every publication was discovered: wait for those expected, up to
  // the deadline.
  // A process announces a node as it is made, then again with each endpoint: a node still without
  // one is waited for too.
  const announced = (name) => name in nodes && nodes[name].writers + nodes[name].readers > 0;
  const missing = () => [...o.expectTopics.filter((name) => !(name in topics)),
                         ...o.expectNodes.filter((name) => !announced(name))];
  while (missing().length > 0 && Date.now() < deadline) {
    gather();
    await new Promise((resolve) => setTimeout(resolve, 20));
  }
  gather();

  for (const name of o.expectTopics) {
    if (!(name in topics)) errors.push(`topic ${name} was not discovered`);
    else if (!topics[name].startsWith(`${PACKAGE}/msg/`)) errors.push(`topic ${name} has type ${topics[name]}`);
  }
  for (const name of o.expectNodes) {
    if (!(name in nodes)) errors.push(`node ${name} was not announced on ros_discovery_info`);
    else if (nodes[name].writers + nodes[name].readers === 0) errors.push(`node ${name} announced no endpoint`);
  }
  if (o.count > 0) {
    if (received !== o.count) errors.push(`received ${received} of ${o.count} samples`);
    if (!inOrder) errors.push("ticks not consecutive");
    if (firstTick !== 0 || lastTick !== o.count - 1) errors.push(`ticks ${firstTick}..${lastTick}, not 0..${o.count - 1}`);
  }
  console.log(JSON.stringify({ received, in_order: inOrder, first_tick: firstTick, last_tick: lastTick, topics, nodes,
                               participants: participants.size, errors }));
  clearInterval(announcer);
  await ros.shutdown();
  process.exit(errors.length === 0 ? 0 : 1);
}

main().catch((error) => {
  console.error(`ros2_listener: ${error.stack ?? error}`);
  process.exit(1);
});
