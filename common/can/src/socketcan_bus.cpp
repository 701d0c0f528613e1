#include "pmlsm/can/socketcan_bus.hpp"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "receive_loop.hpp"

namespace pmlsm::can {

SocketCanBus::SocketCanBus(const std::string& interface_name) {
  if (interface_name.empty() || interface_name.size() >= IFNAMSIZ) {
    throw std::invalid_argument("interface: must be a network interface name of 1 to " + std::to_string(IFNAMSIZ - 1) +
                                " characters, got \"" + interface_name + "\"");
  }
  const std::string where = "SocketCanBus(\"" + interface_name + "\"): ";
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    throw std::system_error(errno, std::generic_category(), where + "socket(PF_CAN, SOCK_RAW, CAN_RAW)");
  }
  auto fail = [&](const char* call) {
    const int error = errno;
    ::close(fd);
    throw std::system_error(error, std::generic_category(), where + call);
  };
  const unsigned index = ::if_nametoindex(interface_name.c_str());
  if (index == 0) fail("if_nametoindex");
  const int off = 0;
  const int on = 1;
  // The kernel's defaults, stated: others on this host hear us, we do not hear ourselves.
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &off, sizeof off) != 0) {
    fail("setsockopt(CAN_RAW_RECV_OWN_MSGS)");
  }
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_LOOPBACK, &on, sizeof on) != 0) {
    fail("setsockopt(CAN_RAW_LOOPBACK)");
  }
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = static_cast<int>(index);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) fail("bind");
  fd_ = fd;
  description_ = "socketcan " + interface_name + " (ifindex " + std::to_string(index) + ")";
}

SocketCanBus::~SocketCanBus() {
  if (fd_ >= 0) ::close(fd_);
}

bool SocketCanBus::send(const CanFrame& frame) noexcept {
  if (!is_valid_frame(frame)) {
    count_send_error();
    return false;
  }
  can_frame out{};
  out.can_id = frame.id;
  if (frame.extended) out.can_id |= CAN_EFF_FLAG;
  if (frame.rtr) out.can_id |= CAN_RTR_FLAG;
  out.can_dlc = frame.dlc;
  if (!frame.rtr) std::memcpy(out.data, frame.data.data(), frame.dlc);
  ssize_t n = -1;
  do {
    n = ::send(fd_, &out, sizeof out, MSG_DONTWAIT | MSG_NOSIGNAL);
  } while (n < 0 && errno == EINTR);
  if (n != static_cast<ssize_t>(sizeof out)) {
    count_send_error();
    return false;
  }
  count_sent();
  return true;
}

SocketCanBus::Poll SocketCanBus::receive_one(CanFrame& frame) noexcept {
  can_frame in{};
  ssize_t n = -1;
  do {
    n = ::recv(fd_, &in, sizeof in, MSG_DONTWAIT);
  } while (n < 0 && errno == EINTR);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK) return Poll::empty;
    count_receive_error();
    return Poll::error;
  }
  if (n != static_cast<ssize_t>(sizeof in) || in.can_dlc > kMaxClassicDlc) {
    count_malformed();
    return Poll::dropped;
  }
  if ((in.can_id & CAN_ERR_FLAG) != 0) {
    count_unsupported();
    return Poll::dropped;
  }
  frame.extended = (in.can_id & CAN_EFF_FLAG) != 0;
  frame.rtr = (in.can_id & CAN_RTR_FLAG) != 0;
  frame.id = in.can_id & (frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
  frame.dlc = in.can_dlc;
  frame.data.fill(0);
  if (!frame.rtr) std::memcpy(frame.data.data(), in.data, in.can_dlc);
  count_received();
  return Poll::frame;
}

bool SocketCanBus::receive(CanFrame& frame, std::chrono::nanoseconds timeout) noexcept {
  return detail::receive_until<Poll>(fd_, timeout, [&] { return receive_one(frame); }) == Poll::frame;
}

}  // namespace pmlsm::can
