#!/usr/bin/env python3
"""python-can as an independent peer of our UdpMulticastBus.

Starts tests/can/can_echo_peer (our C++ bus: it answers every frame with the same frame,
id + 1), opens python-can's own "udp_multicast" bus on the same group and port, sends
frames with assorted ids, DLCs, data and remote flags, and checks every field of every
echo. Then checks the peer's counters: it heard each frame once, never its own echoes
(else it would echo its echoes: id + 2, ...), and nothing malformed.

    python_can_peer.py PATH/TO/can_echo_peer [--group ADDR] [--port N] [--iface ADDR]
                       [--timeout S] [--corrupt-peer]

--iface is the peer's interface ("0.0.0.0": the default route's, which is where python-can
joins; "127.0.0.1" works on the same host too). --corrupt-peer makes the peer flip a data
bit in every echo: the run must then FAIL (a check that this test can fail).

Exit: 0 PASS, 1 FAIL, 2 bad command line, 77 skipped (python-can is not installed).
"""

import argparse
import os
import select
import socket
import subprocess
import sys
import time

SKIP = 77

try:
    import can
except ImportError as error:  # python3-can missing (or another interpreter than Debian's)
    print(
        f"SKIP: python-can (Debian: python3-can) is not importable by {sys.executable}: {error}"
    )
    sys.exit(SKIP)


