// CiA 402 power state machine: statusword/controlword codings, the transition table,
// faults, quick stop and the master's walk to operation enabled.
#include <gtest/gtest.h>

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/drive/power_state.hpp"

namespace {

using namespace pmlsm::drive;
using C = DriveCommand;
using S = PowerState;

constexpr S kAllStates[] = {S::kNotReadyToSwitchOn, S::kSwitchOnDisabled, S::kReadyToSwitchOn,     S::kSwitchedOn,
                            S::kOperationEnabled,   S::kQuickStopActive,  S::kFaultReactionActive, S::kFault};
constexpr C kAllCommands[] = {C::kShutdown,       C::kSwitchOn,  C::kEnableOperation, C::kDisableOperation,
                              C::kDisableVoltage, C::kQuickStop, C::kFaultReset};

// A machine brought into `target` through the standard's transitions. Fault reaction and quick
// stop last long enough not to end on their own during a test.
PowerStateMachine machine_in(S target, PowerStateParams params = {100, 100, true}) {
  PowerStateMachine m(params);
  auto go = [&m](C command) { EXPECT_TRUE(m.request(command).accepted) << to_string(command); };
  switch (target) {
    case S::kNotReadyToSwitchOn: break;
    case S::kSwitchOnDisabled: m.step(); break;
    case S::kReadyToSwitchOn:
      m.step();
      go(C::kShutdown);
      break;
    case S::kSwitchedOn:
      m.step();
      go(C::kShutdown);
      go(C::kSwitchOn);
      break;
    case S::kOperationEnabled:
      m.step();
      go(C::kShutdown);
      go(C::kSwitchOn);
      go(C::kEnableOperation);
      break;
    case S::kQuickStopActive:
      m.step();
      go(C::kShutdown);
      go(C::kSwitchOn);
      go(C::kEnableOperation);
      go(C::kQuickStop);
      break;
    case S::kFaultReactionActive:
      m.step();
      m.fault(0x2310);
      break;
    case S::kFault:
      m.step();
      m.fault(0x2310);
      for (std::uint32_t i = 0; i < params.fault_reaction_ticks; ++i) m.step();
      break;
  }
  EXPECT_EQ(m.state(), target) << to_string(target);
  EXPECT_EQ(m.refused_count(), 0u);
  return m;
}

// ---- names ---------------------------------------------------------------------------------

TEST(PowerStateNames, AreTheStandardsInLowerCase) {
  EXPECT_STREQ(to_string(S::kNotReadyToSwitchOn), "not ready to switch on");
  EXPECT_STREQ(to_string(S::kSwitchOnDisabled), "switch on disabled");
  EXPECT_STREQ(to_string(S::kReadyToSwitchOn), "ready to switch on");
  EXPECT_STREQ(to_string(S::kSwitchedOn), "switched on");
  EXPECT_STREQ(to_string(S::kOperationEnabled), "operation enabled");
  EXPECT_STREQ(to_string(S::kQuickStopActive), "quick stop active");
  EXPECT_STREQ(to_string(S::kFaultReactionActive), "fault reaction active");
  EXPECT_STREQ(to_string(S::kFault), "fault");
}

TEST(DriveCommandNames, AreTheStandardsAndParseBack) {
  EXPECT_STREQ(to_string(C::kShutdown), "shutdown");
  EXPECT_STREQ(to_string(C::kSwitchOn), "switch on");
  EXPECT_STREQ(to_string(C::kEnableOperation), "enable operation");
  EXPECT_STREQ(to_string(C::kDisableOperation), "disable operation");
  EXPECT_STREQ(to_string(C::kDisableVoltage), "disable voltage");
  EXPECT_STREQ(to_string(C::kQuickStop), "quick stop");
  EXPECT_STREQ(to_string(C::kFaultReset), "fault reset");
  for (C c : kAllCommands) EXPECT_EQ(parse_drive_command(to_string(c)), c) << to_string(c);
}

TEST(DriveCommandNames, ParseWithAnySeparatorAndCase) {
  EXPECT_EQ(parse_drive_command("enable-operation"), C::kEnableOperation);
  EXPECT_EQ(parse_drive_command("quick_stop"), C::kQuickStop);
  EXPECT_EQ(parse_drive_command("fault-reset"), C::kFaultReset);
  EXPECT_EQ(parse_drive_command("Switch_On"), C::kSwitchOn);
  EXPECT_EQ(parse_drive_command("DISABLE-VOLTAGE"), C::kDisableVoltage);
  EXPECT_EQ(parse_drive_command("shutdown"), C::kShutdown);
}

TEST(DriveCommandNames, RejectAnythingElse) {
  for (const char* text : {"", "enable", "enableoperation", "enable  operation", "enable.operation", " shutdown",
                           "shutdown ", "shut-down", "reset", "quick stop active"}) {
    EXPECT_EQ(parse_drive_command(text), std::nullopt) << '"' << text << '"';
  }
}

// ---- statusword ----------------------------------------------------------------------------

TEST(Statusword, BitConstantsAreTheStandards) {
  EXPECT_EQ(kStatusReadyToSwitchOn, 0x0001);
  EXPECT_EQ(kStatusSwitchedOn, 0x0002);
  EXPECT_EQ(kStatusOperationEnabled, 0x0004);
  EXPECT_EQ(kStatusFault, 0x0008);
  EXPECT_EQ(kStatusVoltageEnabled, 0x0010);
  EXPECT_EQ(kStatusQuickStop, 0x0020);
  EXPECT_EQ(kStatusSwitchOnDisabled, 0x0040);
  EXPECT_EQ(kStatusWarning, 0x0080);
  EXPECT_EQ(kStatusRemote, 0x0200);
  EXPECT_EQ(kStatusTargetReached, 0x0400);
  EXPECT_EQ(kStatusInternalLimitActive, 0x0800);
  EXPECT_EQ(kObjectControlword, 0x6040);
  EXPECT_EQ(kObjectStatusword, 0x6041);
  EXPECT_EQ(kObjectErrorCode, 0x603F);
}

TEST(Statusword, TypicalDriveValuesDecode) {
  EXPECT_EQ(decode_statusword(0x0237), S::kOperationEnabled);
  EXPECT_EQ(decode_statusword(0x0250), S::kSwitchOnDisabled);
  EXPECT_EQ(decode_statusword(0x0231), S::kReadyToSwitchOn);
  EXPECT_EQ(decode_statusword(0x0233), S::kSwitchedOn);
  EXPECT_EQ(decode_statusword(0x0217), S::kQuickStopActive);
  EXPECT_EQ(decode_statusword(0x021F), S::kFaultReactionActive);
  EXPECT_EQ(decode_statusword(0x0218), S::kFault);
  EXPECT_EQ(decode_statusword(0x0000), S::kNotReadyToSwitchOn);
  EXPECT_EQ(decode_statusword(0x0001), std::nullopt);  // no state shows bit 0 alone
  EXPECT_EQ(decode_statusword(0x0061), std::nullopt);  // switch on disabled with bit 0
}

TEST(Statusword, EncodesTheTypicalValues) {
  EXPECT_EQ(statusword_of(S::kOperationEnabled), 0x0237);
  EXPECT_EQ(statusword_of(S::kSwitchOnDisabled), 0x0250);
  EXPECT_EQ(statusword_of(S::kReadyToSwitchOn), 0x0231);
  EXPECT_EQ(statusword_of(S::kSwitchedOn), 0x0233);
  EXPECT_EQ(statusword_of(S::kQuickStopActive), 0x0217);
  EXPECT_EQ(statusword_of(S::kFaultReactionActive), 0x021F);
  EXPECT_EQ(statusword_of(S::kFault), 0x0218);
  EXPECT_EQ(statusword_of(S::kNotReadyToSwitchOn, false, false), 0x0000);
  EXPECT_EQ(statusword_of(S::kOperationEnabled, false, false), 0x0027);
  EXPECT_EQ(statusword_of(S::kQuickStopActive, false, false) & kStatusQuickStop, 0);  // active low
  EXPECT_NE(statusword_of(S::kOperationEnabled) & kStatusQuickStop, 0);
}

TEST(Statusword, EveryStateRoundTripsWhateverTheOtherBits) {
  // Bits outside the masks: voltage enabled, warning, remote, target reached, internal limit,
  // manufacturer and mode-specific bits.
  const std::uint16_t extras[] = {0x0000,
                                  kStatusVoltageEnabled,
                                  kStatusRemote,
                                  kStatusWarning,
                                  kStatusTargetReached,
                                  kStatusInternalLimitActive,
                                  0x0100,
                                  0xF000,
                                  0xFF90};
  for (S s : kAllStates) {
    for (bool voltage : {false, true}) {
      for (bool remote : {false, true}) {
        const std::uint16_t word = statusword_of(s, voltage, remote);
        EXPECT_EQ((word & kStatusVoltageEnabled) != 0, voltage);
        EXPECT_EQ((word & kStatusRemote) != 0, remote);
        for (std::uint16_t extra : extras) {
          EXPECT_EQ(decode_statusword(static_cast<std::uint16_t>(word | extra)), s)
              << to_string(s) << std::hex << " word 0x" << (word | extra);
        }
      }
    }
  }
}

TEST(Statusword, MasksAreDisjointAndReadOnlyBits0To3And5And6) {
  int count[kPowerStateCount] = {};
  int undecoded = 0;
  for (std::uint32_t w = 0; w <= 0xFFFF; ++w) {
    const auto word = static_cast<std::uint16_t>(w);
    const auto state = decode_statusword(word);
    EXPECT_EQ(state, decode_statusword(word & 0x006F));
    if (state)
      ++count[static_cast<int>(*state)];
    else
      ++undecoded;
  }
  // A 5-bit mask (0x004F) leaves 11 free bits, a 6-bit one (0x006F) 10.
  EXPECT_EQ(count[static_cast<int>(S::kNotReadyToSwitchOn)], 2048);
  EXPECT_EQ(count[static_cast<int>(S::kSwitchOnDisabled)], 2048);
  EXPECT_EQ(count[static_cast<int>(S::kFaultReactionActive)], 2048);
  EXPECT_EQ(count[static_cast<int>(S::kFault)], 2048);
  EXPECT_EQ(count[static_cast<int>(S::kReadyToSwitchOn)], 1024);
  EXPECT_EQ(count[static_cast<int>(S::kSwitchedOn)], 1024);
  EXPECT_EQ(count[static_cast<int>(S::kOperationEnabled)], 1024);
  EXPECT_EQ(count[static_cast<int>(S::kQuickStopActive)], 1024);
  EXPECT_EQ(undecoded, 65536 - 4 * 2048 - 4 * 1024);
}

// ---- controlword ---------------------------------------------------------------------------

TEST(Controlword, CommandCodesAreTheStandards) {
  EXPECT_EQ(controlword_of(C::kShutdown), 0x0006);
  EXPECT_EQ(controlword_of(C::kSwitchOn), 0x0007);
  EXPECT_EQ(controlword_of(C::kEnableOperation), 0x000F);
  EXPECT_EQ(controlword_of(C::kDisableOperation), 0x0007);
  EXPECT_EQ(controlword_of(C::kDisableVoltage), 0x0000);
  EXPECT_EQ(controlword_of(C::kQuickStop), 0x0002);
  EXPECT_EQ(controlword_of(C::kFaultReset), 0x0080);
  EXPECT_EQ(kControlSwitchOn, 0x0001);
  EXPECT_EQ(kControlEnableVoltage, 0x0002);
  EXPECT_EQ(kControlQuickStop, 0x0004);
  EXPECT_EQ(kControlEnableOperation, 0x0008);
  EXPECT_EQ(kControlFaultReset, 0x0080);
  EXPECT_EQ(kControlHalt, 0x0100);
}

TEST(Controlword, EveryCodeDecodesToItsCommand) {
  for (C c : kAllCommands) {
    // Disable operation shares 0x0007 with switch on; the decoder says switch on.
    const C expected = c == C::kDisableOperation ? C::kSwitchOn : c;
    EXPECT_EQ(decode_controlword(controlword_of(c), 0x0000), expected) << to_string(c);
  }
}

TEST(Controlword, FaultResetIsTheRisingEdgeOfBit7) {
  EXPECT_EQ(decode_controlword(0x0080, 0x0000), C::kFaultReset);
  EXPECT_EQ(decode_controlword(0x008F, 0x000F), C::kFaultReset);  // the edge takes precedence
  EXPECT_EQ(decode_controlword(0x0086, 0x0006), C::kFaultReset);
  // Held high: decoded by the low bits.
  EXPECT_EQ(decode_controlword(0x0080, 0x0080), C::kDisableVoltage);
  EXPECT_EQ(decode_controlword(0x0086, 0x0080), C::kShutdown);
  EXPECT_EQ(decode_controlword(0x008F, 0x0080), C::kEnableOperation);
  // Falling edge: nothing special.
  EXPECT_EQ(decode_controlword(0x0006, 0x0080), C::kShutdown);
}

TEST(Controlword, TheStandardsMasks) {
  // disable voltage: bit 1 clear, whatever bits 0, 2, 3.
  for (std::uint16_t w : {0x0000, 0x0001, 0x0004, 0x0005, 0x0008, 0x000D}) {
    EXPECT_EQ(decode_controlword(w, 0), C::kDisableVoltage) << std::hex << w;
  }
  // quick stop: bit 1 set, bit 2 clear.
  for (std::uint16_t w : {0x0002, 0x0003, 0x000A, 0x000B}) {
    EXPECT_EQ(decode_controlword(w, 0), C::kQuickStop) << std::hex << w;
  }
  // shutdown: bits 2, 1 set, bit 0 clear.
  for (std::uint16_t w : {0x0006, 0x000E}) {
    EXPECT_EQ(decode_controlword(w, 0), C::kShutdown) << std::hex << w;
  }
  EXPECT_EQ(decode_controlword(0x0007, 0), C::kSwitchOn);
  EXPECT_EQ(decode_controlword(0x000F, 0), C::kEnableOperation);
}

TEST(Controlword, BitsOutsideTheMasksAreIgnored) {
  for (std::uint32_t w = 0; w <= 0xFFFF; ++w) {
    const auto word = static_cast<std::uint16_t>(w);
    // bit 7 rising: fault reset whatever the rest.
    if (word & kControlFaultReset) {
      EXPECT_EQ(decode_controlword(word, 0), C::kFaultReset);
    }
    // otherwise only bits 0-3 count (halt, mode bits 4-6, manufacturer bits 9-15 ignored).
    const auto previous = static_cast<std::uint16_t>(word & kControlFaultReset);
    const auto decoded = decode_controlword(word, previous);
    ASSERT_TRUE(decoded.has_value()) << std::hex << word;
    EXPECT_EQ(decoded, decode_controlword(word & 0x000F, 0)) << std::hex << word;
  }
}

// ---- the state machine: construction and automatic transitions ----------------------------

TEST(PowerStateMachine, RejectsBadParametersNamingFieldAndValue) {
  auto message = [](PowerStateParams p) -> std::string {
    try {
      PowerStateMachine m(p);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "no exception";
  };
  EXPECT_EQ(message({0, 1, true}), "fault_reaction_ticks: must be >= 1, got 0");
  EXPECT_EQ(message({1, 0, true}), "quick_stop_ticks: must be >= 1, got 0");
  EXPECT_EQ(message({1, 0, false}), "quick_stop_ticks: must be >= 1, got 0");
  EXPECT_NO_THROW(PowerStateMachine({1, 1, false}));
  EXPECT_NO_THROW(PowerStateMachine());
}

TEST(PowerStateMachine, StartsNotReadyAndIsSwitchOnDisabledAfterTheFirstStep) {
  PowerStateMachine m;
  EXPECT_EQ(m.state(), S::kNotReadyToSwitchOn);
  EXPECT_EQ(m.statusword(false, false), 0x0000);
  m.step();  // transition 1
  EXPECT_EQ(m.state(), S::kSwitchOnDisabled);
  m.step();
  EXPECT_EQ(m.state(), S::kSwitchOnDisabled);  // nothing automatic from here
  EXPECT_EQ(m.error_code(), 0);
  EXPECT_EQ(m.fault_count(), 0u);
  EXPECT_EQ(m.refused_count(), 0u);
}

// ---- the transition table ------------------------------------------------------------------

struct Row {
  S from;
  C command;
  bool accepted;
  S to;
  int transition;
};

// Every state x command, quick stop ending in switch on disabled (the default).
const Row kTable[] = {
    // not ready to switch on: initialising, everything refused.
    {S::kNotReadyToSwitchOn, C::kShutdown, false, S::kNotReadyToSwitchOn, 0},
    {S::kNotReadyToSwitchOn, C::kSwitchOn, false, S::kNotReadyToSwitchOn, 0},
    {S::kNotReadyToSwitchOn, C::kEnableOperation, false, S::kNotReadyToSwitchOn, 0},
    {S::kNotReadyToSwitchOn, C::kDisableOperation, false, S::kNotReadyToSwitchOn, 0},
    {S::kNotReadyToSwitchOn, C::kDisableVoltage, false, S::kNotReadyToSwitchOn, 0},
    {S::kNotReadyToSwitchOn, C::kQuickStop, false, S::kNotReadyToSwitchOn, 0},
    {S::kNotReadyToSwitchOn, C::kFaultReset, false, S::kNotReadyToSwitchOn, 0},
    // switch on disabled
    {S::kSwitchOnDisabled, C::kShutdown, true, S::kReadyToSwitchOn, 2},
    {S::kSwitchOnDisabled, C::kSwitchOn, false, S::kSwitchOnDisabled, 0},
    {S::kSwitchOnDisabled, C::kEnableOperation, false, S::kSwitchOnDisabled, 0},
    {S::kSwitchOnDisabled, C::kDisableOperation, false, S::kSwitchOnDisabled, 0},
    {S::kSwitchOnDisabled, C::kDisableVoltage, true, S::kSwitchOnDisabled, 0},
    {S::kSwitchOnDisabled, C::kQuickStop, true, S::kSwitchOnDisabled, 0},
    {S::kSwitchOnDisabled, C::kFaultReset, true, S::kSwitchOnDisabled, 0},
    // ready to switch on
    {S::kReadyToSwitchOn, C::kShutdown, true, S::kReadyToSwitchOn, 0},
    {S::kReadyToSwitchOn, C::kSwitchOn, true, S::kSwitchedOn, 3},
    {S::kReadyToSwitchOn, C::kEnableOperation, true, S::kOperationEnabled, 4},  // 3 + 4
    {S::kReadyToSwitchOn, C::kDisableOperation, false, S::kReadyToSwitchOn, 0},
    {S::kReadyToSwitchOn, C::kDisableVoltage, true, S::kSwitchOnDisabled, 7},
    {S::kReadyToSwitchOn, C::kQuickStop, true, S::kSwitchOnDisabled, 7},
    {S::kReadyToSwitchOn, C::kFaultReset, false, S::kReadyToSwitchOn, 0},
    // switched on
    {S::kSwitchedOn, C::kShutdown, true, S::kReadyToSwitchOn, 6},
    {S::kSwitchedOn, C::kSwitchOn, true, S::kSwitchedOn, 0},
    {S::kSwitchedOn, C::kEnableOperation, true, S::kOperationEnabled, 4},
    {S::kSwitchedOn, C::kDisableOperation, true, S::kSwitchedOn, 0},
    {S::kSwitchedOn, C::kDisableVoltage, true, S::kSwitchOnDisabled, 10},
    {S::kSwitchedOn, C::kQuickStop, true, S::kSwitchOnDisabled, 10},
    {S::kSwitchedOn, C::kFaultReset, false, S::kSwitchedOn, 0},
    // operation enabled
    {S::kOperationEnabled, C::kShutdown, true, S::kReadyToSwitchOn, 8},
    {S::kOperationEnabled, C::kSwitchOn, true, S::kSwitchedOn, 5},  // 0x0007 = disable operation
    {S::kOperationEnabled, C::kEnableOperation, true, S::kOperationEnabled, 0},
    {S::kOperationEnabled, C::kDisableOperation, true, S::kSwitchedOn, 5},
    {S::kOperationEnabled, C::kDisableVoltage, true, S::kSwitchOnDisabled, 9},
    {S::kOperationEnabled, C::kQuickStop, true, S::kQuickStopActive, 11},
    {S::kOperationEnabled, C::kFaultReset, false, S::kOperationEnabled, 0},
    // quick stop active
    {S::kQuickStopActive, C::kShutdown, false, S::kQuickStopActive, 0},
    {S::kQuickStopActive, C::kSwitchOn, false, S::kQuickStopActive, 0},
    {S::kQuickStopActive, C::kEnableOperation, false, S::kQuickStopActive, 0},  // 16 not enabled
    {S::kQuickStopActive, C::kDisableOperation, false, S::kQuickStopActive, 0},
    {S::kQuickStopActive, C::kDisableVoltage, true, S::kSwitchOnDisabled, 12},
    {S::kQuickStopActive, C::kQuickStop, true, S::kQuickStopActive, 0},
    {S::kQuickStopActive, C::kFaultReset, false, S::kQuickStopActive, 0},
    // fault reaction active: everything refused.
    {S::kFaultReactionActive, C::kShutdown, false, S::kFaultReactionActive, 0},
    {S::kFaultReactionActive, C::kSwitchOn, false, S::kFaultReactionActive, 0},
    {S::kFaultReactionActive, C::kEnableOperation, false, S::kFaultReactionActive, 0},
    {S::kFaultReactionActive, C::kDisableOperation, false, S::kFaultReactionActive, 0},
    {S::kFaultReactionActive, C::kDisableVoltage, false, S::kFaultReactionActive, 0},
    {S::kFaultReactionActive, C::kQuickStop, false, S::kFaultReactionActive, 0},
    {S::kFaultReactionActive, C::kFaultReset, false, S::kFaultReactionActive, 0},
    // fault: only fault reset.
    {S::kFault, C::kShutdown, false, S::kFault, 0},
    {S::kFault, C::kSwitchOn, false, S::kFault, 0},
    {S::kFault, C::kEnableOperation, false, S::kFault, 0},
    {S::kFault, C::kDisableOperation, false, S::kFault, 0},
    {S::kFault, C::kDisableVoltage, false, S::kFault, 0},
    {S::kFault, C::kQuickStop, false, S::kFault, 0},
    {S::kFault, C::kFaultReset, true, S::kSwitchOnDisabled, 15},
};

TEST(PowerStateMachine, TheTableCoversEveryStateAndCommandOnce) {
  int seen[kPowerStateCount][kDriveCommandCount] = {};
  for (const Row& r : kTable) ++seen[static_cast<int>(r.from)][static_cast<int>(r.command)];
  for (int s = 0; s < kPowerStateCount; ++s) {
    for (int c = 0; c < kDriveCommandCount; ++c) EXPECT_EQ(seen[s][c], 1) << s << ' ' << c;
  }
}

TEST(PowerStateMachine, EveryStateAndCommandFollowsTheTable) {
  for (const Row& r : kTable) {
    SCOPED_TRACE(std::string(to_string(r.command)) + " in " + to_string(r.from));
    PowerStateMachine m = machine_in(r.from);
    const TransitionResult result = m.request(r.command);
    EXPECT_EQ(result.accepted, r.accepted);
    EXPECT_EQ(result.from, r.from);
    EXPECT_EQ(result.to, r.to);
    EXPECT_EQ(result.transition, r.transition);
    ASSERT_NE(result.reason, nullptr);
    EXPECT_STRNE(result.reason, "");
    EXPECT_EQ(m.state(), r.to);
    EXPECT_EQ(m.refused_count(), r.accepted ? 0u : 1u);
    EXPECT_EQ(decode_statusword(m.statusword()), r.to);
  }
}

TEST(PowerStateMachine, RefusalsAreCountedAndNamed) {
  PowerStateMachine m;
  auto r = m.request(C::kEnableOperation);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason, "drive is initialising (not ready to switch on)");
  m.step();
  r = m.request(C::kEnableOperation);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason, "not allowed in this state");
  EXPECT_EQ(m.refused_count(), 2u);
  EXPECT_EQ(m.state(), S::kSwitchOnDisabled);

