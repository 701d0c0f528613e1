#include "pmlsm/can/udp_multicast_bus.hpp"

#include <arpa/inet.h>
#include <net/if.h>
#include <netinet/in.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "pmlsm/can/pycan_wire.hpp"
#include "receive_loop.hpp"

namespace pmlsm::can {
namespace {

std::string quoted(const std::string& s) { return "\"" + s + "\""; }

[[noreturn]] void invalid(const char* field, const std::string& requirement, const std::string& got) {
  throw std::invalid_argument(std::string(field) + ": " + requirement + ", got " + got);
}

bool is_ipv6_any(const std::string& s) { return s.empty() || s == "::" || s == "0.0.0.0"; }

// What validate() found out, for the constructor.
struct Resolved {
  int family = AF_INET;
  in_addr group4{};
  in_addr interface4{};
  in6_addr group6{};
  unsigned interface_index = 0;  // IPv6
};

Resolved resolve(const UdpMulticastParams& p) {
  Resolved r;
  if (::inet_pton(AF_INET, p.group.c_str(), &r.group4) == 1) {
    r.family = AF_INET;
    if (!IN_MULTICAST(ntohl(r.group4.s_addr))) {
      invalid("group", "must be a multicast address (224.0.0.0/4 or ff00::/8)", quoted(p.group));
    }
  } else if (::inet_pton(AF_INET6, p.group.c_str(), &r.group6) == 1) {
    r.family = AF_INET6;
    if (!IN6_IS_ADDR_MULTICAST(&r.group6)) {
      invalid("group", "must be a multicast address (224.0.0.0/4 or ff00::/8)", quoted(p.group));
    }
  } else {
    invalid("group", "must be a numeric IPv4 or IPv6 multicast address", quoted(p.group));
  }
  if (p.port < 1 || p.port > 65535) invalid("port", "must be in [1, 65535]", std::to_string(p.port));
  if (p.ttl < 0 || p.ttl > 255) invalid("ttl", "must be in [0, 255]", std::to_string(p.ttl));
  if (r.family == AF_INET) {
    if (::inet_pton(AF_INET, p.interface_address.c_str(), &r.interface4) != 1) {
      invalid("interface_address",
              "must be a local IPv4 address for an IPv4 group (\"0.0.0.0\": the default route's "
              "interface)",
              quoted(p.interface_address));
    }
  } else if (!is_ipv6_any(p.interface_address)) {
    r.interface_index = ::if_nametoindex(p.interface_address.c_str());
    if (r.interface_index == 0) {
      invalid("interface_address",
              "must name a network interface (or be \"::\" for the default route's) for an IPv6 group",
              quoted(p.interface_address));
    }
  }
  return r;
}

class Fd {
 public:
  explicit Fd(int fd) noexcept : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const noexcept { return fd_; }
  int release() noexcept { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

std::string to_string(const sockaddr_storage& a) {
  char text[INET6_ADDRSTRLEN] = {};
  if (a.ss_family == AF_INET) {
    const auto& v4 = reinterpret_cast<const sockaddr_in&>(a);
    ::inet_ntop(AF_INET, &v4.sin_addr, text, sizeof text);
    return std::string(text) + ":" + std::to_string(ntohs(v4.sin_port));
  }
  const auto& v6 = reinterpret_cast<const sockaddr_in6&>(a);
  ::inet_ntop(AF_INET6, &v6.sin6_addr, text, sizeof text);
  return "[" + std::string(text) + "]:" + std::to_string(ntohs(v6.sin6_port));
}

double wall_clock_seconds() noexcept {
  timespec now{};
  ::clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<double>(now.tv_sec) + static_cast<double>(now.tv_nsec) * 1e-9;
}

}  // namespace

void validate(const UdpMulticastParams& params) { (void)resolve(params); }

// Two sockets, for IPv4 or IPv6: the receiving one bound to the group's port and joined to it, the
// sending one with its hop limit, loopback and interface. One socket call after another, each
// checked and named in its error; split up it would only pass half-made sockets around.
// NOLINTNEXTLINE(readability-function-size)
UdpMulticastBus::UdpMulticastBus(const UdpMulticastParams& params) : params_(params) {
  const Resolved r = resolve(params_);
  family_ = r.family;
  const auto port = htons(static_cast<std::uint16_t>(params_.port));
  const std::string where = "UdpMulticastBus(group " + params_.group + ", port " + std::to_string(params_.port) +
                            ", interface " + params_.interface_address + "): ";
  auto fail = [&where](const char* call) -> void {
    const int error = errno;
    throw std::system_error(error, std::generic_category(), where + call);
  };
  auto set = [&fail](int fd, int level, int name, const void* value, socklen_t size, const char* call) {
    if (::setsockopt(fd, level, name, value, size) != 0) fail(call);
  };
  const int one = 1;
  const int ttl = params_.ttl;
  const int loop = params_.loopback ? 1 : 0;

  // Receiving socket: the group's port, shared with every other member on this host.
  Fd rx(::socket(family_, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (rx.get() < 0) fail("socket(SOCK_DGRAM)");
  set(rx.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof one, "setsockopt(SO_REUSEADDR)");
  // Sending socket: its own ephemeral port, the source address own echoes are known by.
  Fd tx(::socket(family_, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (tx.get() < 0) fail("socket(SOCK_DGRAM)");

  sockaddr_storage group{};
  socklen_t group_size = 0;
  if (family_ == AF_INET) {
    auto& g = reinterpret_cast<sockaddr_in&>(group);
    g.sin_family = AF_INET;
    g.sin_port = port;
    g.sin_addr = r.group4;
    group_size = sizeof(sockaddr_in);
    if (::bind(rx.get(), reinterpret_cast<const sockaddr*>(&g), group_size) != 0) fail("bind(group:port)");
    ip_mreq join{};
    join.imr_multiaddr = r.group4;
    join.imr_interface = r.interface4;
    set(rx.get(), IPPROTO_IP, IP_ADD_MEMBERSHIP, &join, sizeof join, "setsockopt(IP_ADD_MEMBERSHIP)");

    set(tx.get(), IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl, "setsockopt(IP_MULTICAST_TTL)");
    set(tx.get(), IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop, "setsockopt(IP_MULTICAST_LOOP)");
    if (r.interface4.s_addr != htonl(INADDR_ANY)) {
      set(tx.get(), IPPROTO_IP, IP_MULTICAST_IF, &r.interface4, sizeof r.interface4, "setsockopt(IP_MULTICAST_IF)");
    }
    sockaddr_in local{};
    local.sin_family = AF_INET;
    local.sin_addr = r.interface4;
    local.sin_port = 0;
    if (::bind(tx.get(), reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
      fail("bind(interface:0)");
    }
  } else {
    auto& g = reinterpret_cast<sockaddr_in6&>(group);
    g.sin6_family = AF_INET6;
    g.sin6_port = port;
    g.sin6_addr = r.group6;
    g.sin6_scope_id = r.interface_index;
    group_size = sizeof(sockaddr_in6);
    set(rx.get(), IPPROTO_IPV6, IPV6_V6ONLY, &one, sizeof one, "setsockopt(IPV6_V6ONLY)");
    if (::bind(rx.get(), reinterpret_cast<const sockaddr*>(&g), group_size) != 0) fail("bind(group:port)");
    ipv6_mreq join{};
    join.ipv6mr_multiaddr = r.group6;
    join.ipv6mr_interface = r.interface_index;
    set(rx.get(), IPPROTO_IPV6, IPV6_JOIN_GROUP, &join, sizeof join, "setsockopt(IPV6_JOIN_GROUP)");

    set(tx.get(), IPPROTO_IPV6, IPV6_MULTICAST_HOPS, &ttl, sizeof ttl, "setsockopt(IPV6_MULTICAST_HOPS)");
    set(tx.get(), IPPROTO_IPV6, IPV6_MULTICAST_LOOP, &loop, sizeof loop, "setsockopt(IPV6_MULTICAST_LOOP)");
    if (r.interface_index != 0) {
      set(tx.get(), IPPROTO_IPV6, IPV6_MULTICAST_IF, &r.interface_index, sizeof r.interface_index,
          "setsockopt(IPV6_MULTICAST_IF)");
    }
    sockaddr_in6 local{};
    local.sin6_family = AF_INET6;
    local.sin6_addr = in6addr_any;
    if (::bind(tx.get(), reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
      fail("bind([::]:0)");
    }
  }
  // Connecting fixes the source address the kernel will use (the multicast interface's),
  // so getsockname() tells exactly what our datagrams arrive from.
  if (::connect(tx.get(), reinterpret_cast<const sockaddr*>(&group), group_size) != 0) {
    fail("connect(group:port)");
  }
  socklen_t own_size = sizeof own_source_;
  if (::getsockname(tx.get(), reinterpret_cast<sockaddr*>(&own_source_), &own_size) != 0) {
    fail("getsockname");
  }

  description_ = "udp_multicast " + (family_ == AF_INET ? params_.group : "[" + params_.group + "]") + ":" +
                 std::to_string(params_.port) + " on " +
                 (params_.interface_address.empty() ? std::string("::") : params_.interface_address) + " (ttl " +
                 std::to_string(params_.ttl) + ", loopback " + (params_.loopback ? "on" : "off") + ", sending from " +
                 to_string(own_source_) + ")";
  rx_fd_ = rx.release();
  tx_fd_ = tx.release();
}

UdpMulticastBus::~UdpMulticastBus() {
  if (rx_fd_ >= 0) ::close(rx_fd_);
  if (tx_fd_ >= 0) ::close(tx_fd_);
}

bool UdpMulticastBus::send(const CanFrame& frame) noexcept {
  std::array<std::uint8_t, pycan_wire::kMaxEncodedSize> datagram;
  const std::size_t size = pycan_wire::encode(frame, wall_clock_seconds(), datagram.data(), datagram.size());
  if (size == 0) {
    count_send_error();
    return false;
  }
  ssize_t n = -1;
  do {
    n = ::send(tx_fd_, datagram.data(), size, MSG_DONTWAIT | MSG_NOSIGNAL);
  } while (n < 0 && errno == EINTR);
  if (n != static_cast<ssize_t>(size)) {
    count_send_error();
    return false;
  }
  count_sent();
  return true;
}

bool UdpMulticastBus::is_own(const sockaddr_storage& source) const noexcept {
  if (source.ss_family != own_source_.ss_family) return false;
  if (source.ss_family == AF_INET) {
    const auto& a = reinterpret_cast<const sockaddr_in&>(source);
    const auto& b = reinterpret_cast<const sockaddr_in&>(own_source_);
    return a.sin_port == b.sin_port && a.sin_addr.s_addr == b.sin_addr.s_addr;
  }
  const auto& a = reinterpret_cast<const sockaddr_in6&>(source);
  const auto& b = reinterpret_cast<const sockaddr_in6&>(own_source_);
  return a.sin6_port == b.sin6_port && std::memcmp(&a.sin6_addr, &b.sin6_addr, sizeof(in6_addr)) == 0;
}

UdpMulticastBus::Poll UdpMulticastBus::receive_one(CanFrame& frame) noexcept {
  sockaddr_storage source{};
  iovec iov{rx_buffer_.data(), rx_buffer_.size()};
  msghdr msg{};
  msg.msg_name = &source;
  msg.msg_namelen = sizeof source;
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  ssize_t n = -1;
  do {
    n = ::recvmsg(rx_fd_, &msg, MSG_DONTWAIT);
  } while (n < 0 && errno == EINTR);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK) return Poll::empty;
    count_receive_error();
    return Poll::error;
  }
  if (is_own(source)) {
    count_own_echo();
    return Poll::dropped;
  }
  if ((msg.msg_flags & MSG_TRUNC) != 0) {
    count_malformed();
    return Poll::dropped;
  }
  switch (pycan_wire::decode(rx_buffer_.data(), static_cast<std::size_t>(n), frame).status) {
    case pycan_wire::DecodeStatus::ok: count_received(); return Poll::frame;
    case pycan_wire::DecodeStatus::unsupported: count_unsupported(); return Poll::dropped;
    case pycan_wire::DecodeStatus::malformed: break;
  }
  count_malformed();
  return Poll::dropped;
}

bool UdpMulticastBus::receive(CanFrame& frame, std::chrono::nanoseconds timeout) noexcept {
  return detail::receive_until<Poll>(rx_fd_, timeout, [&] { return receive_one(frame); }) == Poll::frame;
}

}  // namespace pmlsm::can
