#include "pmlsm/ethercat/link.hpp"

#include "pmlsm/util/clock.hpp"

#include <arpa/inet.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <netinet/in.h>
#include <sys/ioctl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <system_error>

namespace pmlsm::ethercat {

bool InProcessWire::Queue::push(Bytes frame) {
  if (frame.size > kMaxEthernetFrameBytes) return false;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (count_ == kQueuedFrames) return false;
    const std::size_t slot = (head_ + count_) % kQueuedFrames;
    std::memcpy(frames_[slot].data(), frame.data, frame.size);
    sizes_[slot] = frame.size;
    ++count_;
  }
  ready_.notify_one();
  return true;
}

std::size_t InProcessWire::Queue::pop(std::uint8_t* buffer, std::int64_t timeout_ns) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!ready_.wait_for(lock, std::chrono::nanoseconds(std::max<std::int64_t>(timeout_ns, 0)),
                       [&] { return count_ > 0; })) {
    return 0;
  }
  const std::size_t size = sizes_[head_];
  std::memcpy(buffer, frames_[head_].data(), size);
  head_ = (head_ + 1) % kQueuedFrames;
  --count_;
  return size;
}

namespace {

/// Whether `fd` has something to read before `deadline` (an interrupted wait goes on).
bool readable_before(int fd, std::chrono::steady_clock::time_point deadline) {
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd p{fd, POLLIN, 0};
    // poll counts in milliseconds: rounded up; the caller then reads without waiting.
    const int ready = ::poll(&p, 1, static_cast<int>(std::max<std::int64_t>(0, left.count() + 1)));
    if (ready > 0) return true;
    if (ready < 0 && errno == EINTR && std::chrono::steady_clock::now() < deadline) continue;
    return false;
  }
}

/// recvfrom() with the kernel's receive stamp (SO_TIMESTAMPNS, CLOCK_REALTIME) turned into
/// CLOCK_MONOTONIC by the two clocks' difference now; `arrival_ns` -1 when there was none.
ssize_t receive_stamped(int fd, void* buffer, std::size_t size, int flags, sockaddr* from, socklen_t* from_size,
                        std::int64_t& arrival_ns) {
  iovec io{buffer, size};
  alignas(cmsghdr) std::array<char, CMSG_SPACE(sizeof(timespec))> control{};
  msghdr message{};
  message.msg_name = from;
  message.msg_namelen = *from_size;
  message.msg_iov = &io;
  message.msg_iovlen = 1;
  message.msg_control = control.data();
  message.msg_controllen = control.size();
  const ssize_t n = ::recvmsg(fd, &message, flags);
  *from_size = message.msg_namelen;
  arrival_ns = -1;
  if (n < 0) return n;
  for (cmsghdr* c = CMSG_FIRSTHDR(&message); c != nullptr; c = CMSG_NXTHDR(&message, c)) {
    if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_TIMESTAMPNS) continue;
    timespec stamp{};
    std::memcpy(&stamp, CMSG_DATA(c), sizeof stamp);
    const std::int64_t mono = monotonic_ns();
    arrival_ns = std::min(mono, to_ns(stamp) - (wall_time_ns() - mono));
  }
  return n;
}

/// The kernel's receive stamps on a socket's frames (last_arrival_ns()); a socket without them
/// still works, its frames unstamped.
void stamp_arrivals(int fd) {
  const int on = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
}

sockaddr_in ipv4(const std::string& address, std::uint16_t port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  if (inet_pton(AF_INET, address.c_str(), &a.sin_addr) != 1) {
    throw std::system_error(EINVAL, std::generic_category(),
                            "EtherCAT over UDP: not an IPv4 address: '" + address + "'");
  }
  return a;
}

}  // namespace

UdpLink::UdpLink(const UdpLinkParams& params) {
  const sockaddr_in local = ipv4(params.local_address, params.local_port);
  if (params.peer_port != 0) {  // else: whoever sent the last frame
    const sockaddr_in peer = ipv4(params.peer_address, params.peer_port);
    static_assert(sizeof peer == sizeof peer_);
    std::memcpy(peer_.data(), &peer, sizeof peer);
  }
  fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd_ < 0) throw std::system_error(errno, std::generic_category(), "EtherCAT over UDP: socket");
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
    const int error = errno;
    ::close(fd_);
    throw std::system_error(
        error, std::generic_category(),
        "EtherCAT over UDP: bind " + params.local_address + ":" + std::to_string(params.local_port));
  }
  sockaddr_in bound{};
  socklen_t bound_size = sizeof bound;
  ::getsockname(fd_, reinterpret_cast<sockaddr*>(&bound), &bound_size);
  bound_port_ = ntohs(bound.sin_port);
  stamp_arrivals(fd_);
  answer_sender_ = params.peer_port == 0;
  peer_known_ = !answer_sender_;
}

