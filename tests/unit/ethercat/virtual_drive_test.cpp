// The virtual CiA 402 drive on EtherCAT (VirtualEthercatDrive: the ESC, the dictionary and CoE of
// VirtualCia402Slave, the drive application of common/canopen over the simulated drive) against
// our master on a segment in this thread: the mode set by SDO, the process data mapped from CoE,
// the power-state walk by controlword in the process data, and a force profile in cyclic
// synchronous torque that moves the plant exactly as the simulated drive stepped directly does;
// the outputs held back outside OP, and a fault with its emergency.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/master.hpp"
#include "pmlsm/sim/simulated_drive.hpp"

namespace pmlsm::ethercat {
namespace {

constexpr std::uint16_t kStation = 0x1001;
constexpr std::uint32_t kLogical = 0x10000;
constexpr std::int64_t kPeriodNs = 1'000'000;

canopen::Cia402ApplicationParams application_params() {
  canopen::Cia402ApplicationParams p;
  p.scaling.rated_force_n = 200.0;  // 0.2 N a per mille
  p.scaling.increments_per_metre = 1e6;
  return p;
}

/// What the master read in one cycle: the slave's inputs (statusword, torque actual per mille,
/// position actual increments), the period before.
struct Inputs {
  std::uint16_t statusword = 0;
  std::int16_t torque_per_mille = 0;
  std::int32_t position_increments = 0;
};

/// The drive on a segment of its own, taken to OP in cyclic synchronous torque by our master.
struct Rig {
  explicit Rig(const canopen::Cia402ApplicationParams& params)
      : system(load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml")),
        behind(system, PlantInitialCondition{}),
        drive(params, behind),
        segment({&drive.esc()}),
        link(segment),
        master(link) {}

  /// Mailbox, PREOP, the mode by SDO, the process data mapped; then SAFEOP (and OP if asked).
  void start(bool op) {
    master.assign_station_addresses(1);
    const SlaveInfo info = master.read_slave_info(kStation);
    master.configure_mailbox(info);
    ASSERT_TRUE(master.request_state(kStation, AlState::kPreOp).reached);
    ASSERT_TRUE(master.sdo_download(info, canopen::kObjectModesOfOperation, 0, 10, 1).done);  // CST
    const ProcessDataLayout layout = master.map_process_data(info, kLogical);
    ASSERT_EQ(layout.output_bytes, 4);
    ASSERT_EQ(layout.input_bytes, 8);
    ASSERT_TRUE(master.request_state(kStation, AlState::kSafeOp).reached);
    drive.after_frame(now_ns);  // the application between frames: SAFEOP's inputs written
    if (op) {
      ASSERT_TRUE(master.request_state(kStation, AlState::kOp).reached);
    }
  }

  /// One process-data cycle: the outputs out and the inputs back in one LRW, then the slave's
  /// application between frames.
  Inputs cycle(std::uint16_t controlword, std::int16_t torque_per_mille) {
    std::array<std::uint8_t, 12> image{};
    image[0] = static_cast<std::uint8_t>(controlword & 0xFF);
    image[1] = static_cast<std::uint8_t>(controlword >> 8);
    image[2] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(torque_per_mille) & 0xFF);
    image[3] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(torque_per_mille) >> 8);
    const Reply r = master.exchange(Command::kLrw, kLogical, image.data(), image.size());
    EXPECT_TRUE(r.answered);
    EXPECT_EQ(r.working_counter, 3) << "outputs written and inputs read by the one slave";
    now_ns += kPeriodNs;
    drive.after_frame(now_ns);
    Inputs in;
    in.statusword = static_cast<std::uint16_t>(image[4] | (image[5] << 8));
    in.torque_per_mille = static_cast<std::int16_t>(image[6] | (image[7] << 8));
    in.position_increments =
        static_cast<std::int32_t>(static_cast<std::uint32_t>(image[8]) | (image[9] << 8) | (image[10] << 16) |
                                  (static_cast<std::uint32_t>(image[11]) << 24));
    return in;
  }

