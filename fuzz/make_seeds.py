#!/usr/bin/env python3
"""Writes the seed corpora of fuzz/corpus/<target>/ from the shipped files and hand-made valid
inputs (frames, datagrams, a tiny MCAP file, CDR samples). Run from anywhere; it overwrites the
seeds it makes and leaves other files in the corpus directories alone."""
import pathlib
import shutil
import struct
import subprocess
import zlib

root = pathlib.Path(__file__).resolve().parent.parent
corpus = root / "fuzz" / "corpus"


def put(target, name, data):
    d = corpus / target
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data if isinstance(data, bytes) else data.encode())


def copy(target, path):
    put(target, path.name, path.read_bytes())


# ---- configs, launch files, weights: the shipped files ------------------------------------------
copy("config_system", root / "configs/system.yaml")
for p in sorted((root / "configs/scenarios").glob("*.yaml")):
    copy("config_scenario", p)
copy("config_training", root / "configs/training.yaml")
copy("config_training", root / "configs/training_robust.yaml")
copy("config_canopen", root / "configs/canopen/drive.yaml")
copy("weights_file", root / "configs/rnn_weights.yaml")
for p in sorted((root / "launch").glob("*.yaml")):
    copy("launch_file", p)
put("launch_file", "with_args.yaml", "#arg controller=pi\n#arg bad\n" + (root / "launch/sim.yaml").read_text())

# Hostile YAML for every YAML parser: nesting deeper than yaml-cpp's guard, an alias bomb.
hostile = {
    "deep_flow.yaml": "a: " + "[" * 5000 + "]" * 5000 + "\n",
    "deep_map.yaml": "a: " + "{a: " * 3000 + "1" + "}" * 3000 + "\n",
    "alias_bomb.yaml": "a: &a [x,x,x,x,x,x,x,x,x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [" + ",".join(["*" + chr(97 + i)] * 9) + "]\n" for i in range(8)),
}
for target in ["config_system", "config_scenario", "config_training", "config_canopen", "weights_file",
               "launch_file"]:
    for name, text in hostile.items():
        put(target, name, text)

# --set overrides: byte 0 picks system (0), scenario (1), training (2), CANopen (3).
put("config_override", "system.txt", "\x00timing.control_period_s=0.001\nplant.max_step_s=1e-4\n")
put("config_override", "system_bad.txt", "\x00plant.nonexistent=1\n=2\nnoequals\n")
put("config_override", "scenario.txt", "\x01command.amplitude_mps=0.1\nduration_s=1.5\n")
put("config_override", "training.txt", "\x02population_size=20\nseed=7\noptimiser=cmaes\n")
put("config_override", "canopen.txt", "\x03drive.node_id=5\nmaster.lockstep.sync_retries=2\n")

# ---- IDL and CDR ---------------------------------------------------------------------------------
stamp = (root / "idl/Stamp.idl").read_text()


def flattened(name):
    own = "".join(l + "\n" for l in (root / f"idl/{name}.idl").read_text().splitlines()
                  if not l.startswith("#include"))
    return own if name == "Stamp" else stamp + own


for name in ["MotorFeedback", "NetworkWeights", "NodeStatus", "DriveState", "TrainingSetup"]:
    put("idl_schema", name + ".txt", f"pmlsm_msgs::msg::{name}\n" + flattened(name))
put("idl_schema", "constructs.txt", """fz::All
module fz {
  const long N = 3;
  const unsigned long M = N * 2 + (4 - 1);
  const string LABEL = "a } b";
  typedef float Triple[N];
  typedef sequence<Triple, 4> Triples;
  enum Colour { RED, @value(9) GREEN, BLUE };
  /* block
     comment */
  module in { @appendable struct Leaf { octet b; string tag; }; };
  @final struct All : in::Leaf {
    @key boolean flag; char c; int8 i8; uint8 u8; int16 i16; uint16 u16;
    int32 i32; uint32 u32; int64 i64; uint64 u64;
    short s; unsigned short us; long l; unsigned long ul; long long ll; unsigned long long ull;
    float f; double d; Colour colour;
    string<6> bounded; Triple t; Triples ts;
    sequence<in::Leaf> leaves; sequence<string<3>, M> names;
    double grid[2][2]; ::fz::in::Leaf pair[2];
  };
};
""")

