#!/usr/bin/env python3
"""python-can as the CANopen master of nodes/virtual_drive (lockstep).

    virtual_drive_test.py PATH/TO/virtual_drive --source-dir DIR [--group ADDR] [--port N]

Starts the drive on a test group/port with a short copy of the pulse scenario, then checks:
boot-up, SDO uploads (0x1000, 0x6041, a missing object -> 0x06020000), SDO downloads of 0x6060
(10 accepted, 3 refused with 0x06090030), NMT start, enabling through RPDO1 controlwords with
SYNCs (statusword & 0x6F == 0x27), 20 lockstep ticks with a target torque (periods stepped +1 a
tick, torque actual follows the target through the current loop, position moves with the force), a repeated SYNC that must not step, a wrong-DLC RPDO1
that is ignored, TPDO2 remapped over SDO while pre-operational, NMT reset communication bringing
the description's mapping back. Then realtime: enabled by controlword with SYNCs and the master's
heartbeat; the heartbeat stops: EMCY 0x8130 within the consumer time, statusword fault.
Exit: 0 PASS, 1 FAIL, 77 skipped (python-can missing).
"""

import argparse
import os
import struct
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from can_test_support import SKIP, Checks, import_can, stop  # noqa: E402

can = import_can()

NODE = 1  # configs/canopen/drive.yaml


def recv_id(bus, cob_id, timeout=2.0, pred=None):
    """The next frame with this id (and pred true), or None."""
    deadline = time.monotonic() + timeout
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        m = bus.recv(timeout=left)
        if m is None:
            return None
        if m.arbitration_id == cob_id and not m.is_extended_id and (pred is None or pred(m)):
            return m


def drain(bus):
    while bus.recv(timeout=0.0) is not None:
        pass


def send(bus, cob_id, data):
    bus.send(can.Message(arbitration_id=cob_id, data=bytes(data), is_extended_id=False))


def sdo(bus, data):
    """Sends an SDO request, returns the response's 8 bytes or None. python-can hears its own
    frames: responses are on 0x580 + node only."""
    drain(bus)
    send(bus, 0x600 + NODE, data)
    m = recv_id(bus, 0x580 + NODE)
    return bytes(m.data) if m else None


def upload(bus, index, sub):
    return sdo(bus, [0x40, index & 0xFF, index >> 8, sub, 0, 0, 0, 0])


def download(bus, index, sub, value, size):
    cmd = {1: 0x2F, 2: 0x2B, 4: 0x23}[size]
    payload = value.to_bytes(size, "little", signed=value < 0) + bytes(4 - size)
    return sdo(bus, [cmd, index & 0xFF, index >> 8, sub] + list(payload))


def abort_code(r):
    return struct.unpack_from("<I", r, 4)[0] if r and r[0] == 0x80 else None


def lockstep(bus, controlword, torque, tick):
    """RPDO1 + SYNC; returns (statusword, torque actual, velocity, position, periods) or None."""
    drain(bus)
    send(bus, 0x200 + NODE, struct.pack("<HhI", controlword, torque, tick))
    send(bus, 0x080, b"")
    return answer(bus)