  SystemParams system;
  SimulatedDriveBackend behind;
  VirtualEthercatDrive drive;
  VirtualSegment segment;
  VirtualSegmentLink link;
  Master master;
  std::int64_t now_ns = 0;
};

TEST(VirtualEthercatDrive, TheMasterEnablesItAndAForceProfileMovesThePlantAsTheSimulatedDriveDoes) {
  const canopen::Cia402ApplicationParams params = application_params();
  Rig rig(params);
  rig.start(true);
  // The same drive stepped directly, call for call: the application samples it once when made.
  SimulatedDriveBackend reference(rig.system, PlantInitialCondition{});
  const canopen::UnitScaling scaling(params.scaling);
  drive::Measurement before = reference.sample();

  // The power-state walk, one controlword a cycle: shutdown, switch on, enable operation. Each
  // cycle is a period (zero force until enabled).
  const std::array<std::pair<std::uint16_t, drive::DriveCommand>, 3> walk{
      {{0x0006, drive::DriveCommand::kShutdown},
       {0x0007, drive::DriveCommand::kSwitchOn},
       {0x000F, drive::DriveCommand::kEnableOperation}}};
  for (const auto& [controlword, command] : walk) {
    rig.cycle(controlword, 0);
    ASSERT_TRUE(reference.request(command).accepted);
    reference.apply(0.0);
    before = reference.sample();
  }
  EXPECT_EQ(rig.behind.power_state(), drive::PowerState::kOperationEnabled);

  // 600 periods of a force profile: what the master reads each cycle is the period before, and
  // it is the simulated drive's own state to the increment.
  std::int32_t moved_increments = 0;
  for (int k = 0; k < 600; ++k) {
    const auto per_mille = static_cast<std::int16_t>(std::lround(300.0 * std::sin(2.0 * M_PI * k / 200.0)));
    const Inputs in = rig.cycle(0x000F, per_mille);
    ASSERT_EQ(in.statusword, drive::statusword_of(drive::PowerState::kOperationEnabled)) << "cycle " << k;
    ASSERT_EQ(in.position_increments, scaling.metres_to_increments(before.position_m).value) << "cycle " << k;
    ASSERT_EQ(in.torque_per_mille, scaling.force_to_per_mille(before.thrust_force_n).value) << "cycle " << k;
    reference.apply(scaling.per_mille_to_force(per_mille));
    before = reference.sample();
    moved_increments = std::max(moved_increments, std::abs(in.position_increments));
  }
  EXPECT_EQ(rig.drive.periods(), 603u);
  EXPECT_GT(moved_increments, 1000) << "the profile moved the motor by more than 1 mm";
  EXPECT_EQ(rig.drive.slave().process().refused_outputs(), 0u);
  EXPECT_EQ(rig.drive.emergencies(), 0u);
}

TEST(VirtualEthercatDrive, OutsideOpTheOutputsAreHeldAndAFaultStopsTheForceWithItsEmergency) {
  canopen::Cia402ApplicationParams params = application_params();
  params.inject_fault_at_period = 4;  // the fifth period: after the walk's three and one with force
  Rig rig(params);
  rig.start(false);
  // SAFEOP: inputs current, outputs not applied, no period stepped.
  for (int k = 0; k < 4; ++k) {
    const Inputs in = rig.cycle(0x000F, 500);
    EXPECT_EQ(in.statusword, drive::statusword_of(drive::PowerState::kSwitchOnDisabled));
  }
  EXPECT_EQ(rig.drive.periods(), 0u);
  EXPECT_EQ(rig.drive.cycles_outside_op(), 4u);
  EXPECT_EQ(rig.behind.power_state(), drive::PowerState::kSwitchOnDisabled);

  ASSERT_TRUE(rig.master.request_state(kStation, AlState::kOp).reached);
  for (const std::uint16_t controlword : {0x0006, 0x0007, 0x000F}) rig.cycle(controlword, 0);
  ASSERT_EQ(rig.behind.power_state(), drive::PowerState::kOperationEnabled);
  rig.cycle(0x000F, 500);
  EXPECT_DOUBLE_EQ(rig.drive.applied_force_n(), 100.0);
  // The fifth period faults (injected): force off, the emergency 0x5000, the statusword's fault bit read.
  rig.cycle(0x000F, 500);
  EXPECT_EQ(rig.drive.emergencies(), 1u);
  EXPECT_EQ(rig.drive.last_emergency(), canopen::kEmcyDeviceHardware);
  EXPECT_DOUBLE_EQ(rig.drive.applied_force_n(), 0.0);
  const Inputs in = rig.cycle(0x000F, 500);
  EXPECT_NE(in.statusword & 0x0008, 0) << "fault bit";
  // Fault reset (a rising bit 7), then the walk again: the emergency 0x0000 says it is gone.
  rig.cycle(0x0080, 0);
  EXPECT_EQ(rig.drive.last_emergency(), canopen::kEmcyNoError);
  for (const std::uint16_t controlword : {0x0006, 0x0007, 0x000F}) rig.cycle(controlword, 0);
  EXPECT_EQ(rig.behind.power_state(), drive::PowerState::kOperationEnabled);
  rig.cycle(0x000F, -250);
  EXPECT_DOUBLE_EQ(rig.drive.applied_force_n(), -50.0);
  // Both emergencies wait in the send mailbox, one behind the other, as CoE messages: the
  // master's next SDO meets them first, in order, and still gets its answer.
  EXPECT_EQ(rig.master.emergencies(), 0u);
  const SlaveInfo info = rig.master.read_slave_info(kStation);
  const SdoResult mode = rig.master.sdo_upload(info, canopen::kObjectModesOfOperationDisplay, 0);
  ASSERT_TRUE(mode.done);
  EXPECT_EQ(mode.value, 10u);
  EXPECT_EQ(rig.master.emergencies(), 2u);
  EXPECT_EQ(rig.master.last_emergency_code(), canopen::kEmcyNoError) << "0x5000, then its end";
  EXPECT_EQ(rig.drive.esc().mailbox_messages_dropped(), 0u);
}

TEST(VirtualEthercatDrive, TheProcessDataWatchdogDropsItToSafeopAndStopsTheForceWhenTheCyclesStop) {
  Rig rig(application_params());
  rig.start(true);
  EXPECT_EQ(rig.drive.esc().process_data_watchdog_ns(), 100'000'000) << "the ESC's default: 100 ms";
  rig.master.configure_process_data_watchdog(kStation, 10'000'000);
  EXPECT_EQ(rig.drive.esc().process_data_watchdog_ns(), 10'000'000);
  EXPECT_THROW(rig.master.configure_process_data_watchdog(kStation, 7'000'000'000), std::invalid_argument);
  for (const std::uint16_t controlword : {0x0006, 0x0007, 0x000F}) rig.cycle(controlword, 0);
  rig.cycle(0x000F, 500);
  ASSERT_DOUBLE_EQ(rig.drive.applied_force_n(), 100.0);
  // The master stops cycling: at 10 ms after the last outputs the slave is still in OP, past it not.
  const std::int64_t last_outputs_ns = rig.now_ns;
  rig.drive.check_watchdog(last_outputs_ns + 10'000'000);
  EXPECT_EQ(rig.master.read_state(kStation).state, AlState::kOp);
  EXPECT_EQ(rig.drive.emergencies(), 0u);
  rig.drive.check_watchdog(last_outputs_ns + 10'000'001);
  const StateResult state = rig.master.read_state(kStation);
  EXPECT_EQ(state.state, AlState::kSafeOp);
  EXPECT_EQ(state.code, al_code::kSyncManagerWatchdog);
  const drive::PowerState power = rig.behind.power_state();
  EXPECT_TRUE(power == drive::PowerState::kFaultReactionActive || power == drive::PowerState::kFault)
      << drive::to_string(power);
  EXPECT_NE(rig.drive.dictionary().get_or(canopen::kObjectStatusword, 0, 0) & 0x0008, 0) << "fault bit";
  EXPECT_EQ(rig.drive.last_emergency(), canopen::kEmcySyncLost);
  EXPECT_EQ(rig.drive.esc().byte_at(reg::kWatchdogStatusProcessData) & 0x01, 0) << "0x0440: expired";
  // Cycles that come again in SAFEOP move nothing; 0x0440 runs again with them.
  const std::uint64_t periods = rig.drive.periods();
  rig.now_ns = last_outputs_ns + 20'000'000;
  rig.cycle(0x000F, 500);
  EXPECT_EQ(rig.drive.periods(), periods);
  EXPECT_EQ(rig.drive.esc().byte_at(reg::kWatchdogStatusProcessData) & 0x01, 1);
}

std::int32_t s32_at(const std::uint8_t* p) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
                                   (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24));
}

TEST(VirtualEthercatDrive, TheCanopenDevicesDictionaryCarriesTheLockstepContractAndARepeatedFrameIsNoSecondPeriod) {
  // The dictionary the CANopen virtual drive runs (configs/canopen): on EtherCAT its RPDO1 is the
  // outputs (controlword, target torque, command tick) and its TPDO1 + TPDO2 the inputs
  // (statusword, torque actual, velocity actual; position actual, periods stepped).
  const std::string root = std::string(PMLSM_SOURCE_DIR) + "/";
  const SystemParams system = load_system_params(root + "configs/system.yaml");
  const CanopenRigConfig rig = load_canopen_config(root + "configs/canopen/drive.yaml");
  const DeviceDictionary device = load_device_dictionary(root + "configs/canopen/virtual_drive_od.yaml");
  canopen::Cia402ApplicationParams params;
  params.scaling = rig.master.scaling;
  SimulatedDriveBackend behind(system, PlantInitialCondition{});
  VirtualEthercatDrive drive(params, behind, build_device_dictionary(rig, device, system.timing.control_period_s));
  VirtualSegment segment({&drive.esc()});
  VirtualSegmentLink link(segment);
  Master master(link);
  master.assign_station_addresses(1);
  const SlaveInfo info = master.read_slave_info(kStation);
  master.configure_mailbox(info);
  ASSERT_TRUE(master.request_state(kStation, AlState::kPreOp).reached);
  ASSERT_TRUE(master.sdo_download(info, canopen::kObjectModesOfOperation, 0, 10, 1).done);
  const ProcessDataLayout layout = master.map_process_data(info, kLogical);
  ASSERT_EQ(layout.output_bytes, 8);
  ASSERT_EQ(layout.input_bytes, 16);
  ASSERT_TRUE(master.request_state(kStation, AlState::kSafeOp).reached);
  ASSERT_TRUE(master.request_state(kStation, AlState::kOp).reached);

  std::int64_t now_ns = 0;
  std::array<std::uint8_t, 24> image{};
  const auto cycle = [&](std::uint16_t controlword, std::int16_t per_mille, std::uint32_t command_tick) {
    image.fill(0);
    image[0] = static_cast<std::uint8_t>(controlword & 0xFF);
    image[1] = static_cast<std::uint8_t>(controlword >> 8);
    image[2] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(per_mille) & 0xFF);
    image[3] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(per_mille) >> 8);
    for (int i = 0; i < 4; ++i) image[4 + i] = static_cast<std::uint8_t>(command_tick >> (8 * i));
    const Reply r = master.exchange(Command::kLrw, kLogical, image.data(), image.size());
    EXPECT_EQ(r.working_counter, 3);
    now_ns += kPeriodNs;
    drive.after_frame(now_ns);
  };
  SimulatedDriveBackend reference(system, PlantInitialCondition{});
  const canopen::UnitScaling scaling(params.scaling);
  drive::Measurement before = reference.sample();

  // The walk before the run: the command tick is one behind the periods stepped, so no period.
  for (const auto& [controlword, command] : std::array<std::pair<std::uint16_t, drive::DriveCommand>, 3>{
           {{0x0006, drive::DriveCommand::kShutdown},
            {0x0007, drive::DriveCommand::kSwitchOn},
            {0x000F, drive::DriveCommand::kEnableOperation}}}) {
    cycle(controlword, 0, 0xFFFFFFFFU);
    ASSERT_TRUE(reference.request(command).accepted);
  }
  EXPECT_EQ(drive.periods(), 0u);
  EXPECT_EQ(drive.unstepped_cycles(), 3u);
  ASSERT_EQ(behind.power_state(), drive::PowerState::kOperationEnabled);

  // The run: tick k's frame steps period k; every tenth frame is sent twice (a reply lost, the
  // master repeats it) and the repeat steps nothing.
  for (std::uint32_t k = 0; k < 300; ++k) {
    const auto per_mille = static_cast<std::int16_t>(std::lround(200.0 * std::sin(2.0 * M_PI * k / 100.0)));
    cycle(0x000F, per_mille, k);
    ASSERT_EQ(static_cast<std::uint32_t>(s32_at(&image[20])), k) << "periods stepped read, the period before";
    ASSERT_EQ(s32_at(&image[16]), scaling.metres_to_increments(before.position_m).value) << "tick " << k;
    ASSERT_EQ(s32_at(&image[12]), scaling.velocity_to_increments(before.velocity_mps).value) << "tick " << k;
    if (k % 10 == 9) cycle(0x000F, per_mille, k);
    reference.apply(scaling.per_mille_to_force(per_mille));
    before = reference.sample();
  }
  EXPECT_EQ(drive.periods(), 300u);
  EXPECT_EQ(drive.unstepped_cycles(), 3u + 30u);
  EXPECT_EQ(drive.slave().process().refused_outputs(), 0u);
}

}  // namespace
}  // namespace pmlsm::ethercat
