#!/usr/bin/env node
// An independent EtherCAT master judges our virtual slave: SOEM 2.0 (Simple Open EtherCAT Master,
// through npm's soem-node; GPL, so only run here as a separate program, never linked) scans the
// interface, reads each slave's identity from its SII, takes the bus to PREOP, reads objects
// over CoE, maps the process data, walks to SAFEOP and OP, and exchanges process data.
//
//   node soem_master.mjs INTERFACE [--read INDEX:SUB ...] [--walk [--exchange N]]
//
// --walk (a CiA 402 drive behind the slave, `pmlsm ethercat serve --drive`): after the cycles
// above, the power-state walk by controlword in the process data (shutdown, switch on, enable
// operation; 0x0006, 0x0007, 0x000F, three cycles each), then 200 cycles of 100 per mille target
// torque; adds {"statusword_enabled":"hex","position_start":N,"position_end":N} (position actual,
// increments, as the inputs carried it). --exchange N: then N more cycles, a square wave of
// +-20 per mille every 100 cycles; adds {"exchange":{"cycles":N,"wkc_errors":N,"no_frame":N}}
// (a working counter other than 3, and frames SOEM got no answer to within its 2 ms and sent
// again, up to 20 times a cycle).
//
// Prints one JSON line: {"slaves":N,"identity":[{"name","vendor","product","address"}],
// "preop":STATE,"reads":{"0x1000:0":"hex bytes" or null},"safeop":STATE,"op":STATE,
// "output_bytes":N,"input_bytes":N,"process_wkc":[the working counters of 5 answered cycles],
// "process_no_frame":N,"inputs":"hex"}. Exits 1 when
// SOEM cannot open the interface or finds no slave; 2 on a usage error.

import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const { SoemMaster } = require("soem-node");

const EC_STATE_PRE_OP = 2;
const EC_STATE_SAFE_OP = 4;
const EC_STATE_OPERATIONAL = 8;
const STATE_TIMEOUT_US = 2_000_000;

const args = process.argv.slice(2);
if (args.length < 1) {
  console.error("usage: node soem_master.mjs INTERFACE [--read INDEX:SUB ...]");
  process.exit(2);
}
const ifname = args[0];
const reads = [];
let walk = false;
let exchange = 0;
for (let i = 1; i < args.length; ++i) {
  if (args[i] === "--walk") {
    walk = true;
  } else if (args[i] === "--exchange" && i + 1 < args.length) {
    exchange = Number.parseInt(args[++i], 10);
  } else if (args[i] === "--read" && i + 1 < args.length) {
    reads.push(args[++i]);
  } else {
    console.error(`soem_master: unexpected argument ${args[i]}`);
    process.exit(2);
  }
}

const master = new SoemMaster(ifname);
if (!master.init()) {
  console.error(`soem_master: SOEM cannot open ${ifname}`);
  process.exit(1);
}
const result = { slaves: master.configInit() };
if (result.slaves <= 0) {
  console.log(JSON.stringify(result));
  master.close();
  process.exit(1);
}
result.identity = master.getSlaves().map((s) => ({ name: s.name, address: s.configadr }));
// SOEM sends mailbox messages only to slaves it has seen in PREOP: wait for it, read it back.
result.preop = master.stateCheck(0, EC_STATE_PRE_OP, STATE_TIMEOUT_US);
master.readState();
result.reads = {};
for (const what of reads) {
  const [index, sub] = what.split(":").map((x) => Number.parseInt(x, 16));
  const data = master.sdoRead(1, index, sub);
  result.reads[what] = data ? data.toString("hex") : null;
}
master.configMapPDO();
result.safeop = master.stateCheck(0, EC_STATE_SAFE_OP, STATE_TIMEOUT_US);
master.writeState(0, EC_STATE_OPERATIONAL);
result.op = master.stateCheck(1, EC_STATE_OPERATIONAL, STATE_TIMEOUT_US);
// Process data: the outputs SOEM mapped from the slave's PDO assignment (controlword 0x0006,
// target torque 100 per mille when they are the CiA 402 RxPDO), a few cycles, their working
// counters and the inputs that came back.
const slave = master.getSlaves()[0];
result.output_bytes = slave.Obytes;
result.input_bytes = slave.Ibytes;
if (slave.Obytes >= 4) new Uint8Array(slave.outputs).set([0x06, 0x00, 100, 0x00]);
// SOEM waits 2 ms for a cycle's frame (EC_TIMEOUTRET, fixed by the binding); a slave process the
// host held longer (a loaded test machine) misses it: such cycles (EC_NOFRAME, -1) are counted
// apart and sent again, up to 50 cycles in all.
result.process_wkc = [];
result.process_no_frame = 0;
for (let cycle = 0; cycle < 50 && result.process_wkc.length < 5; ++cycle) {
  master.sendProcessdata();
  const wkc = master.receiveProcessdata();
  if (wkc === -1) {
    ++result.process_no_frame;
  } else {
    result.process_wkc.push(wkc);
  }
}
result.inputs = Buffer.from(new Uint8Array(master.getSlaves()[0].inputs)).toString("hex");
if (walk && slave.Obytes >= 4 && slave.Ibytes >= 8) {
  const outputs = new DataView(slave.outputs);
  const inputs = () => new DataView(master.getSlaves()[0].inputs);
  // One answered cycle (a frame the host held past SOEM's 2 ms is sent again, up to 20 times);
  // its working counter (-1: never answered).
  let no_frame = 0;
  const cycle = (controlword, torque) => {
    outputs.setUint16(0, controlword, true);
    outputs.setInt16(2, torque, true);
    for (let attempt = 0; attempt < 20; ++attempt) {
      master.sendProcessdata();
      const wkc = master.receiveProcessdata();
      if (wkc !== -1) return wkc;
      ++no_frame;
    }
    return -1;
  };
  for (const controlword of [0x0006, 0x0007, 0x000f]) {
    for (let i = 0; i < 3; ++i) cycle(controlword, 0);
  }
  result.statusword_enabled = inputs().getUint16(0, true).toString(16);
  result.position_start = inputs().getInt32(4, true);
  for (let i = 0; i < 200; ++i) cycle(0x000f, 100);
  result.position_end = inputs().getInt32(4, true);
  if (exchange > 0) {
    no_frame = 0;
    let wkc_errors = 0;
    for (let i = 0; i < exchange; ++i) {
      if (cycle(0x000f, Math.floor(i / 100) % 2 === 0 ? 20 : -20) !== 3) ++wkc_errors;
    }
    result.exchange = { cycles: exchange, wkc_errors, no_frame };
  }
}
master.close();
console.log(JSON.stringify(result));
