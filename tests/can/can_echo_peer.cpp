// can_echo_peer: a UdpMulticastBus node that answers every frame it hears with the same
// frame, id + 1 (wrapping within 11 or 29 bits), for python_can_peer.py to check against
// python-can. Exits after --count frames (0) or at --timeout (3: heard nothing,
// 4: heard some); a bad command line or bus parameter exits 2, a socket error 1.
//
// Prints on stdout, one line each: "READY <bus>" once listening, "ECHO <in> -> <out>" per
// frame, "EXTRA <frame>" for frames heard after the last echo, and at the end
// "COUNTERS sent=.. received=.. send_errors=.. receive_errors=.. malformed_dropped=..
// own_echo_dropped=.. unsupported_dropped=..".
//
//   can_echo_peer --group 239.74.163.2 --port 43113 [--iface 127.0.0.1] [--ttl 1]
//                 [--count 10] [--timeout 10] [--linger 0.3] [--corrupt]
//
// --corrupt flips bit 0 of the first data byte of every echo, to show the checker fails.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>

#include "pmlsm/can/can_bus.hpp"
#include "pmlsm/can/udp_multicast_bus.hpp"
#include "pmlsm/util/exit_codes.hpp"

namespace {

using pmlsm::can::CanFrame;
using Clock = std::chrono::steady_clock;

void print(const char* tag, const CanFrame& f) {
  std::printf("%s %s 0x%0*X dlc %u%s [", tag, f.extended ? "ext" : "std", f.extended ? 8 : 3,
              static_cast<unsigned>(f.id), static_cast<unsigned>(f.dlc), f.rtr ? " rtr" : "");
  for (unsigned i = 0; i < f.dlc && !f.rtr; ++i) std::printf(i ? " %02X" : "%02X", f.data[i]);
  std::printf("]");
}

int usage(const std::string& why) {
  std::fprintf(stderr,
               "can_echo_peer: %s\nusage: can_echo_peer --group ADDR --port N [--iface ADDR] [--ttl N] "
               "[--count N] [--timeout S] [--linger S] [--corrupt]\n",
               why.c_str());
  return pmlsm::kExitBadConfig;
}

std::chrono::nanoseconds seconds(double s) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(s));
}

}  // namespace

int main(int argc, char** argv) {
  pmlsm::can::UdpMulticastParams params;
  long count = 10;
  double timeout_s = 10.0;
  double linger_s = 0.3;
  bool corrupt = false;
  bool have_group = false, have_port = false;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(arg + " needs a value");
        return argv[++i];
      };
      if (arg == "--group") {
        params.group = value();
        have_group = true;
      } else if (arg == "--port") {
        params.port = std::stoi(value());
        have_port = true;
      } else if (arg == "--iface") {
        params.interface_address = value();
      } else if (arg == "--ttl") {
        params.ttl = std::stoi(value());
      } else if (arg == "--count") {
        count = std::stol(value());
      } else if (arg == "--timeout") {
        timeout_s = std::stod(value());
      } else if (arg == "--linger") {
        linger_s = std::stod(value());
      } else if (arg == "--corrupt") {
        corrupt = true;
      } else {
        return usage("unknown argument " + arg);
      }
    }
  } catch (const std::exception& e) {
    return usage(std::string("bad argument: ") + e.what());
  }
  if (!have_group || !have_port) return usage("--group and --port are required");
  if (count < 1 || !(timeout_s > 0) || !(linger_s >= 0)) {
    return usage("--count must be >= 1, --timeout > 0, --linger >= 0");
  }

  std::unique_ptr<pmlsm::can::UdpMulticastBus> bus;
  try {
    bus = std::make_unique<pmlsm::can::UdpMulticastBus>(params);
  } catch (const std::invalid_argument& e) {
    return usage(e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "can_echo_peer: %s\n", e.what());
    return pmlsm::kExitError;
  }
  std::printf("READY %s\n", bus->describe().c_str());
  std::fflush(stdout);

  const auto deadline = Clock::now() + seconds(timeout_s);
  long echoed = 0;
  bool send_failed = false;
  CanFrame in{};
  while (echoed < count) {
    const auto now = Clock::now();
    if (now >= deadline) break;
    if (!bus->receive(in, deadline - now)) continue;
    CanFrame out = in;
    out.id = (in.id + 1) & (in.extended ? pmlsm::can::kMaxExtendedId : pmlsm::can::kMaxStandardId);
    if (corrupt && !out.rtr && out.dlc > 0) out.data[0] ^= 0x01;
    if (!bus->send(out)) send_failed = true;
    ++echoed;
    print("ECHO", in);
    print(" ->", out);
    std::printf("\n");
    std::fflush(stdout);
  }
  // Whatever else arrives (our own echoes are dropped here and counted).
  while (bus->receive(in, seconds(linger_s))) {
    print("EXTRA", in);
    std::printf("\n");
  }
  const pmlsm::can::CanBusCounters c = bus->counters();
  std::printf(
      "COUNTERS sent=%llu received=%llu send_errors=%llu receive_errors=%llu malformed_dropped=%llu "
      "own_echo_dropped=%llu unsupported_dropped=%llu\n",
      static_cast<unsigned long long>(c.sent), static_cast<unsigned long long>(c.received),
      static_cast<unsigned long long>(c.send_errors), static_cast<unsigned long long>(c.receive_errors),
      static_cast<unsigned long long>(c.malformed_dropped), static_cast<unsigned long long>(c.own_echo_dropped),
      static_cast<unsigned long long>(c.unsupported_dropped));
  std::fflush(stdout);
  if (echoed == 0) {
    std::fprintf(stderr, "can_echo_peer: no frame within %.3g s\n", timeout_s);
    return pmlsm::kExitPeerMissing;
  }
  if (echoed < count) {
    std::fprintf(stderr, "can_echo_peer: %ld of %ld frames within %.3g s\n", echoed, count, timeout_s);
    return pmlsm::kExitPeerLost;
  }
  return send_failed ? pmlsm::kExitError : pmlsm::kExitOk;
}