# cdr_decode: byte 0 picks the schema (cdr_decode.cpp's order), then the encapsulation header.
schemas = ["Stamp", "DriveState", "DriveControl", "MotorFeedback", "PlantTruth", "ForceCommand",
           "NetworkWeights", "TrainerProgress", "NodeStatus", "TrainingSetup", "EvaluationRequest",
           "EvaluationResult", "WorkerStatus", "fz::All"]
for i, name in enumerate(schemas):
    tag = name.replace("::", "_")
    put("cdr_decode", f"{i:02d}_{tag}_le.bin", bytes([i, 0, 1, 0, 0]) + bytes(range(1, 97)))
    put("cdr_decode", f"{i:02d}_{tag}_be.bin", bytes([i, 0, 0, 0, 0]) + bytes(96))
# NetworkWeights, little endian: stamp, version, layer_sizes [3,6,6,3,1], 3 weights, scale, gain,
# cost, source "seed".
weights = struct.pack("<QqqQ", 12, 1, 2, 3) + struct.pack("<I5H", 5, 3, 6, 6, 3, 1) + bytes(2)
weights += struct.pack("<I", 3) + struct.pack("<3d", 0.5, -0.25, 1.0)
weights += struct.pack("<3d", 0.02, 300.0, 5.3) + struct.pack("<I", 5) + b"seed\0"
put("cdr_decode", "06_NetworkWeights_values.bin", bytes([6, 0, 1, 0, 0]) + weights)


# ---- MCAP ----------------------------------------------------------------------------------------
def mstr(s):
    b = s.encode()
    return struct.pack("<I", len(b)) + b


def record(op, content):
    return struct.pack("<BQ", op, len(content)) + content


magic = b"\x89MCAP0\r\n"
idl = flattened("ForceCommand")
schema = record(0x03, struct.pack("<H", 1) + mstr("pmlsm_msgs::msg::ForceCommand") + mstr("omgidl") + mstr(idl))
meta = mstr("offered_qos_profiles") + mstr("")
channel = record(0x04, struct.pack("<HH", 0, 1) + mstr("/pmlsm/force_command") + mstr("cdr") +
                 struct.pack("<I", len(meta)) + meta)
messages = b"".join(record(0x05, struct.pack("<HIQQ", 0, k, 1000 * k, 1000 * k) + bytes([0, 1, 0, 0]) +
                           struct.pack("<QqqdQ", k, k, k, 0.5 * k, k)) for k in range(3))
inner = schema + channel + messages
header = record(0x01, mstr("ros2") + mstr("pmlsm fuzz seed"))


def compress(tool, data):
    # The zstd and lz4 command-line tools write the frame formats MCAP uses.
    return subprocess.run([tool, "-c", "-q"], input=data, stdout=subprocess.PIPE, check=True).stdout


def mcap_file(compression):
    records = inner if compression == "" else compress(compression, inner)
    chunk = record(0x06, struct.pack("<QQQI", 0, 2000, len(inner), zlib.crc32(inner)) + mstr(compression) +
                   struct.pack("<Q", len(records)) + records)
    data = magic + header + chunk
    data_end = record(0x0F, struct.pack("<I", zlib.crc32(data)))
    summary_start = len(data) + len(data_end)
    statistics = record(0x0B, struct.pack("<QHII", 3, 1, 1, 1) + struct.pack("<QQ", 0, 2000) + struct.pack("<I", 0))
    summary = schema + channel + statistics
    footer_head = struct.pack("<BQ", 0x02, 20) + struct.pack("<QQ", summary_start, 0)
    footer = footer_head + struct.pack("<I", zlib.crc32(summary + footer_head))
    return data + data_end + summary + footer + magic, len(chunk)


