// The per-frame paths of UdpMulticastBus allocate nothing once constructed: send(),
// receive() of frames, own echoes, malformed and foreign datagrams, timeouts, and the wire
// codec. Its own executable: it replaces the global operator new to count allocations.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <new>
#include <vector>

#include "can_test_support.hpp"
#include "pmlsm/can/pycan_wire.hpp"
#include "pmlsm/can/udp_multicast_bus.hpp"
#include "../allocation_counter.hpp"

namespace pmlsm::can {
namespace {

using namespace test;
using namespace std::chrono_literals;

TEST(UdpMulticastBusAllocations, SteadyStateSendAndReceiveAllocateNothing) {
  const UdpMulticastParams params = unique_params();
  UdpMulticastBus a(params);
  UdpMulticastBus b(params);
  const RawSender raw(params);
  const std::vector<std::uint8_t> garbage = {0x93, 0x01, 0x02};
  const std::vector<std::uint8_t> foreign = pack(python_fields(0x1FFFFFFF, true, false, 8, {1, 2, 3, 4, 5, 6, 7, 8}));
  CanFrame got{};
  // Warm up: first use of every path (lazy initialisation in the C++ or C library).
  ASSERT_TRUE(a.send(make_frame(1, false, false, 8, 1)));
  ASSERT_TRUE(b.receive(got, 2s));
  EXPECT_FALSE(a.receive(got, 1ms));

  constexpr int kRounds = 200;
  const std::size_t before = pmlsm::test::allocations();
  int received = 0;
  for (int i = 0; i < kRounds; ++i) {
    const CanFrame f = CanFrame{static_cast<std::uint32_t>(i),
                                static_cast<std::uint8_t>(i % 9),
                                {1, 2, 3, 4, 5, 6, 7, 8},
                                i % 5 == 0,
                                i % 2 == 0};
    if (!a.send(f)) break;
    if (b.receive(got, 2s)) ++received;
  }
  a.receive(got, 0ns);  // drains 200 own echoes
  const std::size_t during_traffic = pmlsm::test::allocations() - before;
  EXPECT_EQ(during_traffic, 0u);
  EXPECT_EQ(received, kRounds);
  EXPECT_EQ(a.counters().own_echo_dropped, static_cast<std::uint64_t>(kRounds + 1));

  // Dropped input: malformed and a foreign frame (raw sends prepared beforehand).
  ASSERT_TRUE(raw.send(garbage));
  ASSERT_TRUE(raw.send(foreign));
  const std::size_t before_drop = pmlsm::test::allocations();
  ASSERT_TRUE(b.receive(got, 2s));
  EXPECT_EQ(got.id, 0x1FFFFFFFu);
  EXPECT_FALSE(b.receive(got, 5ms));  // a timeout
  EXPECT_EQ(pmlsm::test::allocations() - before_drop, 0u);
  EXPECT_EQ(b.counters().malformed_dropped, 1u);

  // The codec on its own.
  std::array<std::uint8_t, pycan_wire::kMaxEncodedSize> buffer{};
  const std::size_t before_codec = pmlsm::test::allocations();
  const std::size_t n = pycan_wire::encode(make_frame(0x7FF, false, false, 8, 3), 1.0, buffer.data(), buffer.size());
  const auto result = pycan_wire::decode(buffer.data(), n, got);
  EXPECT_EQ(pmlsm::test::allocations() - before_codec, 0u);
  EXPECT_EQ(result.status, pycan_wire::DecodeStatus::ok);
}

}  // namespace
}  // namespace pmlsm::can
