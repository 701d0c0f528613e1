// UdpMulticastBus (python-can's udp_multicast wire format) and SocketCanBus. Two buses in
// this process on a group and port of their own: frames cross field by field, nobody hears
// itself, foreign garbage is counted and dropped, timeouts hold. SocketCAN runs where the
// kernel has it, and says why it was skipped where it does not.
#include <gtest/gtest.h>

#include <poll.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "can_test_support.hpp"
#include "pmlsm/can/can_bus.hpp"
#include "pmlsm/can/pycan_wire.hpp"
#include "pmlsm/can/socketcan_bus.hpp"
#include "pmlsm/can/udp_multicast_bus.hpp"

namespace pmlsm::can {
namespace {

using namespace test;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// Generous: the loopback path takes microseconds; this only bounds a failing test.
constexpr auto kArrival = 2s;

void expect_same(const CanFrame& got, const CanFrame& sent) {
  EXPECT_EQ(got.id, sent.id) << sent;
  EXPECT_EQ(got.extended, sent.extended) << sent;
  EXPECT_EQ(got.rtr, sent.rtr) << sent;
  EXPECT_EQ(got.dlc, sent.dlc) << sent;
  for (std::size_t i = 0; i < 8; ++i) {
    const std::uint8_t want = (!sent.rtr && i < sent.dlc) ? sent.data[i] : 0;
    EXPECT_EQ(got.data[i], want) << sent << ", data[" << i << "]";
  }
}

// The frames every transport must carry: both id widths at their edges, every dlc, remote
// frames, and bytes past dlc that must not travel.
std::vector<CanFrame> assorted_frames() {
  std::vector<CanFrame> frames;
  const std::vector<std::pair<std::uint32_t, bool>> ids = {{0x000, false},     {0x001, false},     {0x123, false},
                                                           {0x7FF, false},     {0x00000000, true}, {0x00000800, true},
                                                           {0x01ABCDEF, true}, {0x1FFFFFFF, true}};
  std::uint8_t seed = 1;
  for (const auto& [id, extended] : ids) {
    for (std::uint8_t dlc = 0; dlc <= 8; ++dlc) {
      frames.push_back(make_frame(id, extended, false, dlc, seed));
      seed = static_cast<std::uint8_t>(seed + 29);
    }
  }
  frames.push_back(make_frame(0x7FF, false, true, 0, 0));
  frames.push_back(make_frame(0x123, false, true, 3, 0));
  frames.push_back(make_frame(0x1FFFFFFF, true, true, 8, 0));
  frames.push_back(CanFrame{0x55, 2, {0xA1, 0xB2, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE}, false, false});
  frames.push_back(CanFrame{0x56, 4, {0xEE, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE}, true, false});
  frames.push_back(CanFrame{0x00, 8, {0x00, 0xFF, 0x80, 0x7F, 0x01, 0xFE, 0x00, 0xFF}, false, false});
  return frames;
}

// ---- parameters --------------------------------------------------------------------------

void expect_invalid(const UdpMulticastParams& p, const std::string& field, const std::string& value) {
  try {
    validate(p);
    ADD_FAILURE() << "validate() accepted " << field << " = " << value;
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(field + ":", 0), 0u) << what;
    EXPECT_NE(what.find(value), std::string::npos) << what;
  }
  EXPECT_THROW(UdpMulticastBus bus(p), std::invalid_argument) << field << " = " << value;
}

TEST(UdpMulticastParams, DefaultsArePythonCans) {
  const UdpMulticastParams p;
  EXPECT_EQ(p.group, "239.74.163.2");
  EXPECT_EQ(p.port, 43113);
  EXPECT_EQ(p.ttl, 1);
  EXPECT_TRUE(p.loopback);
  EXPECT_EQ(p.interface_address, "127.0.0.1");
  EXPECT_NO_THROW(validate(p));
}

TEST(UdpMulticastParams, RejectedFieldsAreNamedWithTheirValue) {
  auto p = [](auto change) {
    UdpMulticastParams params;
    change(params);
    return params;
  };
  expect_invalid(p([](auto& q) { q.group = "192.168.1.1"; }), "group", "\"192.168.1.1\"");
  expect_invalid(p([](auto& q) { q.group = "240.0.0.1"; }), "group", "\"240.0.0.1\"");
  expect_invalid(p([](auto& q) { q.group = "fe80::1"; }), "group", "\"fe80::1\"");
  expect_invalid(p([](auto& q) { q.group = "can-bus.local"; }), "group", "\"can-bus.local\"");
  expect_invalid(p([](auto& q) { q.group = ""; }), "group", "\"\"");
  expect_invalid(p([](auto& q) { q.port = 0; }), "port", "got 0");
  expect_invalid(p([](auto& q) { q.port = -5; }), "port", "got -5");
  expect_invalid(p([](auto& q) { q.port = 65536; }), "port", "got 65536");
  expect_invalid(p([](auto& q) { q.ttl = -1; }), "ttl", "got -1");
  expect_invalid(p([](auto& q) { q.ttl = 256; }), "ttl", "got 256");
  expect_invalid(p([](auto& q) { q.interface_address = "eth0"; }), "interface_address", "\"eth0\"");
  expect_invalid(p([](auto& q) { q.interface_address = "::1"; }), "interface_address", "\"::1\"");
  expect_invalid(p([](auto& q) {
                   q.group = "ff15::1";
                   q.interface_address = "no-such-if9";
                 }),
                 "interface_address", "\"no-such-if9\"");
  UdpMulticastParams v6;
  v6.group = "ff15:7079:7468:6f6e:6465:6d6f:6d63:6173";
  v6.interface_address = "::";
  EXPECT_NO_THROW(validate(v6));
}

TEST(UdpMulticastBus, SocketErrorsNameTheCallAndErrno) {
  UdpMulticastParams p = unique_params();
  p.interface_address = "192.0.2.254";  // TEST-NET-1: not an address of this host
  try {
    UdpMulticastBus bus(p);
    GTEST_SKIP() << "192.0.2.254 is an address of this host";
  } catch (const std::system_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(p.group), std::string::npos) << what;
    EXPECT_NE(what.find("192.0.2.254"), std::string::npos) << what;
    EXPECT_NE(what.find("setsockopt(IP_ADD_MEMBERSHIP)"), std::string::npos) << what;
    EXPECT_NE(what.find(std::strerror(e.code().value())), std::string::npos) << what;
  }
}