  int refused = 0;
  for (const Row& row : kTable) refused += row.accepted ? 0 : 1;
  EXPECT_EQ(refused, 7 + 3 + 2 + 1 + 1 + 5 + 7 + 6);
}

TEST(PowerStateMachine, RepeatingACyclicCommandIsNotAnError) {
  PowerStateMachine m = machine_in(S::kOperationEnabled);
  for (int i = 0; i < 1000; ++i) {
    const auto r = m.request(C::kEnableOperation);
    ASSERT_TRUE(r.accepted);
    ASSERT_EQ(r.transition, 0);
  }
  EXPECT_EQ(m.state(), S::kOperationEnabled);
  EXPECT_EQ(m.refused_count(), 0u);
}

// ---- the master's walk ---------------------------------------------------------------------

TEST(NextCommand, IsTheStandardsPathToOperationEnabled) {
  EXPECT_EQ(next_command_towards_operation_enabled(S::kNotReadyToSwitchOn), std::nullopt);
  EXPECT_EQ(next_command_towards_operation_enabled(S::kSwitchOnDisabled), C::kShutdown);
  EXPECT_EQ(next_command_towards_operation_enabled(S::kReadyToSwitchOn), C::kSwitchOn);
  EXPECT_EQ(next_command_towards_operation_enabled(S::kSwitchedOn), C::kEnableOperation);
  EXPECT_EQ(next_command_towards_operation_enabled(S::kOperationEnabled), std::nullopt);
  EXPECT_EQ(next_command_towards_operation_enabled(S::kQuickStopActive), C::kDisableVoltage);
  EXPECT_EQ(next_command_towards_operation_enabled(S::kFaultReactionActive), std::nullopt);
  EXPECT_EQ(next_command_towards_operation_enabled(S::kFault), C::kFaultReset);
}