def answer(bus):
    t1 = recv_id(bus, 0x180 + NODE)
    t2 = recv_id(bus, 0x280 + NODE)
    if t1 is None or t2 is None or len(t1.data) != 8 or len(t2.data) != 8:
        return None
    sw, tq, vel = struct.unpack("<Hhi", bytes(t1.data))
    pos, periods = struct.unpack("<iI", bytes(t2.data))
    return sw, tq, vel, pos, periods


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("drive")
    parser.add_argument("--source-dir", default=os.path.join(os.path.dirname(__file__), "..", ".."))
    pid = os.getpid()
    parser.add_argument("--group", default=f"239.74.{180 + (pid >> 8) % 40}.{pid & 0xFF}")
    parser.add_argument("--port", type=int, default=6150)
    parser.add_argument("--domain", type=int, default=int(os.environ.get("PMLSM_TEST_DOMAIN_BASE", "100")) + 47,
                        help="DDS domain of the drive's NodeStatus (test offset 47)")
    args = parser.parse_args()
    src = os.path.abspath(args.source_dir)
    checks = Checks()

    tmp = tempfile.mkdtemp(prefix="virtual_drive_test_")
    scenario = os.path.join(tmp, "short.yaml")
    with open(os.path.join(src, "configs/scenarios/pulse.yaml")) as f:
        text = f.read()
    text = text.replace('duration_s: {value: 2.0,', 'duration_s: {value: 0.05,')
    text = text.replace('cost_window_s: {value: 1.0,', 'cost_window_s: {value: 0.05,')
    with open(scenario, "w") as f:
        f.write(text)

    try:
        bus = can.Bus(interface="udp_multicast", channel=args.group, port=args.port, hop_limit=1, fd=False)
    except can.CanInterfaceNotImplementedError as error:
        print(f"SKIP: python-can's udp_multicast interface is unavailable: {error}")
        return SKIP
    log = open(os.path.join(tmp, "drive.log"), "w+")
    drive = subprocess.Popen(
        [args.drive, "--config", os.path.join(src, "configs/system.yaml"), "--scenario", scenario,
         "--canopen-config", os.path.join(src, "configs/canopen/drive.yaml"),
         "--dictionary", os.path.join(src, "configs/canopen/virtual_drive_od.yaml"),
         "--can-group", args.group, "--can-port", str(args.port), "--can-iface", "127.0.0.1",
         "--domain", str(args.domain), "--profiles", os.path.join(src, "configs/dds/profiles.xml")],
        stdout=log, stderr=subprocess.STDOUT)
    try:
        run_checks(bus, checks, drive)
        stop(drive, timeout=5)
        log.seek(0)
        print("---- drive output ----\n" + log.read() + "----------------------")
        realtime_checks(args, src, tmp, bus, checks)
    finally:
        stop(drive, timeout=5)
        bus.shutdown()
    print(f"{'PASS' if not checks.failed else 'FAIL'}: {checks.passed} checks passed, "
          f"{len(checks.failed)} failed" + "".join(f"\n  failed: {w}" for w in checks.failed))
    return 0 if not checks.failed else 1