// ---- traffic -------------------------------------------------------------------------------

class UdpBusPair : public ::testing::Test {
 protected:
  void SetUp() override {
    params_ = unique_params();
    a_ = std::make_unique<UdpMulticastBus>(params_);
    b_ = std::make_unique<UdpMulticastBus>(params_);
  }

  UdpMulticastParams params_;
  std::unique_ptr<UdpMulticastBus> a_;
  std::unique_ptr<UdpMulticastBus> b_;
};

TEST_F(UdpBusPair, FramesRoundTripFieldByField) {
  const auto frames = assorted_frames();
  for (const CanFrame& sent : frames) {
    ASSERT_TRUE(a_->send(sent)) << sent;
    CanFrame got{};
    got.data.fill(0xCC);
    ASSERT_TRUE(b_->receive(got, kArrival)) << "lost: " << sent;
    expect_same(got, sent);
  }
  // And the other way round.
  for (const CanFrame& sent : frames) {
    ASSERT_TRUE(b_->send(sent)) << sent;
    CanFrame got{};
    ASSERT_TRUE(a_->receive(got, kArrival)) << "lost: " << sent;
    expect_same(got, sent);
  }
  const std::uint64_t n = frames.size();
  EXPECT_EQ(a_->counters().sent, n);
  EXPECT_EQ(b_->counters().received, n);
  EXPECT_EQ(b_->counters().sent, n);
  EXPECT_EQ(a_->counters().received, n);
  EXPECT_EQ(a_->counters().malformed_dropped, 0u);
  EXPECT_EQ(b_->counters().malformed_dropped, 0u);
}

