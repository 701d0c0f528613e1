// The master's walk through CiA 402's power state machine, against pmlsm::drive's
// PowerStateMachine playing the drive: statusword in, controlword out.
#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

#include "pmlsm/canopen/cia402_master.hpp"
#include "pmlsm/drive/power_state.hpp"

namespace {

using namespace pmlsm::canopen;
using pmlsm::drive::DriveCommand;
using pmlsm::drive::PowerState;
using pmlsm::drive::PowerStateMachine;
using pmlsm::drive::PowerStateParams;

// A drive on the other end of the bus: each cycle it sends its statusword, the master answers
// with a controlword, which the drive decodes (against the previous one, for the fault reset
// edge) and obeys.
struct Loop {
  explicit Loop(PowerStateParams params = {}) : drive(params) {}

  Cia402MasterOutput cycle(bool enable) {
    drive.step();
    const Cia402MasterOutput out = master.update(drive.statusword(), enable);
    const auto command = pmlsm::drive::decode_controlword(out.controlword, previous);
    if (command) drive.request(*command);
    previous = out.controlword;
    controlwords.push_back(out.controlword);
    return out;
  }

  // Cycles until the drive is in `target` (at most `limit`); the number of cycles taken.
  int run_until(PowerState target, bool enable, int limit = 20) {
    for (int i = 1; i <= limit; ++i) {
      cycle(enable);
      if (drive.state() == target) return i;
    }
    return -1;
  }