// A master that sends one command per tick, stepping the drive after each, until operation
// enabled; returns the commands sent.
std::vector<C> walk_to_operation_enabled(PowerStateMachine& m, int max_ticks = 20) {
  std::vector<C> sent;
  for (int tick = 0; tick < max_ticks && m.state() != S::kOperationEnabled; ++tick) {
    if (const auto command = next_command_towards_operation_enabled(m.state())) {
      EXPECT_TRUE(m.request(*command).accepted) << to_string(*command);
      sent.push_back(*command);
    }
    m.step();
  }
  return sent;
}

TEST(NextCommand, WalksFromPowerOnToOperationEnabled) {
  PowerStateMachine m;
  const auto sent = walk_to_operation_enabled(m);
  EXPECT_EQ(m.state(), S::kOperationEnabled);
  EXPECT_EQ(sent, (std::vector<C>{C::kShutdown, C::kSwitchOn, C::kEnableOperation}));
  EXPECT_EQ(m.refused_count(), 0u);
  EXPECT_TRUE(m.force_allowed());
}

TEST(NextCommand, WalksOutOfAFault) {
  PowerStateMachine m = machine_in(S::kOperationEnabled, {3, 1, true});
  m.fault(0x7500);
  const auto sent = walk_to_operation_enabled(m);
  EXPECT_EQ(m.state(), S::kOperationEnabled);
  EXPECT_EQ(sent, (std::vector<C>{C::kFaultReset, C::kShutdown, C::kSwitchOn, C::kEnableOperation}));
  EXPECT_EQ(m.refused_count(), 0u);
}

