// Frame lengths against the CAN 2.0A frame layout, and the bridge's load per 1 ms cycle.
#include "pmlsm/canopen/bus_load.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace pmlsm::canopen {
namespace {

TEST(BusLoad, FrameBitsFollowTheStandardFrameLayout) {
  // 47 bits of frame around the data; worst-case stuffing floor((33 + 8n) / 4).
  EXPECT_EQ(can_frame_bits(0, false), 47U);
  EXPECT_EQ(can_frame_bits(0, true), 55U);
  EXPECT_EQ(can_frame_bits(1, false), 55U);
  EXPECT_EQ(can_frame_bits(1, true), 65U);
  EXPECT_EQ(can_frame_bits(8, false), 111U);
  EXPECT_EQ(can_frame_bits(8, true), 135U);
}

TEST(BusLoad, TheBridgeCycleAtOneMegabitIsUnderHalfTheBusEvenAtWorstStuffing) {
  const BusLoad load = bus_load(bridge_cycle_frames(1e-3, 100, 100, false), 1e6, 1e-3);
  // SYNC 55 + 3 x 111 + 2 heartbeats x 55 / 100 = 389.1 bits; worst 65 + 3 x 135 + 1.3 = 471.3.
  EXPECT_NEAR(load.bits_per_cycle, 389.1, 1e-9);
  EXPECT_NEAR(load.bits_per_cycle_worst, 471.3, 1e-9);
  EXPECT_NEAR(load.load, 0.3891, 1e-9);
  EXPECT_NEAR(load.load_worst, 0.4713, 1e-9);
  // At 500 kbit/s the same cycle would not fit in half the bus.
  EXPECT_GT(bus_load(bridge_cycle_frames(1e-3, 100, 100, false), 5e5, 1e-3).load, 0.5);
  // A load sensor's TPDO3 (8 bytes) adds 111 bits, 135 at worst: still just over half at worst.
  const BusLoad with_sensor = bus_load(bridge_cycle_frames(1e-3, 100, 100, true), 1e6, 1e-3);
  EXPECT_NEAR(with_sensor.bits_per_cycle, 500.1, 1e-9);
  EXPECT_NEAR(with_sensor.load_worst, 0.6063, 1e-9);
}

TEST(BusLoad, BadInputIsRefusedNamingIt) {
  EXPECT_THROW(bus_load({}, 0.0, 1e-3), std::invalid_argument);
  EXPECT_THROW(bus_load({}, 1e6, -1.0), std::invalid_argument);
  EXPECT_THROW(bus_load({{"x", 9, 1.0}}, 1e6, 1e-3), std::invalid_argument);
  EXPECT_THROW(bus_load({{"x", 1, -1.0}}, 1e6, 1e-3), std::invalid_argument);
}

}  // namespace
}  // namespace pmlsm::canopen