  PowerStateMachine drive;
  Cia402Master master;
  std::uint16_t previous = 0;
  std::vector<std::uint16_t> controlwords;
};

TEST(Cia402MasterTest, WalksFromPowerOnToOperationEnabled) {
  Loop loop;
  EXPECT_GT(loop.run_until(PowerState::kOperationEnabled, true), 0);
  // shutdown, switch on, enable operation.
  const std::vector<std::uint16_t> expected{0x0006, 0x0007, 0x000F};
  EXPECT_EQ(loop.controlwords, expected);
  const Cia402MasterOutput out = loop.cycle(true);
  EXPECT_EQ(out.status, Cia402MasterStatus::kOperationEnabled);
  EXPECT_EQ(out.controlword, 0x000F);
  EXPECT_EQ(out.waiting_cycles, 0u);
  EXPECT_FALSE(out.timed_out);
  EXPECT_EQ(loop.drive.refused_count(), 0u);
}

TEST(Cia402MasterTest, WaitsInNotReadyToSwitchOn) {
  Cia402Master master;
  const auto out = master.update(pmlsm::drive::statusword_of(PowerState::kNotReadyToSwitchOn), true);
  EXPECT_EQ(out.controlword, 0x0000);
  EXPECT_EQ(out.status, Cia402MasterStatus::kWalking);
  EXPECT_EQ(out.waiting_cycles, 1u);
}

TEST(Cia402MasterTest, FaultIsResetOnlyOnRequestAsARisingEdge) {
  Loop loop;
  ASSERT_GT(loop.run_until(PowerState::kOperationEnabled, true), 0);
  loop.drive.fault(0x2310);
  ASSERT_GT(loop.run_until(PowerState::kFault, true), 0);
  // Without a request the master waits in fault, bit 7 low.
  for (int i = 0; i < 10; ++i) {
    const auto out = loop.cycle(true);
    EXPECT_EQ(out.status, Cia402MasterStatus::kFaultResetNeeded);
    EXPECT_EQ(out.controlword, 0x0000);
    EXPECT_FALSE(out.timed_out);
    EXPECT_EQ(loop.drive.state(), PowerState::kFault);
  }
  // (The drive refuses every word but the reset while in fault; from the reset on, nothing.)
  const std::uint64_t refused_in_fault = loop.drive.refused_count();
  loop.master.request_fault_reset();
  EXPECT_TRUE(loop.master.fault_reset_pending());
  loop.controlwords.clear();
  const auto reset = loop.cycle(true);
  EXPECT_EQ(reset.controlword, 0x0080);
  EXPECT_EQ(reset.command, DriveCommand::kFaultReset);
  EXPECT_EQ(reset.status, Cia402MasterStatus::kFaultResetting);
  EXPECT_FALSE(loop.master.fault_reset_pending());
  EXPECT_EQ(loop.drive.state(), PowerState::kSwitchOnDisabled);
  ASSERT_GT(loop.run_until(PowerState::kOperationEnabled, true), 0);
  const std::vector<std::uint16_t> expected{0x0080, 0x0006, 0x0007, 0x000F};
  EXPECT_EQ(loop.controlwords, expected);
  EXPECT_EQ(loop.drive.refused_count(), refused_in_fault);
  EXPECT_EQ(loop.drive.fault_count(), 1u);
}

TEST(Cia402MasterTest, FaultResetAfterBit7HighSendsALowWordFirst) {
  // A drive stuck in fault: the first reset edge does not clear it; a second request needs a
  // new edge, so the master first drops bit 7.
  Cia402Master master;
  const std::uint16_t fault = pmlsm::drive::statusword_of(PowerState::kFault);
  master.request_fault_reset();
  EXPECT_EQ(master.update(fault, true).controlword, 0x0080);
  auto out = master.update(fault, true);  // still in fault: bit 7 held
  EXPECT_EQ(out.controlword, 0x0080);
  EXPECT_EQ(out.status, Cia402MasterStatus::kFaultResetting);
  master.request_fault_reset();
  EXPECT_EQ(master.update(fault, true).controlword, 0x0000);
  EXPECT_EQ(master.update(fault, true).controlword, 0x0080);
}

TEST(Cia402MasterTest, FromSwitchOnDisabledAndFromQuickStopActive) {
  PowerStateParams keep_quick_stop;
  keep_quick_stop.quick_stop_to_switch_on_disabled = false;
  Loop loop(keep_quick_stop);
  ASSERT_GT(loop.run_until(PowerState::kOperationEnabled, true), 0);
  loop.master.quick_stop(true);
  auto out = loop.cycle(true);
  EXPECT_EQ(out.controlword, 0x0002);
  EXPECT_EQ(out.status, Cia402MasterStatus::kQuickStop);
  EXPECT_EQ(loop.drive.state(), PowerState::kQuickStopActive);
  for (int i = 0; i < 5; ++i) {
    out = loop.cycle(true);
    EXPECT_EQ(out.controlword, 0x0002);
    EXPECT_EQ(loop.drive.state(), PowerState::kQuickStopActive);
    EXPECT_EQ(out.waiting_cycles, 0u);  // staying in quick stop active is what was asked
  }
  loop.master.quick_stop(false);
  loop.controlwords.clear();
  ASSERT_GT(loop.run_until(PowerState::kOperationEnabled, true), 0);
  // disable voltage (quick stop active -> switch on disabled), then the walk.
  const std::vector<std::uint16_t> expected{0x0000, 0x0006, 0x0007, 0x000F};
  EXPECT_EQ(loop.controlwords, expected);
}

TEST(Cia402MasterTest, QuickStopThatEndsInSwitchOnDisabled) {
  Loop loop;  // quick stop ends by itself in switch on disabled
  ASSERT_GT(loop.run_until(PowerState::kOperationEnabled, true), 0);
  loop.master.quick_stop(true);
  ASSERT_GT(loop.run_until(PowerState::kSwitchOnDisabled, true), 0);
  const auto out = loop.cycle(true);
  EXPECT_EQ(out.status, Cia402MasterStatus::kQuickStop);
  EXPECT_EQ(loop.drive.state(), PowerState::kSwitchOnDisabled);
}

TEST(Cia402MasterTest, DisableGoesToSwitchOnDisabled) {
  Loop loop;
  ASSERT_GT(loop.run_until(PowerState::kOperationEnabled, true), 0);
  const auto out = loop.cycle(false);
  EXPECT_EQ(out.controlword, 0x0000);
  EXPECT_EQ(loop.drive.state(), PowerState::kSwitchOnDisabled);
  const auto idle = loop.cycle(false);
  EXPECT_EQ(idle.status, Cia402MasterStatus::kDisabled);
  EXPECT_EQ(idle.waiting_cycles, 0u);
}

TEST(Cia402MasterTest, TimeoutReportsTheStateItIsStuckIn) {
  Cia402MasterParams params;
  params.timeout_cycles = 5;
  Cia402Master master(params);
  // A drive that never leaves ready to switch on.
  const std::uint16_t ready = pmlsm::drive::statusword_of(PowerState::kReadyToSwitchOn);
  for (std::uint32_t i = 1; i <= 5; ++i) {
    const auto out = master.update(ready, true);
    EXPECT_EQ(out.controlword, 0x0007);
    EXPECT_EQ(out.waiting_cycles, i);
    EXPECT_FALSE(out.timed_out);
  }
  const auto out = master.update(ready, true);
  EXPECT_TRUE(out.timed_out);
  ASSERT_TRUE(out.stuck_in.has_value());
  EXPECT_EQ(*out.stuck_in, PowerState::kReadyToSwitchOn);
  EXPECT_EQ(out.controlword, 0x0007);
  // A state change restarts the count.
  const auto moved = master.update(pmlsm::drive::statusword_of(PowerState::kSwitchedOn), true);
  EXPECT_FALSE(moved.timed_out);
  EXPECT_EQ(moved.waiting_cycles, 1u);
  EXPECT_THROW(Cia402Master(Cia402MasterParams{0}), std::invalid_argument);
}

TEST(Cia402MasterTest, InvalidStatuswordHoldsTheLastControlword) {
  Cia402MasterParams params;
  params.timeout_cycles = 2;
  Cia402Master master(params);
  master.update(pmlsm::drive::statusword_of(PowerState::kSwitchOnDisabled), true);  // 0x0006
  auto out = master.update(0x0001, true);
  EXPECT_EQ(out.status, Cia402MasterStatus::kInvalidStatusword);
  EXPECT_EQ(out.controlword, 0x0006);
  EXPECT_FALSE(out.state.has_value());
  EXPECT_FALSE(out.command.has_value());
  master.update(0x0001, true);
  out = master.update(0x0001, true);
  EXPECT_TRUE(out.timed_out);
  EXPECT_FALSE(out.stuck_in.has_value());
  EXPECT_STREQ(to_string(out.status), "invalid statusword");
}

TEST(Cia402MasterTest, StuckInFaultReactionIsReported) {
  Loop loop(PowerStateParams{100000, 1, true});  // an endless fault reaction
  Cia402MasterParams params;
  params.timeout_cycles = 10;
  loop.master = Cia402Master(params);
  loop.drive.step();
  loop.drive.fault(0x4210);
  Cia402MasterOutput out;
  for (int i = 0; i < 11; ++i) out = loop.cycle(true);
  EXPECT_TRUE(out.timed_out);
  EXPECT_EQ(*out.stuck_in, PowerState::kFaultReactionActive);
}

}  // namespace