TEST(NextCommand, WalksOutOfAQuickStopThatDoesNotEndByItself) {
  PowerStateMachine m = machine_in(S::kQuickStopActive, {1, 1, false});
  const auto sent = walk_to_operation_enabled(m);
  EXPECT_EQ(m.state(), S::kOperationEnabled);
  EXPECT_EQ(sent, (std::vector<C>{C::kDisableVoltage, C::kShutdown, C::kSwitchOn, C::kEnableOperation}));
}

TEST(NextCommand, OverTheControlwordAndStatusword) {
  // The master sees only statuswords and sends controlwords; the drive decodes them.
  PowerStateMachine drive;
  std::uint16_t previous = 0x0000;
  for (int tick = 0; tick < 20 && drive.state() != S::kOperationEnabled; ++tick) {
    const auto seen = decode_statusword(drive.statusword());
    ASSERT_TRUE(seen.has_value());
    ASSERT_EQ(*seen, drive.state());
    const auto command = next_command_towards_operation_enabled(*seen);
    const std::uint16_t controlword = command ? controlword_of(*command) : previous;
    const auto decoded = decode_controlword(controlword, previous);
    ASSERT_TRUE(decoded.has_value());
    if (command) {
      EXPECT_TRUE(drive.request(*decoded).accepted);
    }
    previous = controlword;
    drive.step();
  }
  EXPECT_EQ(drive.state(), S::kOperationEnabled);
  EXPECT_EQ(drive.statusword(), 0x0237);
  // 0x0007 in operation enabled is disable operation.
  const auto r = drive.request(*decode_controlword(0x0007, 0x000F));
  EXPECT_EQ(r.transition, 5);
  EXPECT_EQ(drive.state(), S::kSwitchedOn);
}