UdpLink::~UdpLink() { ::close(fd_); }

bool UdpLink::send(Bytes ethernet_frame) {
  if (ethernet_frame.size < kEthernetHeaderBytes + kFrameHeaderBytes) return false;
  const std::uint8_t* ethercat = ethernet_frame.data + kEthernetHeaderBytes;
  const std::size_t length = kFrameHeaderBytes + ((ethercat[0] | (ethercat[1] << 8)) & 0x07FF);
  if (kEthernetHeaderBytes + length > ethernet_frame.size || !peer_known_) return false;
  const ssize_t sent = ::sendto(fd_, ethercat, length, MSG_DONTWAIT, reinterpret_cast<const sockaddr*>(peer_.data()),
                                sizeof(sockaddr_in));
  return sent == static_cast<ssize_t>(length);
}

std::size_t UdpLink::receive(std::uint8_t* buffer, std::int64_t timeout_ns) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
  for (;;) {
    if (!readable_before(fd_, deadline)) return 0;
    sockaddr_in sender{};
    socklen_t sender_size = sizeof sender;
    const ssize_t n =
        receive_stamped(fd_, buffer + kEthernetHeaderBytes, kMaxEthernetFrameBytes - kEthernetHeaderBytes, MSG_DONTWAIT,
                        reinterpret_cast<sockaddr*>(&sender), &sender_size, last_arrival_ns_);
    if (n < static_cast<ssize_t>(kFrameHeaderBytes)) {
      if (n >= 0) ++dropped_;
      if (std::chrono::steady_clock::now() < deadline) continue;
      return 0;
    }
    if (answer_sender_) {
      std::memcpy(peer_.data(), &sender, sizeof sender);
      peer_known_ = true;
    }
    std::memset(buffer, 0, kEthernetHeaderBytes - 2);
    buffer[12] = static_cast<std::uint8_t>(kEtherType >> 8);
    buffer[13] = static_cast<std::uint8_t>(kEtherType & 0xFFU);
    return kEthernetHeaderBytes + static_cast<std::size_t>(n);
  }
}

RawSocketLink::RawSocketLink(const std::string& interface) {
  const auto fail = [&](const std::string& what) {
    const int error = errno;
    if (fd_ >= 0) ::close(fd_);
    throw std::system_error(error, std::generic_category(), "EtherCAT on " + interface + ": " + what);
  };
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    throw std::system_error(EINVAL, std::generic_category(), "EtherCAT: not an interface name: '" + interface + "'");
  }
  fd_ = ::socket(AF_PACKET, SOCK_RAW | SOCK_CLOEXEC, htons(kEtherType));
  if (fd_ < 0) fail("raw socket (needs CAP_NET_RAW)");
  interface_index_ = static_cast<int>(::if_nametoindex(interface.c_str()));
  if (interface_index_ == 0) fail("no such interface");
  ifreq request{};
  std::memcpy(request.ifr_name, interface.c_str(), interface.size());
  if (::ioctl(fd_, SIOCGIFHWADDR, &request) != 0) fail("its address");
  std::memcpy(mac_.data(), request.ifr_hwaddr.sa_data, mac_.size());
  sockaddr_ll address{};
  address.sll_family = AF_PACKET;
  address.sll_protocol = htons(kEtherType);
  address.sll_ifindex = interface_index_;
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) fail("bind");
  const int ignore = 1;  // our own frames are not the bus's answer (Linux 4.20 and later)
  ::setsockopt(fd_, SOL_PACKET, PACKET_IGNORE_OUTGOING, &ignore, sizeof ignore);
  stamp_arrivals(fd_);
}

RawSocketLink::~RawSocketLink() { ::close(fd_); }

bool RawSocketLink::send(Bytes ethernet_frame) {
  const ssize_t sent = ::send(fd_, ethernet_frame.data, ethernet_frame.size, MSG_DONTWAIT);
  return sent == static_cast<ssize_t>(ethernet_frame.size);
}

std::size_t RawSocketLink::receive(std::uint8_t* buffer, std::int64_t timeout_ns) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
  for (;;) {
    if (!readable_before(fd_, deadline)) return 0;
    sockaddr_ll from{};
    socklen_t from_size = sizeof from;
    const ssize_t n = receive_stamped(fd_, buffer, kMaxEthernetFrameBytes, MSG_DONTWAIT | MSG_TRUNC,
                                      reinterpret_cast<sockaddr*>(&from), &from_size, last_arrival_ns_);
    const bool ours = from.sll_pkttype == PACKET_OUTGOING;  // where PACKET_IGNORE_OUTGOING is not there
    if (n > 0 && n <= static_cast<ssize_t>(kMaxEthernetFrameBytes) && !ours) return static_cast<std::size_t>(n);
    if (std::chrono::steady_clock::now() >= deadline) return 0;
  }
}

}  // namespace pmlsm::ethercat