TEST_F(UdpBusPair, ABusDoesNotHearItselfButEveryoneElseDoes) {
  UdpMulticastBus c(params_);  // a third node: hears both
  constexpr int kFrames = 20;
  for (int i = 0; i < kFrames; ++i) ASSERT_TRUE(a_->send(make_frame(0x100 + i, false, false, 1, 7)));
  for (int i = 0; i < kFrames; ++i) {
    CanFrame got{};
    ASSERT_TRUE(b_->receive(got, kArrival)) << i;
    EXPECT_EQ(got.id, 0x100u + i);
    ASSERT_TRUE(c.receive(got, kArrival)) << i;
    EXPECT_EQ(got.id, 0x100u + i);
  }
  CanFrame got{};
  EXPECT_FALSE(a_->receive(got, 50ms)) << "a heard its own frame: " << got;
  EXPECT_EQ(a_->counters().own_echo_dropped, static_cast<std::uint64_t>(kFrames));
  EXPECT_EQ(a_->counters().received, 0u);

  ASSERT_TRUE(b_->send(make_frame(0x200, true, false, 2, 9)));
  ASSERT_TRUE(a_->receive(got, kArrival));
  EXPECT_EQ(got.id, 0x200u);
  ASSERT_TRUE(c.receive(got, kArrival));
  EXPECT_EQ(got.id, 0x200u);
  EXPECT_FALSE(b_->receive(got, 50ms)) << "b heard its own frame: " << got;
  EXPECT_EQ(b_->counters().own_echo_dropped, 1u);
  EXPECT_EQ(b_->counters().received, static_cast<std::uint64_t>(kFrames));
  EXPECT_EQ(c.counters().own_echo_dropped, 0u);
  EXPECT_EQ(c.counters().received, static_cast<std::uint64_t>(kFrames + 1));
}

// The loopback option acts on a real interface (on "lo" every datagram comes back in
// anyway): there, with TTL 0 (nothing leaves the host), loopback decides whether members on
// this host hear a sender at all. Own echoes are dropped either way.
TEST(UdpMulticastBus, LoopbackOptionOnTheDefaultInterface) {
  UdpMulticastParams p = unique_params();
  p.interface_address = "0.0.0.0";
  p.ttl = 0;
  std::unique_ptr<UdpMulticastBus> listener, loud;
  try {
    listener = std::make_unique<UdpMulticastBus>(p);
    loud = std::make_unique<UdpMulticastBus>(p);
  } catch (const std::system_error& e) {
    GTEST_SKIP() << "no multicast on a default route here: " << e.what();
  }
  p.loopback = false;
  UdpMulticastBus quiet(p);

  ASSERT_TRUE(quiet.send(make_frame(0x321, false, false, 1, 1)));
  ASSERT_TRUE(loud->send(make_frame(0x322, false, false, 1, 1)));
  CanFrame got{};
  ASSERT_TRUE(listener->receive(got, kArrival));
  EXPECT_EQ(got.id, 0x322u) << "heard the sender with loopback off";
  EXPECT_FALSE(listener->receive(got, 50ms)) << got;
  ASSERT_TRUE(quiet.receive(got, kArrival)) << "loopback off still hears others";
  EXPECT_EQ(got.id, 0x322u);
  EXPECT_FALSE(quiet.receive(got, 10ms)) << got;
  EXPECT_EQ(quiet.counters().own_echo_dropped, 0u) << "its own never came back";
  EXPECT_FALSE(loud->receive(got, 10ms)) << got;
  EXPECT_EQ(loud->counters().own_echo_dropped, 1u);
}