// ---- faults --------------------------------------------------------------------------------

TEST(Fault, FromOperationEnabledThroughFaultReactionToFault) {
  PowerStateMachine m = machine_in(S::kOperationEnabled, {5, 1, true});
  m.fault(0x2310);  // continuous over-current
  EXPECT_EQ(m.state(), S::kFaultReactionActive);
  EXPECT_EQ(m.error_code(), 0x2310);
  EXPECT_EQ(m.fault_count(), 1u);
  EXPECT_FALSE(m.force_allowed());
  EXPECT_TRUE(m.power_stage_enabled());  // braking
  EXPECT_EQ(m.statusword(), 0x021F);
  for (int i = 0; i < 4; ++i) {
    m.step();
    EXPECT_EQ(m.state(), S::kFaultReactionActive) << "step " << i + 1;
  }
  m.step();  // the 5th: transition 14
  EXPECT_EQ(m.state(), S::kFault);
  EXPECT_EQ(m.statusword(), 0x0218);
  EXPECT_FALSE(m.power_stage_enabled());
  m.step();
  EXPECT_EQ(m.state(), S::kFault);  // fault is left only by fault reset

  const auto r = m.request(C::kFaultReset);
  EXPECT_TRUE(r.accepted);
  EXPECT_EQ(r.transition, 15);
  EXPECT_EQ(m.state(), S::kSwitchOnDisabled);
  EXPECT_EQ(m.error_code(), 0x2310);  // 0x603F keeps the last error
  EXPECT_EQ(m.fault_count(), 1u);
}