def run_checks(bus, checks, drive):
    boot = recv_id(bus, 0x700 + NODE, timeout=10.0)
    if not checks.check(boot is not None and bytes(boot.data) == b"\x00",
                        f"boot-up 0x{0x700 + NODE:03X} [00] (got {boot})"):
        return
    r = upload(bus, 0x1000, 0)
    checks.check(r is not None and r[0] == 0x43 and struct.unpack_from("<I", r, 4)[0] == 0x00020192,
                 f"SDO upload 0x1000 = 0x00020192 (got {r.hex() if r else None})")
    r = upload(bus, 0x6041, 0)
    checks.check(r is not None and r[0] == 0x4B and (struct.unpack_from("<H", r, 4)[0] & 0x4F) == 0x40,
                 f"SDO upload 0x6041: switch on disabled (got {r.hex() if r else None})")
    r = upload(bus, 0x2345, 0)
    checks.check(abort_code(r) == 0x06020000, f"SDO upload of missing 0x2345: abort 0x06020000 (got {r.hex() if r else None})")
    r = download(bus, 0x6060, 0, 10, 1)
    checks.check(r is not None and r[0] == 0x60, f"SDO download 0x6060 = 10 accepted (got {r.hex() if r else None})")
    r = download(bus, 0x6060, 0, 3, 1)
    checks.check(abort_code(r) == 0x06090030, f"SDO download 0x6060 = 3: abort 0x06090030 (got {r.hex() if r else None})")

    send(bus, 0x000, [0x01, NODE])  # NMT start
    hb = recv_id(bus, 0x700 + NODE, timeout=2.0, pred=lambda m: bytes(m.data) == b"\x05")
    checks.check(hb is not None, "heartbeat shows operational (0x05) after NMT start")

    # The first SYNC only answers (periods stepped 0), then each controlword with its tick.
    drain(bus)
    send(bus, 0x080, b"")
    a = answer(bus)
    if not checks.check(a is not None and a[4] == 0, f"first SYNC answered with periods stepped 0 (got {a})"):
        return
    periods = a[4]
    for cw in (0x06, 0x07, 0x0F):
        a = lockstep(bus, cw, 0, periods)
        if not checks.check(a is not None and a[4] == periods + 1, f"controlword 0x{cw:02X}: stepped (got {a})"):
            return
        periods = a[4]
    checks.check((a[0] & 0x6F) == 0x27, f"TPDO1 statusword 0x{a[0]:04X}: operation enabled")

    torque = 200  # per mille of the rated force
    start_pos = a[3]
    ok_steps, last_pos, actuals = True, a[3], []
    for _ in range(20):
        a = lockstep(bus, 0x0F, torque, periods)
        if a is None or a[4] != periods + 1:
            ok_steps = False
            print(f"  tick {periods}: answer {a}")
            break
        periods, last_pos = a[4], a[3]
        actuals.append(a[1])
    checks.check(ok_steps, "20 lockstep ticks: periods stepped +1 a tick")
    # Torque actual is what the current loop makes of the target (K_f i_q): it rises towards
    # the target and, once the loop has settled, holds it to within 2 per mille.
    checks.check(len(actuals) == 20 and 0 < actuals[0] and all(abs(t - torque) <= 2 for t in actuals[10:]),
                 f"torque actual follows the target {torque}: {actuals}")
    checks.check(last_pos > start_pos + 10, f"position moved with the force: {start_pos} -> {last_pos} increments")

    drain(bus)
    send(bus, 0x080, b"")  # a repeated SYNC, no new RPDO1
    a = answer(bus)
    checks.check(a is not None and a[4] == periods, f"repeated SYNC does not step (periods {periods}, got {a})")

    drain(bus)
    send(bus, 0x200 + NODE, [0x0F, 0x00, 0x00])  # wrong DLC for RPDO1 (3, not 8)
    send(bus, 0x080, b"")
    a = answer(bus)
    checks.check(a is not None and a[4] == periods, f"wrong-DLC RPDO1 ignored: SYNC answered, no step (got {a})")
    a = lockstep(bus, 0x0F, torque, periods)
    checks.check(a is not None and a[4] == periods + 1, f"drive still steps after the malformed frame (got {a})")
    periods = a[4] if a else periods
    checks.check(drive.poll() is None, "drive still running")

    # Remapping TPDO2 over SDO (CiA 301's order) while pre-operational: position actual only.
    send(bus, 0x000, [0x80, NODE])  # NMT enter pre-operational
    recv_id(bus, 0x700 + NODE, timeout=2.0, pred=lambda m: bytes(m.data) == b"\x7f")
    steps = [(0x1801, 1, 0x80000280 + NODE, 4), (0x1A01, 0, 0, 1), (0x1A01, 1, 0x60640020, 4), (0x1A01, 0, 1, 1),
             (0x1801, 1, 0x280 + NODE, 4)]
    answers = [download(bus, i, sub, v, size) for i, sub, v, size in steps]
    checks.check(all(r is not None and r[0] == 0x60 for r in answers),
                 f"TPDO2 remapped over SDO: {[r.hex() if r else None for r in answers]}")
    r = download(bus, 0x1A01, 1, 0x60400010, 4)  # controlword into a TPDO while it is valid: refused
    checks.check(abort_code(r) is not None, f"a mapping write to a valid PDO is refused (got {r.hex() if r else None})")
    send(bus, 0x000, [0x01, NODE])
    recv_id(bus, 0x700 + NODE, timeout=2.0, pred=lambda m: bytes(m.data) == b"\x05")
    drain(bus)
    send(bus, 0x080, b"")
    t2 = recv_id(bus, 0x280 + NODE)
    checks.check(t2 is not None and len(t2.data) == 4, f"TPDO2 now 4 bytes (got {bytes(t2.data).hex() if t2 else None})")

    # NMT reset communication: boot-up, the communication objects back to the description's.
    send(bus, 0x000, [0x82, NODE])
    boot = recv_id(bus, 0x700 + NODE, timeout=2.0, pred=lambda m: bytes(m.data) == b"\x00")
    checks.check(boot is not None, "boot-up after NMT reset communication")
    r = upload(bus, 0x1A01, 0)
    checks.check(r is not None and r[0] == 0x4F and r[4] == 2, f"TPDO2 mapping back to 2 entries (got {r.hex() if r else None})")
    send(bus, 0x000, [0x01, NODE])
    recv_id(bus, 0x700 + NODE, timeout=2.0, pred=lambda m: bytes(m.data) == b"\x05")
    drain(bus)
    send(bus, 0x080, b"")
    a = answer(bus)
    checks.check(a is not None and a[4] == periods, f"TPDO2 of 8 bytes again, periods stepped kept (got {a})")