TEST_F(UdpBusPair, MalformedDatagramsAreCountedAndDropped) {
  const RawSender raw(params_);
  const auto ok = python_fields(0x123, false, false, 2, {1, 2});
  const std::string text = "hello, not msgpack";
  const std::vector<std::uint8_t> valid = pack(ok);
  std::vector<std::uint8_t> trailing = valid;
  trailing.push_back(0x00);
  const std::vector<std::vector<std::uint8_t>> malformed = {
      {text.begin(), text.end()},
      {},
      {0xC1},
      std::vector<std::uint8_t>(valid.begin(), valid.begin() + 40),
      trailing,
      pack(without(ok, "arbitration_id")),
      pack(without(ok, "dlc")),
      pack(without(ok, "data")),
      pack(python_fields(0x123, false, false, 9, {1, 2, 3, 4, 5, 6, 7, 8, 9})),
      pack(python_fields(0x123, false, false, 8, {1, 2, 3, 4, 5, 6, 7, 8, 9})),
      pack(python_fields(0x800, false, false, 0, {})),
      pack(python_fields(0x20000000, true, false, 0, {})),
      pack(with(ok, "arbitration_id", int_value(-1))),
      pack(with(ok, "is_extended_id", uint_value(0))),
      pack(python_fields(0x123, false, false, 3, {1, 2})),
      std::vector<std::uint8_t>(5000, 0x8B),  // longer than the receive buffer
  };
  const std::vector<std::vector<std::uint8_t>> unsupported = {
      pack(with(python_fields(0x123, false, false, 12, std::vector<std::uint8_t>(12, 3)), "is_fd", bool_value(true))),
      pack(with(ok, "is_error_frame", bool_value(true))),
  };
  for (const auto& d : malformed) ASSERT_TRUE(raw.send(d));
  for (const auto& d : unsupported) ASSERT_TRUE(raw.send(d));
  // Then a good frame from the same foreign node: it is the first thing b returns.
  ASSERT_TRUE(raw.send(pack(python_fields(0x0AB, false, false, 2, {0xCA, 0xFE}))));

  for (UdpMulticastBus* bus : {b_.get(), a_.get()}) {
    CanFrame got{};
    ASSERT_TRUE(bus->receive(got, kArrival));
    expect_same(got, CanFrame{0x0AB, 2, {0xCA, 0xFE, 0, 0, 0, 0, 0, 0}, false, false});
    EXPECT_FALSE(bus->receive(got, 20ms)) << "unexpected: " << got;
    const CanBusCounters c = bus->counters();
    EXPECT_EQ(c.malformed_dropped, malformed.size());
    EXPECT_EQ(c.unsupported_dropped, unsupported.size());
    EXPECT_EQ(c.received, 1u);
    EXPECT_EQ(c.receive_errors, 0u);
  }
  // The bus is still fine afterwards.
  ASSERT_TRUE(a_->send(make_frame(0x7, false, false, 8, 3)));
  CanFrame got{};
  ASSERT_TRUE(b_->receive(got, kArrival));
  expect_same(got, make_frame(0x7, false, false, 8, 3));
}

TEST_F(UdpBusPair, InvalidFramesAreNotSentButCounted) {
  EXPECT_FALSE(a_->send(CanFrame{0x800, 0, {}, false, false}));
  EXPECT_FALSE(a_->send(CanFrame{0x20000000, 0, {}, false, true}));
  EXPECT_FALSE(a_->send(CanFrame{0x1, 9, {}, false, false}));
  EXPECT_EQ(a_->counters().send_errors, 3u);
  EXPECT_EQ(a_->counters().sent, 0u);
  CanFrame got{};
  EXPECT_FALSE(b_->receive(got, 50ms));
  EXPECT_EQ(b_->counters().malformed_dropped, 0u);
}