TEST(Fault, TheFirstCodeIsKeptAndAPersistingFaultCountsOnce) {
  PowerStateMachine m = machine_in(S::kOperationEnabled, {2, 1, true});
  m.fault(0x2310);
  m.fault(0x4310);  // over-temperature, during the fault reaction
  EXPECT_EQ(m.error_code(), 0x2310);
  m.step();
  m.step();
  EXPECT_EQ(m.state(), S::kFault);
  m.fault(0x5530);
  EXPECT_EQ(m.state(), S::kFault);
  EXPECT_EQ(m.error_code(), 0x2310);
  EXPECT_EQ(m.fault_count(), 1u);

  // After the reset a new fault is a new episode with its own code.
  m.request(C::kFaultReset);
  m.fault(0x5530);
  EXPECT_EQ(m.state(), S::kFaultReactionActive);
  EXPECT_EQ(m.error_code(), 0x5530);
  EXPECT_EQ(m.fault_count(), 2u);
}

TEST(Fault, ZeroIsStoredAsGenericError) {
  PowerStateMachine m = machine_in(S::kSwitchedOn);
  m.fault(0);
  EXPECT_EQ(m.error_code(), kErrorCodeGeneric);
  EXPECT_EQ(m.error_code(), 0x1000);
}

TEST(Fault, EntersFaultReactionFromEveryOtherState) {
  for (S s : kAllStates) {
    SCOPED_TRACE(to_string(s));
    PowerStateMachine m = machine_in(s);
    const std::uint64_t before = m.fault_count();
    m.fault(0x8611);
    const bool already = s == S::kFaultReactionActive || s == S::kFault;
    EXPECT_EQ(m.state(), already ? s : S::kFaultReactionActive);
    EXPECT_EQ(m.fault_count(), already ? before : before + 1);
  }
}

