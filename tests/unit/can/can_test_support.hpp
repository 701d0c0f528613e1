// Helpers shared by the CAN tests: test-unique multicast groups, python-can style datagrams
// built field by field (to break one field at a time), frame comparison.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstring>
#include <functional>
#include <ostream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#ifndef MSGPACK_NO_BOOST
#define MSGPACK_NO_BOOST
#endif
#include <msgpack.hpp>

#include "pmlsm/can/can_frame.hpp"
#include "pmlsm/can/udp_multicast_bus.hpp"

namespace pmlsm::can {

// For gtest messages (found by ADL, so in CanFrame's namespace; tests only).
inline std::ostream& operator<<(std::ostream& out, const CanFrame& f) {
  static const char* hex = "0123456789abcdef";
  out << (f.extended ? "ext " : "std ") << "id 0x" << std::hex << f.id << std::dec << " dlc " << int{f.dlc}
      << (f.rtr ? " rtr" : "") << " data";
  for (std::uint8_t b : f.data) out << ' ' << hex[b >> 4] << hex[b & 0xF];
  return out;
}

}  // namespace pmlsm::can

namespace pmlsm::can::test {

/// A port the kernel hands out as free right now (an ephemeral one, released again).
inline int free_udp_port() {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) throw std::runtime_error("socket() failed");
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof a;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), size) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &size) != 0) {
    ::close(fd);
    throw std::runtime_error("bind()/getsockname() failed");
  }
  ::close(fd);
  return ntohs(a.sin_port);
}

/// Loopback params on a group no other process uses (one group a pid: 239.192.0.0/10
/// holds 22 bits, pid_max's width) and a port no other test of this process uses: tests
/// running in parallel (ctest -j, one process a test) never hear each other.
inline UdpMulticastParams unique_params() {
  const auto pid = static_cast<unsigned>(::getpid());
  UdpMulticastParams p;
  p.group = "239." + std::to_string(192 + ((pid >> 16) & 0x3F)) + "." + std::to_string((pid >> 8) & 0xFF) + "." +
            std::to_string(pid & 0xFF);
  p.port = free_udp_port();
  p.interface_address = "127.0.0.1";
  return p;
}

/// msgpack-c's packer, plus raw bytes into its (unbuffered) sbuffer.
struct Packer : msgpack::packer<msgpack::sbuffer> {
  explicit Packer(msgpack::sbuffer& b) : msgpack::packer<msgpack::sbuffer>(b), buffer(b) {}
  msgpack::sbuffer& buffer;
};
using Field = std::pair<std::string, std::function<void(Packer&)>>;

inline std::function<void(Packer&)> uint_value(std::uint64_t v) {
  return [v](Packer& pk) { pk.pack_uint64(v); };
}
inline std::function<void(Packer&)> int_value(std::int64_t v) {
  return [v](Packer& pk) { pk.pack_int64(v); };
}
/// A MessagePack float 64 (0xcb), as Python packs a float; msgpack-c 4's pack_double()
/// packs integral values (291.0, 0.0) as integers instead.
inline std::function<void(Packer&)> float64_value(double v) {
  return [v](Packer& pk) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    char bytes[9] = {static_cast<char>(0xCB)};
    for (int i = 0; i < 8; ++i) bytes[1 + i] = static_cast<char>(bits >> (56 - 8 * i));
    pk.buffer.write(bytes, sizeof bytes);
  };
}
inline std::function<void(Packer&)> bool_value(bool v) {
  return [v](Packer& pk) { v ? pk.pack_true() : pk.pack_false(); };
}
inline std::function<void(Packer&)> bin_value(std::vector<std::uint8_t> bytes) {
  return [bytes](Packer& pk) {
    pk.pack_bin(static_cast<std::uint32_t>(bytes.size()));
    pk.pack_bin_body(reinterpret_cast<const char*>(bytes.data()), static_cast<std::uint32_t>(bytes.size()));
  };
}
inline std::function<void(Packer&)> str_value(std::string s) {
  return [s](Packer& pk) {
    pk.pack_str(static_cast<std::uint32_t>(s.size()));
    pk.pack_str_body(s.data(), static_cast<std::uint32_t>(s.size()));
  };
}