TEST_F(UdpBusPair, ReceiveTimeoutIsHonoured) {
  CanFrame got{};
  for (std::chrono::nanoseconds timeout : {std::chrono::nanoseconds(0), std::chrono::nanoseconds(-5ms)}) {
    const auto t0 = Clock::now();
    EXPECT_FALSE(b_->receive(got, timeout));
    EXPECT_LT(Clock::now() - t0, 50ms) << "timeout <= 0 must not wait";
  }
  for (auto timeout : {std::chrono::nanoseconds(30ms), std::chrono::nanoseconds(120ms)}) {
    const auto t0 = Clock::now();
    EXPECT_FALSE(b_->receive(got, timeout));
    const auto waited = Clock::now() - t0;
    EXPECT_GE(waited, timeout);
    EXPECT_LT(waited, timeout + 500ms) << "overslept";
  }
  // Only own echoes queued: dropped, and the deadline still holds.
  for (int i = 0; i < 50; ++i) ASSERT_TRUE(a_->send(make_frame(0x10, false, false, 8, 1)));
  const auto t0 = Clock::now();
  EXPECT_FALSE(a_->receive(got, 40ms));
  const auto waited = Clock::now() - t0;
  EXPECT_GE(waited, 40ms);
  EXPECT_LT(waited, 540ms);
  EXPECT_EQ(a_->counters().own_echo_dropped, 50u);
  // A frame arriving mid-wait ends it early: queued before the call, returned at once.
  ASSERT_TRUE(b_->send(make_frame(0x11, false, false, 0, 0)));
  const auto t1 = Clock::now();
  EXPECT_TRUE(a_->receive(got, 5s));
  EXPECT_LT(Clock::now() - t1, 1s);
}

TEST_F(UdpBusPair, ZeroTimeoutReachesAFrameQueuedBehindDroppedOnes) {
  const RawSender raw(params_);
  UdpMulticastBus witness(params_);
  for (int i = 0; i < 30; ++i) ASSERT_TRUE(a_->send(make_frame(0x30, false, false, 1, 1)));
  for (int i = 0; i < 30; ++i) ASSERT_TRUE(raw.send({0xC1}));
  ASSERT_TRUE(b_->send(make_frame(0x31, false, false, 1, 1)));
  // A witness: once it has b's frame, so has a (the kernel hands each datagram to every
  // member in one pass). Then a takes it with a zero timeout, past 60 dropped datagrams.
  CanFrame got{};
  for (int i = 0; i < 31; ++i) ASSERT_TRUE(witness.receive(got, kArrival));
  EXPECT_EQ(got.id, 0x31u);
  ASSERT_TRUE(a_->receive(got, 0ns));
  EXPECT_EQ(got.id, 0x31u);
  EXPECT_EQ(a_->counters().own_echo_dropped, 30u);
  EXPECT_EQ(a_->counters().malformed_dropped, 30u);
}

TEST_F(UdpBusPair, FdBecomesReadableAndDescribeNamesTheBus) {
  ASSERT_GE(b_->fd(), 0);
  pollfd p{b_->fd(), POLLIN, 0};
  EXPECT_EQ(::poll(&p, 1, 0), 0);
  ASSERT_TRUE(a_->send(make_frame(0x42, false, false, 1, 1)));
  EXPECT_EQ(::poll(&p, 1, 2000), 1);
  CanFrame got{};
  EXPECT_TRUE(b_->receive(got, 0ns));
  const std::string d = b_->describe();
  EXPECT_NE(d.find("udp_multicast"), std::string::npos) << d;
  EXPECT_NE(d.find(params_.group + ":" + std::to_string(params_.port)), std::string::npos) << d;
  EXPECT_NE(d.find("127.0.0.1"), std::string::npos) << d;
}