// ---- quick stop ----------------------------------------------------------------------------

TEST(QuickStop, FromOperationEnabledEndsInSwitchOnDisabled) {
  PowerStateMachine m = machine_in(S::kOperationEnabled, {1, 3, true});
  const auto r = m.request(C::kQuickStop);
  EXPECT_EQ(r.transition, 11);
  EXPECT_EQ(m.state(), S::kQuickStopActive);
  EXPECT_EQ(m.statusword(), 0x0217);
  EXPECT_FALSE(m.force_allowed());
  EXPECT_TRUE(m.power_stage_enabled());
  m.step();
  m.step();
  EXPECT_EQ(m.state(), S::kQuickStopActive);
  m.step();  // the 3rd: transition 12
  EXPECT_EQ(m.state(), S::kSwitchOnDisabled);
  EXPECT_FALSE(m.power_stage_enabled());
}

TEST(QuickStop, StaysWhenConfiguredAndEnableOperationResumes) {
  PowerStateMachine m = machine_in(S::kOperationEnabled, {1, 1, false});
  m.request(C::kQuickStop);
  for (int i = 0; i < 100; ++i) m.step();
  EXPECT_EQ(m.state(), S::kQuickStopActive);
  const auto r = m.request(C::kEnableOperation);
  EXPECT_TRUE(r.accepted);
  EXPECT_EQ(r.transition, 16);
  EXPECT_EQ(m.state(), S::kOperationEnabled);
}