def free_udp_port():
    """A port the kernel hands out as free right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def fmt(m):
    kind = "ext" if m.is_extended_id else "std"
    width = 8 if m.is_extended_id else 3
    rtr = " rtr" if m.is_remote_frame else ""
    return f"{kind} 0x{m.arbitration_id:0{width}X} dlc {m.dlc}{rtr} [{bytes(m.data).hex(' ')}]"


def same_frame(a, b):
    return (
        a.arbitration_id == b.arbitration_id
        and a.is_extended_id == b.is_extended_id
        and a.is_remote_frame == b.is_remote_frame
        and a.dlc == b.dlc
        and bytes(a.data) == bytes(b.data)
    )


def frames_to_send():
    """Both id widths at their edges (0x7FF and 0x1FFFFFFF wrap to 0 in the echo), every
    DLC 0..8, remote frames, data bytes 0x00..0xFF."""
    std, ext = False, True
    spec = [
        (0x000, std, False, 0, b""),
        (0x001, std, False, 1, b"\x00"),
        (0x123, std, False, 3, b"\x01\x02\x03"),
        (0x2AA, std, False, 8, bytes([0x00, 0x11, 0x22, 0x7F, 0x80, 0xAA, 0xFE, 0xFF])),
        (0x555, std, False, 6, b"\xde\xad\xbe\xef\x00\x01"),
        (0x7FE, std, False, 8, b"\xff" * 8),
        (0x7FF, std, False, 2, b"\x80\x7f"),
        (0x00000000, ext, False, 0, b""),
        (0x000007FF, ext, False, 4, b"\x04\x03\x02\x01"),
        (0x01ABCDEF, ext, False, 5, b"\x10\x20\x30\x40\x50"),
        (0x01555555, ext, False, 7, bytes(range(7))),
        (0x1FFFFFFE, ext, False, 8, bytes(range(0xF8, 0x100))),
        (0x1FFFFFFF, ext, False, 8, b"\x00\xff\x00\xff\x00\xff\x00\xff"),
        (0x100, std, True, 0, b""),
        (0x200, std, True, 3, b""),
        (0x01234567, ext, True, 8, b""),
    ]
    return [
        can.Message(
            arbitration_id=i, is_extended_id=x, is_remote_frame=r, dlc=d, data=data, check=True
        )
        for i, x, r, d, data in spec
    ]


def expected_echo(m):
    mask = 0x1FFFFFFF if m.is_extended_id else 0x7FF
    return can.Message(
        arbitration_id=(m.arbitration_id + 1) & mask,
        is_extended_id=m.is_extended_id,
        is_remote_frame=m.is_remote_frame,
        dlc=m.dlc,
        data=m.data,
    )


class Checks:
    def __init__(self):
        self.passed = []
        self.failed = []

    def check(self, ok, what):
        (self.passed if ok else self.failed).append(what)
        print(f"  {'ok  ' if ok else 'FAIL'} {what}")
        return ok


def read_line(stream, deadline):
    """One line from the peer's stdout, or None at the deadline or end of file."""
    line = b""
    while not line.endswith(b"\n"):
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([stream], [], [], left)[0]:
            return None
        byte = os.read(stream.fileno(), 1)
        if not byte:
            return None
        line += byte
    return line.decode(errors="replace").rstrip("\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("peer", help="path to the can_echo_peer program")
    pid = os.getpid()
    parser.add_argument("--group", default=f"239.74.{(pid >> 8) & 0xFF}.{pid & 0xFF}")
    parser.add_argument("--port", type=int, default=0, help="0: a free port")
    parser.add_argument("--iface", default="0.0.0.0", help="the C++ peer's interface address")
    parser.add_argument("--timeout", type=float, default=2.0, help="seconds to wait for each echo")
    parser.add_argument("--corrupt-peer", action="store_true")
    args = parser.parse_args()
    port = args.port or free_udp_port()
    frames = frames_to_send()

    print(f"python-can {can.__version__} (python {sys.version.split()[0]}) <-> {args.peer}")
    print(f"group {args.group} port {port}, C++ peer on interface {args.iface}")
    checks = Checks()
    if not checks.check(os.access(args.peer, os.X_OK), f"peer program {args.peer} is executable"):
        return summary(checks)

    try:
        bus = can.Bus(interface="udp_multicast", channel=args.group, port=port, hop_limit=1, fd=False)
    except can.CanInterfaceNotImplementedError as error:  # msgpack missing
        print(f"SKIP: python-can's udp_multicast interface is unavailable: {error}")
        return SKIP
    except Exception as error:  # noqa: BLE001 - report whatever python-can raises
        checks.check(False, f"python-can opens udp_multicast {args.group}:{port}: {error!r}")
        return summary(checks)

    command = [
        args.peer, "--group", args.group, "--port", str(port), "--iface", args.iface,
        "--count", str(len(frames)), "--timeout", str(10 + len(frames) * args.timeout),
    ]
    if args.corrupt_peer:
        command.append("--corrupt")
    peer = subprocess.Popen(command, stdout=subprocess.PIPE)
    peer_lines = []
    try:
        ready = read_line(peer.stdout, time.monotonic() + 10)
        if not checks.check(ready is not None and ready.startswith("READY"),
                            f"C++ peer is listening: {ready}"):
            return summary(checks)

        own_pending = []  # python-can hears itself (4.1 has no own-echo filter)
        own_copies = 0
        for sent in frames:
            bus.send(sent)
            own_pending.append(sent)
            want = expected_echo(sent)
            deadline = time.monotonic() + args.timeout
            while True:
                left = deadline - time.monotonic()
                try:
                    got = bus.recv(timeout=max(left, 0))
                except can.CanOperationError as error:
                    checks.check(False, f"python-can could not decode a datagram: {error!r} "
                                        f"(cause {error.__cause__!r})")
                    continue
                if got is None:
                    checks.check(False, f"echo of {fmt(sent)}: none within {args.timeout} s")
                    break
                own = next((m for m in own_pending if same_frame(m, got)), None)
                if own is not None:
                    own_pending.remove(own)
                    own_copies += 1
                    continue
                if got.arbitration_id == want.arbitration_id and got.is_extended_id == want.is_extended_id:
                    problems = [
                        f"{name} {getattr(got, name)!r} != {getattr(want, name)!r}"
                        for name in ("is_remote_frame", "dlc", "is_fd", "is_error_frame")
                        if getattr(got, name) != getattr(want, name)
                    ]
                    if bytes(got.data) != bytes(want.data):
                        problems.append(f"data {bytes(got.data).hex(' ')} != {bytes(want.data).hex(' ')}")
                    checks.check(not problems, f"{fmt(sent)} -> {fmt(got)}"
                                 + ("" if not problems else ": " + "; ".join(problems)))
                    break
                checks.check(False, f"while waiting for {fmt(want)}: unexpected {fmt(got)}")

        # Nothing more may come: an echo of an echo (id + 2) means the peer heard itself.
        deadline = time.monotonic() + 0.5
        extra = []
        while (left := deadline - time.monotonic()) > 0:
            try:
                got = bus.recv(timeout=left)
            except can.CanOperationError as error:
                extra.append(f"undecodable datagram ({error.__cause__!r})")
                continue
            if got is None:
                break
            own = next((m for m in own_pending if same_frame(m, got)), None)
            if own is not None:
                own_pending.remove(own)
                own_copies += 1
            else:
                extra.append(fmt(got))
        checks.check(not extra, "no frames after the last echo" + (f": {extra}" if extra else ""))

        try:
            peer.wait(timeout=15)
        except subprocess.TimeoutExpired:
            peer.kill()
            peer.wait()
        while (line := read_line(peer.stdout, time.monotonic() + 1)) is not None:
            peer_lines.append(line)
        checks.check(peer.returncode == 0, f"C++ peer exit code {peer.returncode} (0: all {len(frames)} frames echoed)")
        counters = next((l for l in peer_lines if l.startswith("COUNTERS ")), "")
        values = dict(kv.split("=") for kv in counters.split()[1:])
        n = str(len(frames))
        for key, want in (("received", n), ("sent", n), ("own_echo_dropped", n), ("malformed_dropped", "0"),
                          ("unsupported_dropped", "0"), ("send_errors", "0"), ("receive_errors", "0")):
            checks.check(values.get(key) == want, f"C++ peer {key} = {values.get(key)} (want {want})")
        print(f"  note python-can received {own_copies} of its own {len(frames)} frames back "
              f"(python-can {can.__version__} does not filter its own datagrams; our bus does)")
    finally:
        if peer.poll() is None:
            peer.kill()
            peer.wait()
        bus.shutdown()
    return summary(checks)


def summary(checks):
    total = len(checks.passed) + len(checks.failed)
    if checks.failed:
        print(f"FAIL: {len(checks.failed)} of {total} checks failed:")
        for what in checks.failed:
            print(f"  - {what}")
        return 1
    print(f"PASS: {total} of {total} checks")
    return 0


if __name__ == "__main__":
    sys.exit(main())