/// The 11 fields python-can 4.1's pack_message() writes, in its order.
inline std::vector<Field> python_fields(std::uint32_t id, bool extended, bool rtr, std::uint8_t dlc,
                                        std::vector<std::uint8_t> data) {
  return {
      {"timestamp", float64_value(1700000000.25)},
      {"arbitration_id", uint_value(id)},
      {"is_extended_id", bool_value(extended)},
      {"is_remote_frame", bool_value(rtr)},
      {"is_error_frame", bool_value(false)},
      {"channel", [](Packer& pk) { pk.pack_nil(); }},
      {"dlc", uint_value(dlc)},
      {"data", bin_value(std::move(data))},
      {"is_fd", bool_value(false)},
      {"bitrate_switch", bool_value(false)},
      {"error_state_indicator", bool_value(false)},
  };
}

inline std::vector<Field> without(std::vector<Field> fields, const std::string& key) {
  std::vector<Field> out;
  for (auto& f : fields) {
    if (f.first != key) out.push_back(std::move(f));
  }
  return out;
}

inline std::vector<Field> with(std::vector<Field> fields, const std::string& key, std::function<void(Packer&)> value) {
  for (auto& f : fields) {
    if (f.first == key) f.second = std::move(value);
  }
  return fields;
}

inline std::vector<std::uint8_t> pack(const std::vector<Field>& fields) {
  msgpack::sbuffer buffer;
  Packer pk(buffer);
  pk.pack_map(static_cast<std::uint32_t>(fields.size()));
  for (const auto& f : fields) {
    pk.pack_str(static_cast<std::uint32_t>(f.first.size()));
    pk.pack_str_body(f.first.data(), static_cast<std::uint32_t>(f.first.size()));
    f.second(pk);
  }
  return {reinterpret_cast<const std::uint8_t*>(buffer.data()),
          reinterpret_cast<const std::uint8_t*>(buffer.data()) + buffer.size()};
}

inline std::vector<std::uint8_t> from_hex(const std::string& hex) {
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2) {
    out.push_back(static_cast<std::uint8_t>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  }
  return out;
}

inline CanFrame make_frame(std::uint32_t id, bool extended, bool rtr, std::uint8_t dlc, std::uint8_t seed) {
  CanFrame f{id, dlc, {}, rtr, extended};
  for (std::size_t i = 0; i < f.data.size(); ++i) {
    f.data[i] = i < dlc && !rtr ? static_cast<std::uint8_t>(seed + 37 * i) : 0;
  }
  return f;
}

/// A raw UDP socket sending to `params`' group through its interface, as a foreign node.
class RawSender {
 public:
  explicit RawSender(const UdpMulticastParams& params) {
    fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
    if (fd_ < 0) throw std::runtime_error("socket() failed");
    in_addr iface{};
    ::inet_pton(AF_INET, params.interface_address.c_str(), &iface);
    ::setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_IF, &iface, sizeof iface);
    to_.sin_family = AF_INET;
    to_.sin_port = htons(static_cast<std::uint16_t>(params.port));
    ::inet_pton(AF_INET, params.group.c_str(), &to_.sin_addr);
  }
  ~RawSender() { ::close(fd_); }
  RawSender(const RawSender&) = delete;
  RawSender& operator=(const RawSender&) = delete;

  bool send(const std::vector<std::uint8_t>& datagram) const {
    return ::sendto(fd_, datagram.data(), datagram.size(), 0, reinterpret_cast<const sockaddr*>(&to_), sizeof to_) ==
           static_cast<ssize_t>(datagram.size());
  }

 private:
  int fd_ = -1;
  sockaddr_in to_{};
};

}  // namespace pmlsm::can::test