def realtime_checks(args, src, tmp, bus, checks):
    """Realtime: enabled with SYNCs and the master's heartbeat, then the heartbeat stops (SYNCs go on):
    fault 0x8130 and its EMCY within the consumer time (350 ms, master.heartbeat_timeout_ms)."""
    log = open(os.path.join(tmp, "drive_rt.log"), "w+")
    drive = subprocess.Popen(
        [args.drive, "--config", os.path.join(src, "configs/system.yaml"), "--clock", "realtime",
         "--scenario", os.path.join(src, "configs/scenarios/pulse.yaml"),
         "--canopen-config", os.path.join(src, "configs/canopen/drive.yaml"),
         "--canopen-set", "drive.sync_timeout_ms=2000",
         "--dictionary", os.path.join(src, "configs/canopen/virtual_drive_od.yaml"),
         "--can-group", args.group, "--can-port", str(args.port), "--can-iface", "127.0.0.1",
         "--domain", str(args.domain), "--profiles", os.path.join(src, "configs/dds/profiles.xml")],
        stdout=log, stderr=subprocess.STDOUT)
    try:
        if not checks.check(recv_id(bus, 0x700 + NODE, timeout=10.0, pred=lambda m: bytes(m.data) == b"\x00")
                            is not None, "realtime drive: boot-up"):
            return
        send(bus, 0x000, [0x01, NODE])
        heartbeat = [0x05]
        for cw in (0x06, 0x07, 0x0F):
            send(bus, 0x77F, heartbeat)
            send(bus, 0x200 + NODE, struct.pack("<HhI", cw, 0, 0))
            send(bus, 0x080, b"")
            time.sleep(0.01)
        t_end = time.monotonic() + 0.5
        next_heartbeat = 0.0
        while time.monotonic() < t_end:  # enabled, master alive: SYNC every 5 ms, heartbeat every 100 ms
            if time.monotonic() >= next_heartbeat:
                send(bus, 0x77F, heartbeat)
                next_heartbeat = time.monotonic() + 0.1
            send(bus, 0x080, b"")
            time.sleep(0.005)
        r = upload(bus, 0x6041, 0)
        enabled = r is not None and (struct.unpack_from("<H", r, 4)[0] & 0x6F) == 0x27
        checks.check(enabled, f"realtime drive enabled by controlword (statusword {r.hex() if r else None})")
        stopped_at = time.monotonic()
        emcy = None
        next_sync = 0.0
        while time.monotonic() - stopped_at < 2.0 and emcy is None:  # SYNCs go on every 5 ms
            if time.monotonic() >= next_sync:
                send(bus, 0x080, b"")
                next_sync = time.monotonic() + 0.005
            m = bus.recv(timeout=0.001)
            if m is not None and m.arbitration_id == 0x80 + NODE and bytes(m.data)[:2] == b"\x30\x81":
                emcy = time.monotonic()
        checks.check(emcy is not None, "master heartbeat stopped: EMCY 0x8130 (heartbeat error)")
        if emcy is not None:
            print(f"master heartbeat stopped -> EMCY 0x8130 after {1e3 * (emcy - stopped_at):.0f} ms "
                  f"(consumer time 350 ms, the last heartbeat up to 100 ms before)")
            checks.check(emcy - stopped_at < 0.35 + 0.3, "within the consumer time (plus scheduling slack)")
        r = upload(bus, 0x6041, 0)
        checks.check(r is not None and (struct.unpack_from("<H", r, 4)[0] & 0x4F) in (0x08, 0x0F),
                     f"statusword: fault reaction active or fault, force off (got {r.hex() if r else None})")
    finally:
        stop(drive, timeout=5)
        log.seek(0)
        print("---- realtime drive output ----\n" + log.read() + "----------------------")


if __name__ == "__main__":
    sys.exit(main())