mcap, chunk_bytes = mcap_file("")
put("mcap_reader", "three_messages.mcap", mcap)
put("mcap_reader", "three_messages_zstd.mcap", mcap_file("zstd")[0])
put("mcap_reader", "three_messages_lz4.mcap", mcap_file("lz4")[0])
put("mcap_reader", "unchunked.mcap", magic + header + schema + channel + messages +
    record(0x0F, struct.pack("<I", 0)) + struct.pack("<BQ", 0x02, 20) + bytes(20) + magic)
put("mcap_reader", "truncated.mcap", mcap[: len(magic + header) + chunk_bytes // 2])

# ---- Foxglove client messages: one per line, 'B' = binary ----------------------------------------
put("foxglove_protocol", "subscribe.txt",
    '{"op":"subscribe","subscriptions":[{"id":1,"channelId":1},{"id":2,"channelId":3}]}\n'
    '{"op":"unsubscribe","subscriptionIds":[1]}\n'
    '{"op":"subscribe","subscriptions":[{"id":1,"channelId":2}]}\n')
put("foxglove_protocol", "rejects.txt",
    '{"op":"subscribe","subscriptions":[{"id":5,"channelId":99}]}\n'
    '{"op":"getParameters","parameterNames":["a"]}\n'
    '{"op":"unsubscribe","subscriptionIds":[42]}\n'
    '{"op":"subscribe","subscriptions":[{"id":5,"channelId":1},{"id":5,"channelId":2}]}\n')
put("foxglove_protocol", "malformed.txt", '{"op":"subscribe","subscriptions":[{"id":-1,"channelId":"x"}]}\n')
put("foxglove_protocol", "binary.txt", "B\x01\x00\x00\x00\x00\n")


# ---- CANopen frames: flags, id (2 bytes), 8 data bytes, elapsed ms (canopen_input.hpp) -----------
def frame(cob_id, data, bits=0, elapsed=1, rtr=False):
    flags = (len(data) << 4) | (bits << 2) | (1 if rtr else 0)
    return bytes([flags]) + struct.pack("<H", cob_id) + bytes(data).ljust(8, b"\0") + bytes([elapsed])


put("canopen_sdo", "server_requests.bin",
    frame(0x605, [0x40, 0x41, 0x60, 0, 0, 0, 0, 0]) +
    frame(0x605, [0x2B, 0x40, 0x60, 0, 0x06, 0, 0, 0]) +
    frame(0x605, [0x2F, 0x60, 0x60, 0, 10, 0, 0, 0]) +
    frame(0x605, [0x23, 0x00, 0x14, 1, 0x05, 0x02, 0, 0x80]) +
    frame(0x605, [0x80, 0x41, 0x60, 0, 0, 0, 4, 5]) +
    frame(0x605, [0x00, 0x41, 0x60, 0, 0, 0, 0, 0]))
put("canopen_sdo", "client_responses.bin",
    frame(0x585, [0x4B, 0x41, 0x60, 0, 0x37, 0x02, 0, 0], bits=1) +
    frame(0x585, [0x60, 0x40, 0x60, 0, 0, 0, 0, 0], bits=2) +
    frame(0x585, [0x80, 0x40, 0x60, 0, 0, 0, 2, 6], bits=2) +
    frame(0x585, [0x41, 0x41, 0x60, 0, 8, 0, 0, 0], bits=1) +
    frame(0x585, [0x60, 0x40, 0x60, 0, 0, 0, 0, 0], bits=1, elapsed=200))
# The PDO remapping procedure over SDO: invalidate RPDO1, sub 0 = 0, one entry, sub 0 = 1, valid.
put("canopen_sdo", "remap.bin",
    frame(0x605, [0x23, 0x00, 0x14, 1, 0x05, 0x02, 0, 0x80]) +
    frame(0x605, [0x2F, 0x00, 0x16, 0, 0, 0, 0, 0]) +
    frame(0x605, [0x23, 0x00, 0x16, 1, 0x10, 0x00, 0x71, 0x60]) +
    frame(0x605, [0x2F, 0x00, 0x16, 0, 1, 0, 0, 0]) +
    frame(0x605, [0x23, 0x00, 0x14, 1, 0x05, 0x02, 0, 0x00]))
put("canopen_frames", "nmt_heartbeat_sync_emcy.bin",
    frame(0x000, [0x01, 5]) + frame(0x705, [0x05]) + frame(0x705, [0x00]) + frame(0x080, []) +
    frame(0x080, [3]) + frame(0x085, [0x10, 0x23, 0x02, 1, 2, 3, 4, 5]) + frame(0x085, [0, 0, 0, 0, 0, 0, 0, 0]) +
    frame(0x000, [0x02, 0]) + frame(0x000, [0x80, 5]) + frame(0x000, [0x81, 5]) +
    frame(0x705, [0x7F], elapsed=120) + frame(0x000, [0x82, 0]))
put("canopen_frames", "rpdo.bin",
    frame(0x000, [0x01, 5]) + frame(0x205, [0x0F, 0x00, 0x64, 0x00]) + frame(0x205, [0x0F, 0x00]) +
    frame(0x205, [0x0F, 0x00, 0x64, 0x00, 1, 2, 3, 4, 5]) +
    frame(0x205, [0x10, 0x00, 0x71, 0x60, 0x10, 0x00, 0x40, 0x60], bits=1) + frame(0x205, [1, 2, 3, 4]))


# ---- UDP-multicast datagrams (python-can's msgpack map) ------------------------------------------
def fixstr(s):
    return bytes([0xA0 | len(s)]) + s.encode()


def mp_uint(v):
    if v < 0x80:
        return bytes([v])
    if v < 0x100:
        return bytes([0xCC, v])
    if v < 0x10000:
        return b"\xcd" + struct.pack(">H", v)
    return b"\xce" + struct.pack(">I", v)


def datagram(cob_id, data, extended=False, remote=False):
    b = lambda v: b"\xc3" if v else b"\xc2"
    fields = [("timestamp", b"\xcb" + struct.pack(">d", 0.0)), ("arbitration_id", mp_uint(cob_id)),
              ("is_extended_id", b(extended)), ("is_remote_frame", b(remote)), ("is_error_frame", b(False)),
              ("channel", b"\xc0"), ("dlc", mp_uint(len(data))),
              ("data", b"\xc4" + bytes([0 if remote else len(data)]) + (b"" if remote else bytes(data))),
              ("is_fd", b(False)), ("bitrate_switch", b(False)), ("error_state_indicator", b(False))]
    return bytes([0x80 | len(fields)]) + b"".join(fixstr(k) + v for k, v in fields)


put("can_pycan_wire", "sdo.bin", datagram(0x605, [0x40, 0x41, 0x60, 0, 0, 0, 0, 0]))
put("can_pycan_wire", "sync.bin", datagram(0x080, []))
put("can_pycan_wire", "extended.bin", datagram(0x1ABCDE, [1, 2, 3], extended=True))
put("can_pycan_wire", "remote.bin", datagram(0x705, [0], remote=True))


# ---- EtherCAT frames (Ethernet, EtherType 0x88A4): a broadcast read, and an LRW behind an FPRD ----
def ecat_datagram(cmd, idx, address, data, more, wkc=0):
    return struct.pack("<BBIHH", cmd, idx, address, len(data) | (0x8000 if more else 0), 0) + bytes(data) + \
        struct.pack("<H", wkc)


def ecat_frame(datagrams):
    body = b"".join(datagrams)
    frame = b"\xff" * 6 + b"\x02\x00\x00\x00\x00\x01" + b"\x88\xa4" + struct.pack("<H", len(body) | 0x1000) + body
    return frame + b"\x00" * max(0, 60 - len(frame))


put("ethercat_frames", "brd_al_status.bin", ecat_frame([ecat_datagram(7, 1, 0x01300000, [0, 0], False, 2)]))
put("ethercat_frames", "fprd_lrw.bin", ecat_frame([ecat_datagram(4, 2, 0x01301001, [8, 0], True, 1),
                                                   ecat_datagram(12, 3, 0x00010000, range(12), False, 3)]))
def framed(*frames):
    return b"".join(struct.pack("<H", len(f)) + f for f in frames)


# A master's start: station address by position, mailbox sync managers, PREOP, an SII read.
put("ethercat_slave", "bring_up.bin", framed(
    ecat_frame([ecat_datagram(2, 1, 0x00100000, [0x01, 0x10], False)]),
    ecat_frame([ecat_datagram(5, 2, 0x08001001, [0x00, 0x10, 0x80, 0, 0x26, 0, 1, 0], True),
                ecat_datagram(5, 3, 0x08081001, [0x80, 0x10, 0x80, 0, 0x22, 0, 1, 0], False)]),
    ecat_frame([ecat_datagram(5, 4, 0x01201001, [2, 0], False)]),
    ecat_frame([ecat_datagram(5, 5, 0x05021001, [0, 1, 8, 0, 0, 0], True),
                ecat_datagram(4, 6, 0x05081001, [0] * 8, False)]),
    # An SDO upload of 0x1000 over CoE into the receive mailbox, then the send mailbox read.
    ecat_frame([ecat_datagram(5, 7, 0x10001001, list(struct.pack("<HHBB", 10, 0, 0, 0x13)) +
                              list(struct.pack("<H", 0x2000)) + [0x40, 0x00, 0x10, 0, 0, 0, 0, 0] + [0] * 112,
                              False)]),
    ecat_frame([ecat_datagram(4, 8, 0x10801001, [0] * 128, False)])))
# An SII image: the fixed part, a strings category (three strings) and a general category.
fixed = bytearray(128)
struct.pack_into("<IIII", fixed, 16, 0x6A, 0x414B44, 2, 7)
strings = bytes([3, 5]) + b"Drive" + bytes([3]) + b"D-1" + bytes([7]) + b"a drive"
strings += b"\0" * (len(strings) % 2)
general = bytes([1, 0, 2, 3]) + bytes(28)
put("ethercat_sii", "small.bin", bytes(fixed) + struct.pack("<HH", 10, len(strings) // 2) + strings +
    struct.pack("<HH", 30, len(general) // 2) + general + struct.pack("<HH", 0xFFFF, 0xFFFF))
# A capture: section header, an Ethernet interface in nanoseconds, two packets (the SDO upload
# request above, and an EtherCAT frame over UDP to port 34980).
def pcapng_block(kind, body):
    body = body + b"\0" * (-len(body) % 4)
    return struct.pack("<II", kind, len(body) + 12) + body + struct.pack("<I", len(body) + 12)
def packet(frame, time_ns):
    return pcapng_block(6, struct.pack("<IIIII", 0, time_ns >> 32, time_ns & 0xFFFFFFFF, len(frame), len(frame)) +
                        frame)
sdo_request = ecat_frame([ecat_datagram(5, 7, 0x10001001, list(struct.pack("<HHBB", 10, 0, 0, 0x13)) +
                                        list(struct.pack("<H", 0x2000)) + [0x40, 0x00, 0x10, 0, 0, 0, 0, 0], False, 1)])
payload = sdo_request[14:]
ip = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 28 + len(payload), 0, 0, 64, 17, 0, bytes(4), bytes([255] * 4))
udp = struct.pack(">HHHH", 34980, 34980, 8 + len(payload), 0)
over_udp = bytes([0xFF] * 6 + [0] * 6 + [0x08, 0x00]) + ip + udp + payload
put("ethercat_pcapng", "two_frames.pcapng",
    pcapng_block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1)) +
    pcapng_block(1, struct.pack("<HHIHH", 1, 0, 0, 9, 1) + bytes([9, 0, 0, 0]) + bytes(4)) +
    packet(bytes(sdo_request), 1_700_000_000_000_000_000) + packet(over_udp, 1_700_000_000_000_001_000))
print("seeds written under", corpus)
