// SYNC0 (the ESC's DC cyclic unit, pmlsm/ethercat/esc.hpp) and a drive synchronous to it, on a
// simulated clock in this thread: the pulses fall at the start time our master chose on the grid
// of the slave's system time and every cycle after it, each the application's interrupt; a start
// already past waits for the 32-bit wrap as an ET1100 does; the virtual drive refuses OP in DC mode
// without SYNC0 at its period (0x0030) or with another cycle written (0x0035); and our master's
// drive booted with drive.sync0 runs the virtual drive a period a pulse, read back as the simulated
// drive stepped directly reads, the pulses that found no new outputs counted in 0x1C32:0B.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "coe_slave.hpp"
#include "shipped_drive.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/ethercat_config.hpp"
#include "pmlsm/ethercat/cia402_drive.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/master.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "pmlsm/util/little_endian.hpp"

namespace pmlsm::ethercat {
namespace sync0_test {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kStartNs = 7'000'000'123;  // the simulated clock's start: off the grid

/// One slave on a segment whose clock is `now_ns`, addressed, its distributed clock on the
/// master's time (the simulated clock).
struct Bus {
  test::CoeSlave slave;
  std::int64_t now_ns = kStartNs;
  VirtualSegment segment{{&slave.esc}, [this] { return now_ns; }};
  VirtualSegmentLink link{segment};
  Master master{link};
  std::vector<std::int64_t> interrupts;
  Bus() {
    master.assign_station_addresses(1);
    master.configure_distributed_clock(0x1001, static_cast<std::uint64_t>(now_ns));
    slave.esc.set_sync0_handler([this](std::int64_t at) { interrupts.push_back(at); });
  }
  /// A frame at `at` (reading 0x098E): the slave's clock runs on to it.
  std::uint8_t frame_at(std::int64_t at) {
    now_ns = at;
    std::array<std::uint8_t, 1> status{};
    master.exchange(Command::kFprd, physical_address(0x1001, reg::kDcSync0Status), status.data(), 1);
    return status[0];
  }
  std::uint64_t next_pulse() const { return slave.esc.sync0().next_ns; }
};

TEST(Sync0, PulsesFromTheStartOurMasterChoseEveryCycleEachTheApplicationsInterrupt) {
  Bus bus;
  const std::uint64_t start = bus.master.configure_sync0(0x1001, kMs, 250'000, 10 * kMs);
  // The first whole millisecond of system time at least 10 ms ahead, shifted by 250 us.
  EXPECT_EQ(start % kMs, 250'000u);
  EXPECT_GE(start, static_cast<std::uint64_t>(kStartNs + 10 * kMs));
  EXPECT_LT(start, static_cast<std::uint64_t>(kStartNs + 12 * kMs));
  const Sync0State& s = bus.slave.esc.sync0();
  EXPECT_TRUE(s.active);
  EXPECT_EQ(s.cycle_ns, 1'000'000u);
  EXPECT_EQ(s.late_starts, 0u);
  EXPECT_EQ(bus.frame_at(static_cast<std::int64_t>(start) - 1), 0) << "not yet";
  EXPECT_EQ(s.pulses, 0u);
  EXPECT_EQ(bus.frame_at(static_cast<std::int64_t>(start)), 1) << "the pulse at its time, 0x098E set";
  EXPECT_EQ(bus.frame_at(static_cast<std::int64_t>(start) + 10), 0) << "read, acknowledged";
  EXPECT_EQ(s.pulses, 1u);
  bus.frame_at(static_cast<std::int64_t>(start) + 10 * kMs + kMs / 2);
  EXPECT_EQ(s.pulses, 11u);
  ASSERT_EQ(bus.interrupts.size(), 11u);
  EXPECT_EQ(bus.interrupts.back(), static_cast<std::int64_t>(start) + 10 * kMs + kMs / 2);
  // 0x0990 reads the next pulse.
  std::array<std::uint8_t, 8> next{};
  bus.master.exchange(Command::kFprd, physical_address(0x1001, reg::kDcStartTime), next.data(), 8);
  EXPECT_EQ(get_le32(next.data()) | (std::uint64_t{get_le32(next.data() + 4)} << 32), start + 11 * kMs);
  // Off: no more pulses.
  std::array<std::uint8_t, 1> off{};
  bus.master.exchange(Command::kFpwr, physical_address(0x1001, reg::kDcActivation), off.data(), 1);
  bus.frame_at(static_cast<std::int64_t>(start) + 20 * kMs);
  EXPECT_EQ(s.pulses, 11u);
  EXPECT_EQ(bus.slave.esc.ns_to_next_sync0(), -1);
  EXPECT_THROW(bus.master.configure_sync0(0x1001, 0, 0), std::invalid_argument);
  EXPECT_THROW(bus.master.configure_sync0(0x1001, kMs, kMs), std::invalid_argument);
  EXPECT_THROW(bus.master.configure_sync0(0x1001, kMs, -1), std::invalid_argument);
  EXPECT_THROW(bus.master.configure_sync0(0x1001, kMs, 0, -1), std::invalid_argument);
}

TEST(Sync0, AStartAlreadyPastWaitsForTheLow32BitsToComeRoundAndASingleShotPulsesOnce) {
  Bus bus;
  const auto write = [&](std::uint16_t address, std::uint64_t value, std::uint16_t bytes) {
    std::array<std::uint8_t, 8> data{};
    put_le32(data.data(), static_cast<std::uint32_t>(value));
    put_le32(data.data() + 4, static_cast<std::uint32_t>(value >> 32));
    bus.master.exchange(Command::kFpwr, physical_address(0x1001, address), data.data(), bytes);
  };
  const auto system_now = [&] { return bus.slave.esc.dc().system_time_ns(); };
  const std::uint64_t past = system_now() - 5 * kMs;
  write(reg::kDcSync0CycleTime, kMs, 4);
  write(reg::kDcStartTime, past, 8);
  write(reg::kDcActivation, 0x03, 1);
  const Sync0State& s = bus.slave.esc.sync0();
  EXPECT_EQ(s.late_starts, 1u);
  EXPECT_EQ(s.next_ns & 0xFFFFFFFFULL, past & 0xFFFFFFFFULL);
  EXPECT_GT(s.next_ns, system_now());
  EXPECT_EQ(s.next_ns - past, std::uint64_t{1} << 32) << "4.29 s after the start asked for";
  bus.frame_at(bus.now_ns + 100 * kMs);
  EXPECT_EQ(s.pulses, 0u) << "an ET1100 stays silent until then";
  // A single shot (cycle 0): one pulse, then the unit is off.
  write(reg::kDcActivation, 0x00, 1);
  write(reg::kDcSync0CycleTime, 0, 4);
  write(reg::kDcStartTime, system_now() + kMs, 8);
  write(reg::kDcActivation, 0x03, 1);
  bus.frame_at(bus.now_ns + 5 * kMs);
  EXPECT_EQ(s.pulses, 1u);
  EXPECT_FALSE(s.active);
}

TEST(Sync0, AClockMovedFarAheadAtOnceHandsTheApplicationTheLastSecondsPulsesOnly) {
  Bus bus;
  const std::uint64_t start = bus.master.configure_sync0(0x1001, kMs, 0, 0);
  bus.frame_at(static_cast<std::int64_t>(start) + 5'000 * kMs);
  const Sync0State& s = bus.slave.esc.sync0();
  EXPECT_EQ(s.dropped, 4'001u);
  EXPECT_EQ(s.pulses, 1'000u) << "the last second's";
  EXPECT_EQ(bus.interrupts.size(), 1'000u);
  EXPECT_EQ(s.next_ns, start + 5'001 * kMs);
}

/// The virtual drive and our master's drive on a simulated clock: every frame takes `frame_ns`.
struct DcRig : test::ShippedDrive {
  explicit DcRig(Cia402DriveConfig config)
      : drive(make_drive(true)),
        segment({&drive->esc()}, [this] { return now_ns; }),
        link(segment, [this] { drive->after_frame(now_ns += frame_ns); }),
        master(config, link, [this] { return now_ns; }) {}

  static Cia402DriveConfig dc_config() {
    Cia402DriveConfig c = rig_config();
    c.realtime = true;
    c.sync0 = true;
    return c;
  }

  std::unique_ptr<VirtualEthercatDrive> drive;
  std::int64_t now_ns = kStartNs;
  std::int64_t frame_ns = 300'000;  // the enable walk: about a pulse a cycle
  VirtualSegment segment;
  VirtualSegmentLink link;
  Cia402Drive master;
};

double profile_n(int k) { return 120.0 * std::sin(2.0 * M_PI * k / 150.0); }

TEST(Sync0, OurMastersDriveOnSync0RunsTheVirtualDriveAPeriodAPulseAsTheSimulatedDriveSteppedDirectly) {
  DcRig rig(DcRig::dc_config());
  rig.master.boot();
  canopen::ObjectDictionary& od = rig.drive->dictionary();
  EXPECT_EQ(od.get_or(kObjectOutputSyncParameters, kSyncParameterMode, 0), kSyncModeDcSync0);
  EXPECT_EQ(od.get_or(kObjectInputSyncParameters, kSyncParameterMode, 0), kSyncModeDcSync0);
  EXPECT_EQ(od.get_or(kObjectOutputSyncParameters, kSyncParameterCycleTime, 0), kMs);
  EXPECT_EQ(rig.drive->esc().al_state(), AlState::kOp);
  EXPECT_EQ(rig.master.sync0_start_ns() % kMs, 500'000u) << "drive.sync0_shift_us: half a cycle after the grid";
  // The first pulse 100 ms on (the lead), then the walk to operation enabled, a pulse a cycle.
  rig.now_ns = static_cast<std::int64_t>(rig.master.sync0_start_ns());
  rig.master.start();
  rig.master.enable_and_wait();
  ASSERT_EQ(rig.master.power_state(), drive::PowerState::kOperationEnabled) << rig.master.last_problem();
  // The run: each tick on the grid, its frames 10 us apart; the pulse half a cycle on steps the
  // tick's command, and the next tick reads what it caused, as from a drive synchronous to SM2.
  // The drive's clock ran before the run too: the lead's and the walk's periods, at no force.
  SimulatedDriveBackend reference(rig.system, PlantInitialCondition{});
  for (std::uint64_t i = 0; i < rig.drive->periods(); ++i) {
    reference.apply(0.0);
    reference.sample();
  }
  for (const auto c :
       {drive::DriveCommand::kShutdown, drive::DriveCommand::kSwitchOn, drive::DriveCommand::kEnableOperation}) {
    ASSERT_TRUE(reference.request(c).accepted);
  }
  const canopen::UnitScaling& scaling = rig.master.scaling();
  rig.frame_ns = 10'000;
  std::int64_t tick_ns = (rig.now_ns / kMs + 1) * kMs;
  const std::uint64_t periods_before = rig.drive->periods();
  drive::Measurement expected = reference.sample();
  for (int k = 0; k < 300; ++k, tick_ns += kMs) {
    rig.now_ns = tick_ns;
    const drive::Measurement m = rig.master.sample();
    ASSERT_EQ(rig.drive->periods() - periods_before, static_cast<std::uint64_t>(k)) << "tick " << k;
    ASSERT_EQ(scaling.metres_to_increments(m.position_m).value, scaling.metres_to_increments(expected.position_m).value)
        << "tick " << k;
    ASSERT_EQ(scaling.velocity_to_increments(m.velocity_mps).value,
              scaling.velocity_to_increments(expected.velocity_mps).value)
        << "tick " << k;
    rig.master.apply(profile_n(k));
    reference.apply(scaling.per_mille_to_force(scaling.force_to_per_mille(profile_n(k)).value));
    expected = reference.sample();
  }
  EXPECT_EQ(rig.drive->periods() - periods_before, 299u) << "a period a pulse (the last tick's is half a cycle on)";
  EXPECT_EQ(rig.drive->sync0_without_outputs(), 0u);
  EXPECT_EQ(rig.master.counters().outputs_after_sync0, 0u) << "every tick's outputs 10-20 us into it";
  EXPECT_EQ(rig.drive->unstepped_cycles(), 0u) << "the command tick gates nothing on SYNC0";
  // A tick without outputs (the controller late): the pulse steps on the outputs SM2 holds, counted.
  rig.now_ns = tick_ns;
  rig.master.sample();
  tick_ns += kMs;
  rig.now_ns = tick_ns;
  rig.master.sample();
  EXPECT_EQ(rig.drive->sync0_without_outputs(), 1u);
  EXPECT_EQ(od.get_or(kObjectOutputSyncParameters, kSyncParameterSmMissed, 0), 1);
  EXPECT_EQ(rig.drive->periods() - periods_before, 301u) << "the drive's clock goes on";
  EXPECT_EQ(rig.drive->esc().sync0().late_starts, 0u);
  // Outputs 600 us into their tick, after its pulse at 500 us: the master counts them late.
  rig.now_ns = tick_ns + 600'000;
  rig.master.apply(0.0);
  EXPECT_EQ(rig.master.counters().outputs_after_sync0, 1u);
}

TEST(Sync0, InDcModeTheDriveRefusesOpWithoutSync0AtItsPeriodNamingTheCode) {
  VirtualCia402Slave slave;
  std::int64_t now_ns = kStartNs;
  VirtualSegment segment({&slave.esc()}, [&] { return now_ns; });
  VirtualSegmentLink link(segment);
  Master master(link);
  const SlaveInfo info = test::to_preop(master);
  // The sync modes the objects take: 3 is none of ETG.1020's; 0x22 only for the inputs.
  EXPECT_EQ(master.sdo_download(info, kObjectOutputSyncParameters, 1, 3, 2).abort_code, canopen::kAbortValueRange);
  EXPECT_EQ(master.sdo_download(info, kObjectOutputSyncParameters, 1, 0x22, 2).abort_code, canopen::kAbortValueRange);
  EXPECT_TRUE(master.sdo_download(info, kObjectInputSyncParameters, 1, 0x22, 2).done);
  EXPECT_EQ(master.sdo_upload(info, kObjectOutputSyncParameters, kSyncParameterModes).value, 0x0006u);
  EXPECT_EQ(master.sdo_upload(info, kObjectOutputSyncParameters, kSyncParameterMinCycle).value, 1'000'000u);
  ASSERT_TRUE(master.sdo_download(info, kObjectOutputSyncParameters, 1, kSyncModeDcSync0, 2).done);
  master.map_process_data(info, 0x10000);
  master.configure_distributed_clock(0x1001, static_cast<std::uint64_t>(now_ns));
  ASSERT_TRUE(master.request_state(0x1001, AlState::kSafeOp).reached);
  StateResult op = master.request_state(0x1001, AlState::kOp);
  EXPECT_FALSE(op.reached);
  EXPECT_EQ(op.describe(), "SAFEOP, refused: 0x0030 invalid DC SYNC configuration") << "SYNC0 off";
  master.configure_sync0(0x1001, 2 * kMs, 0);
  EXPECT_EQ(master.request_state(0x1001, AlState::kOp).code, al_code::kInvalidDcSyncConfiguration)
      << "SYNC0 at 2 ms, the drive's period 1 ms";
  master.configure_sync0(0x1001, kMs, 0);
  ASSERT_TRUE(master.sdo_download(info, kObjectOutputSyncParameters, kSyncParameterCycleTime, 500'000, 4).done);
  op = master.request_state(0x1001, AlState::kOp);
  EXPECT_EQ(op.code, al_code::kInvalidSyncCycleTime) << op.describe();
  ASSERT_TRUE(master.sdo_download(info, kObjectOutputSyncParameters, kSyncParameterCycleTime, 1'000'000, 4).done);
  EXPECT_TRUE(master.request_state(0x1001, AlState::kOp).reached);
}

TEST(Sync0, ALockstepRunRefusesSync0AndSync0NeedsDistributedClocks) {
  Cia402DriveConfig config = DcRig::dc_config();
  config.realtime = false;
  DcRig rig(config);
  try {
    rig.master.boot();
    ADD_FAILURE() << "a lockstep boot with drive.sync0 went through";
  } catch (const Cia402DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("realtime only"), std::string::npos) << e.what();
  }
  config.distributed_clocks = false;
  EXPECT_THROW(config.validate(), std::invalid_argument);
}

}  // namespace sync0_test
}  // namespace pmlsm::ethercat
