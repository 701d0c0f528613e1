// The links EtherCAT frames travel on (pmlsm/ethercat/link.hpp): in one process and over UDP on
// loopback (ports the kernel picks), frames arrive whole and in order, a slave's UDP link answers
// whoever asked, and a wait with nothing coming ends at its timeout.
#include "pmlsm/ethercat/link.hpp"

#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <string>
#include <system_error>
#include <thread>

#include "pmlsm/util/clock.hpp"

namespace pmlsm::ethercat {
namespace {

constexpr std::int64_t kArrivalNs = 2'000'000'000;  // bounds a failing test only
constexpr std::int64_t kShortWaitNs = 20'000'000;

/// Frame `n`: an LRW with n + 1 data bytes of value n.
FrameBuilder numbered(std::uint8_t n) {
  FrameBuilder frame;
  std::array<std::uint8_t, 64> data{};
  data.fill(n);
  frame.add(Command::kLrw, n, 0x10000U + n, data.data(), static_cast<std::uint16_t>(n + 1));
  return frame;
}

void expect_numbered(const std::uint8_t* bytes, std::size_t size, std::uint8_t n) {
  ParsedFrame parsed;
  ASSERT_EQ(parse_ethernet_frame(bytes, size, parsed), FrameError::kNone) << int(n);
  ASSERT_EQ(parsed.count, 1u);
  EXPECT_EQ(parsed.datagrams[0].header.index, n);
  EXPECT_EQ(parsed.datagrams[0].header.length, n + 1);
  EXPECT_EQ(parsed.datagrams[0].data[n], n);
}

TEST(EtherCatLink, AnInProcessWireCarriesFramesInOrderAndDropsBeyondItsQueue) {
  InProcessWire wire;
  std::array<std::uint8_t, kMaxEthernetFrameBytes> buffer{};
  for (std::uint8_t n = 0; n < InProcessWire::kQueuedFrames; ++n)
    ASSERT_TRUE(wire.end_a().send(numbered(n).ethernet()));
  EXPECT_FALSE(wire.end_a().send(numbered(99).ethernet()));  // the queue is full
  EXPECT_EQ(wire.end_a().receive(buffer.data(), 0), 0u);     // nothing came the other way
  for (std::uint8_t n = 0; n < InProcessWire::kQueuedFrames; ++n) {
    const std::size_t size = wire.end_b().receive(buffer.data(), kArrivalNs);
    expect_numbered(buffer.data(), size, n);
  }
  EXPECT_EQ(wire.end_b().receive(buffer.data(), kShortWaitNs), 0u);
}

TEST(EtherCatLink, OverUdpAMasterAsksAndASlaveAnswersWhoeverAsked) {
  UdpLink slave({"127.0.0.1", 0, "127.0.0.1", 0});
  UdpLink master({"127.0.0.1", 0, "127.0.0.1", slave.bound_port()});
  std::array<std::uint8_t, kMaxEthernetFrameBytes> buffer{};
  EXPECT_FALSE(slave.send(numbered(1).ethernet())) << "a slave has nobody to answer before a frame came";
  for (std::uint8_t n = 0; n < 20; ++n) {
    ASSERT_TRUE(master.send(numbered(n).ethernet()));
    const std::size_t asked = slave.receive(buffer.data(), kArrivalNs);
    expect_numbered(buffer.data(), asked, n);
    ASSERT_TRUE(slave.send({buffer.data(), asked}));
    const std::size_t answered = master.receive(buffer.data(), kArrivalNs);
    expect_numbered(buffer.data(), answered, n);
  }
  // A datagram too short for an EtherCAT header is dropped and counted; the wait goes on to its end.
  const int raw = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(raw, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(slave.bound_port());
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const std::uint8_t one_byte = 0x0E;
  ASSERT_EQ(::sendto(raw, &one_byte, 1, 0, reinterpret_cast<const sockaddr*>(&to), sizeof to), 1);
  ::close(raw);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(slave.receive(buffer.data(), kShortWaitNs), 0u);
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::nanoseconds(kShortWaitNs));
  EXPECT_EQ(slave.dropped(), 1u);
}

TEST(EtherCatLink, OverUdpAFrameReadLateCarriesTheTimeItCameNotTheTimeItWasRead) {
  UdpLink slave({"127.0.0.1", 0, "127.0.0.1", 0});
  UdpLink master({"127.0.0.1", 0, "127.0.0.1", slave.bound_port()});
  EXPECT_EQ(slave.last_arrival_ns(), -1) << "nothing came yet";
  // Linux turns receive stamps on for the whole system a moment after the first socket asks (a
  // deferred switch); until then a frame carries the time it was read. Frames go until one is
  // stamped, at most 50.
  std::array<std::uint8_t, kMaxEthernetFrameBytes> buffer{};
  int frames = 0;
  bool stamped_on_arrival = false;
  for (; frames < 50 && !stamped_on_arrival; ++frames) {
    const std::int64_t before_send = monotonic_ns();
    ASSERT_TRUE(master.send(numbered(3).ethernet()));
    pollfd ready{slave.fd(), POLLIN, 0};
    ASSERT_EQ(::poll(&ready, 1, 2000), 1);
    const std::int64_t there = monotonic_ns();
    // A reader busy elsewhere for 2 ms (a slave's process woken late).
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    expect_numbered(buffer.data(), slave.receive(buffer.data(), kArrivalNs), 3);
    const std::int64_t arrived = slave.last_arrival_ns();
    ASSERT_GE(arrived, before_send);
    stamped_on_arrival = arrived <= there;
  }
  EXPECT_TRUE(stamped_on_arrival) << "after " << frames << " frames, each stamped when it was read";
}

TEST(EtherCatLink, AnAddressThatIsNotIpv4IsRefusedNamingIt) {
  try {
    UdpLink bad({"not-an-address", 0, "127.0.0.1", 1});
    FAIL() << "no exception";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("not-an-address"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pmlsm::ethercat