TEST(QuickStop, EnableOperationIsRefusedWhenTheQuickStopEndsByItself) {
  PowerStateMachine m = machine_in(S::kQuickStopActive);
  const auto r = m.request(C::kEnableOperation);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason, "quick stop ends in switch on disabled (transition 16 not enabled)");
  EXPECT_EQ(m.refused_count(), 1u);
}

TEST(QuickStop, AFaultDuringTheQuickStopWins) {
  PowerStateMachine m = machine_in(S::kQuickStopActive);
  m.fault(0x3210);
  EXPECT_EQ(m.state(), S::kFaultReactionActive);
}

// ---- what each state allows ----------------------------------------------------------------

TEST(PowerStateMachine, ForceOnlyInOperationEnabled) {
  for (S s : kAllStates) {
    SCOPED_TRACE(to_string(s));
    const PowerStateMachine m = machine_in(s);
    EXPECT_EQ(m.force_allowed(), s == S::kOperationEnabled);
    EXPECT_EQ(m.power_stage_enabled(),
              s == S::kOperationEnabled || s == S::kQuickStopActive || s == S::kFaultReactionActive);
    EXPECT_EQ(m.high_voltage_allowed(), s == S::kReadyToSwitchOn || s == S::kSwitchedOn || s == S::kOperationEnabled ||
                                            s == S::kQuickStopActive || s == S::kFaultReactionActive);
  }
}

}  // namespace