TEST(UdpMulticastBus, Ipv6RoundTrip) {
  UdpMulticastParams p = unique_params();
  const auto pid = static_cast<unsigned>(::getpid());
  // python-can's IPv6 default group with this process's id in the last 32 bits.
  p.group = "ff15:7079:7468:6f6e:6465:6d6f:" + std::to_string(0) + ":" + [pid] {
    char text[16];
    std::snprintf(text, sizeof text, "%x", pid & 0xFFFF);
    return std::string(text);
  }();
  p.interface_address = "::";
  std::unique_ptr<UdpMulticastBus> a, b;
  try {
    a = std::make_unique<UdpMulticastBus>(p);
    b = std::make_unique<UdpMulticastBus>(p);
  } catch (const std::system_error& e) {
    GTEST_SKIP() << "no IPv6 multicast here: " << e.what();
  }
  const CanFrame sent = make_frame(0x1ABCDEF, true, false, 8, 5);
  ASSERT_TRUE(a->send(sent));
  CanFrame got{};
  ASSERT_TRUE(b->receive(got, kArrival)) << b->describe();
  expect_same(got, sent);
  EXPECT_FALSE(a->receive(got, 20ms));
  EXPECT_EQ(a->counters().own_echo_dropped, 1u);
  EXPECT_NE(a->describe().find("[" + p.group + "]"), std::string::npos) << a->describe();
}

// ---- SocketCAN -----------------------------------------------------------------------------

// Opens a SocketCanBus, or says why this host cannot: a skip with the reason, never a pass.
std::unique_ptr<SocketCanBus> open_or_skip_reason(const std::string& name, std::string& why) {
  try {
    return std::make_unique<SocketCanBus>(name);
  } catch (const std::system_error& e) {
    if (e.code() == std::errc::address_family_not_supported) {
      why = std::string("this kernel has no AF_CAN: ") + e.what();
    } else if (e.code() == std::errc::no_such_device) {
      why = "no interface " + name + ": " + e.what();
    } else {
      throw;
    }
    return nullptr;
  }
}

TEST(SocketCanBus, VcanRoundTrip) {
  std::string why;
  auto a = open_or_skip_reason("vcan0", why);
  if (!a) GTEST_SKIP() << why;
  auto b = open_or_skip_reason("vcan0", why);
  ASSERT_TRUE(b) << why;
  for (const CanFrame& sent : assorted_frames()) {
    ASSERT_TRUE(a->send(sent)) << sent;
    CanFrame got{};
    ASSERT_TRUE(b->receive(got, kArrival)) << "lost: " << sent;
    expect_same(got, sent);
  }
  CanFrame got{};
  EXPECT_FALSE(a->receive(got, 20ms)) << "a heard its own frame: " << got;
  EXPECT_FALSE(a->send(CanFrame{0x800, 0, {}, false, false}));
  EXPECT_EQ(a->counters().send_errors, 1u);
  const auto t0 = Clock::now();
  EXPECT_FALSE(b->receive(got, 30ms));
  EXPECT_GE(Clock::now() - t0, 30ms);
  EXPECT_NE(a->describe().find("vcan0"), std::string::npos);
}

TEST(SocketCanBus, Can0Opens) {
  std::string why;
  auto bus = open_or_skip_reason("can0", why);
  if (!bus) GTEST_SKIP() << why;
  // A real controller: sending needs a peer to acknowledge, so only opening is checked.
  EXPECT_GE(bus->fd(), 0);
  EXPECT_NE(bus->describe().find("can0"), std::string::npos);
}

TEST(SocketCanBus, MissingInterfaceOrAfCanNamesInterfaceAndErrno) {
  try {
    SocketCanBus bus("nocan7");
    FAIL() << "opened a CAN interface that should not exist";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("\"nocan7\""), std::string::npos) << what;
    const auto* sys = dynamic_cast<const std::system_error*>(&e);
    ASSERT_NE(sys, nullptr) << what;
    EXPECT_NE(what.find(std::strerror(sys->code().value())), std::string::npos) << what;
    // Either the kernel has no AF_CAN, or it has and there is no such interface.
    EXPECT_TRUE(sys->code() == std::errc::address_family_not_supported || sys->code() == std::errc::no_such_device)
        << what;
  }
  EXPECT_THROW(SocketCanBus(""), std::invalid_argument);
  EXPECT_THROW(SocketCanBus("a-name-longer-than-15"), std::invalid_argument);
}

}  // namespace
}  // namespace pmlsm::can
