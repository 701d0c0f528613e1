// Our EtherCAT master's CiA 402 drive (ethercat::Cia402Drive, the drive loop's backend) against the
// virtual EtherCAT drive over the simulated drive, in this thread: the boot (identity, mode, the
// process data found in the drive's own mapping), the enable walk stepping nothing, a force
// profile through the drive seam read back as the simulated drive stepped directly reads, lost
// replies that cost no period and no second one, a drive that stops answering lost at zero force
// with its AL state named, and (realtime) the drive's watchdog fault read with its error code.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/ethercat_config.hpp"
#include "pmlsm/ethercat/cia402_drive.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "shipped_drive.hpp"

namespace pmlsm::ethercat::backend_test {
namespace {

constexpr std::int64_t kPeriodNs = 1'000'000;

/// A link that loses what `drop` picks of the frames sent (counted from 0; the frame went out and
/// passed the drive, its reply is lost, as on a wire that drops on the way back), or everything
/// once `dead` is set (a cable pulled: nothing goes out).
class LossyLink final : public Link {
 public:
  explicit LossyLink(Link& inner) : inner_(inner) {}
  bool send(Bytes frame) override {
    if (dead) return true;  // sent into a cable that leads nowhere
    const bool lose_reply = drop && drop(sent_++);
    if (!inner_.send(frame)) return false;
    if (lose_reply) {
      std::array<std::uint8_t, kMaxEthernetFrameBytes> sink{};
      inner_.receive(sink.data(), 0);
      ++dropped;
    }
    return true;
  }
  std::size_t receive(std::uint8_t* buffer, std::int64_t timeout_ns) override {
    return dead ? 0 : inner_.receive(buffer, timeout_ns);
  }
  std::function<bool(std::uint64_t)> drop;
  bool dead = false;
  std::uint64_t dropped = 0;

 private:
  Link& inner_;
  std::uint64_t sent_ = 0;
};

/// The virtual drive with the CANopen device's dictionary (the lockstep contract) or the CiA 402
/// one alone, on a segment of its own, its application run after every frame at a simulated time
/// that advances one period a frame; our drive backend on a lossy link to it.
struct Rig : test::ShippedDrive {
  explicit Rig(bool device_dictionary, Cia402DriveConfig config = rig_config())
      : drive(make_drive(device_dictionary)),
        segment({&drive->esc()}),
        link(segment, [this] { drive->after_frame(now_ns += step_ns); }),
        lossy(link),
        master(config, lossy) {}

  std::unique_ptr<VirtualEthercatDrive> drive;
  VirtualSegment segment;
  std::int64_t now_ns = 0;
  std::int64_t step_ns = kPeriodNs;
  VirtualSegmentLink link;
  LossyLink lossy;
  Cia402Drive master;
};

double profile_n(int k) { return 120.0 * std::sin(2.0 * M_PI * k / 150.0); }

/// The boot, the walk to operation enabled, then `ticks` ticks of `force_n` through the seam.
void boot_and_run(Rig& rig, int ticks, double force_n) {
  rig.master.boot();
  rig.master.start();
  rig.master.enable_and_wait();
  for (int k = 0; k < ticks; ++k) {
    rig.master.sample();
    rig.master.apply(force_n);
  }
}

/// `ticks` ticks through the seam (sample, then apply), each reading compared with the simulated
/// drive stepped directly, call for call, to the encoder's and the torque's quantisation.
void run_against_reference(Rig& rig, int ticks) {
  SimulatedDriveBackend reference(rig.system, PlantInitialCondition{});
  ASSERT_TRUE(reference.request(drive::DriveCommand::kShutdown).accepted);
  ASSERT_TRUE(reference.request(drive::DriveCommand::kSwitchOn).accepted);
  ASSERT_TRUE(reference.request(drive::DriveCommand::kEnableOperation).accepted);
  const canopen::UnitScaling& scaling = rig.master.scaling();
  drive::Measurement expected = reference.sample();
  for (int k = 0; k < ticks; ++k) {
    const drive::Measurement m = rig.master.sample();
    ASSERT_FALSE(rig.master.lost()) << "tick " << k << ": " << rig.master.last_problem();
    ASSERT_EQ(scaling.metres_to_increments(m.position_m).value, scaling.metres_to_increments(expected.position_m).value)
        << "tick " << k;
    ASSERT_EQ(scaling.velocity_to_increments(m.velocity_mps).value,
              scaling.velocity_to_increments(expected.velocity_mps).value)
        << "tick " << k;
    // The command as the drive holds it: per mille of the rated force.
    const double commanded_n = scaling.per_mille_to_force(scaling.force_to_per_mille(profile_n(k)).value);
    rig.master.apply(profile_n(k));
    reference.apply(commanded_n);
    expected = reference.sample();
  }
}

TEST(EthercatCia402Drive, BootsWalksAndDrivesTheVirtualDriveAsTheSimulatedDriveSteppedDirectly) {
  Rig rig(true);
  rig.master.boot();
  EXPECT_EQ(rig.drive->esc().al_state(), AlState::kOp);
  EXPECT_TRUE(rig.master.lockstep_contract());
  // Every mode's targets (22 bytes in three RxPDOs) and the actual values with the torque demand.
  EXPECT_EQ(rig.master.layout().output_bytes, 22);
  EXPECT_EQ(rig.master.layout().input_bytes, 18);
  EXPECT_EQ(rig.drive->esc().process_data_watchdog_ns(), 0) << "lockstep: the watchdog off";
  rig.master.start();
  rig.master.enable_and_wait();
  EXPECT_EQ(rig.master.power_state(), drive::PowerState::kOperationEnabled);
  EXPECT_EQ(rig.drive->periods(), 0u) << "the boot and the walk step nothing";

  run_against_reference(rig, 600);
  EXPECT_EQ(rig.drive->periods(), 600u) << "each tick's outputs one period";
  EXPECT_GT(std::abs(rig.behind.sample().position_m), 1e-4) << "the profile moved the motor";
  EXPECT_EQ(rig.master.counters().frames_lost, 0u);
  EXPECT_EQ(rig.master.counters().working_counter_errors, 0u);
  EXPECT_EQ(rig.master.fault_count(), 0u);
}

TEST(EthercatCia402Drive, LostRepliesCostNoPeriodAndStepNoSecondOne) {
  Rig rig(true);
  rig.master.boot();
  rig.master.start();
  rig.master.enable_and_wait();
  // From now on one reply in seven is lost on its way back (the frame passed the drive).
  rig.lossy.drop = [](std::uint64_t n) { return n % 7 == 3; };
  run_against_reference(rig, 400);
  EXPECT_GT(rig.lossy.dropped, 50u);
  EXPECT_GT(rig.master.master().frames_lost(), 50u) << "each lost reply's frame was sent again";
  EXPECT_EQ(rig.drive->periods(), 400u) << "every tick one period, however often its outputs came";
  EXPECT_GT(rig.drive->unstepped_cycles(), 0u) << "outputs that came twice stepped nothing the second time";
}

TEST(EthercatCia402Drive, ADriveThatStopsAnsweringIsLostAtZeroForceNeverWaitedFor) {
  Rig rig(true);
  boot_and_run(rig, 20, 50.0);
  rig.lossy.dead = true;  // the cable pulled
  rig.master.sample();
  EXPECT_TRUE(rig.master.lost());
  EXPECT_EQ(rig.master.error_code(), drive::kErrorCommandTimeout);
  EXPECT_EQ(rig.master.power_state(), drive::PowerState::kFault);
  EXPECT_NE(std::string(rig.master.last_problem()).find("does not answer"), std::string::npos)
      << rig.master.last_problem();
  // Lost for good: no frame is sent any more, and no request enables it again.
  const std::uint64_t cycles = rig.master.counters().cycles;
  rig.master.apply(50.0);
  rig.master.sample();
  EXPECT_EQ(rig.master.counters().cycles, cycles);
  EXPECT_FALSE(rig.master.request(drive::DriveCommand::kEnableOperation).accepted);
}

TEST(EthercatCia402Drive, RealtimeTheDrivesWatchdogFaultIsReadWithItsErrorCode) {
  Cia402DriveConfig config = Rig::rig_config();
  config.realtime = true;
  config.watchdog_ms = 10;
  Rig rig(true, config);
  rig.master.boot();
  EXPECT_EQ(rig.drive->esc().process_data_watchdog_ns(), 10'000'000) << "realtime: drive.watchdog_ms";
  rig.master.start();
  rig.master.enable_and_wait();
  for (int k = 0; k < 50; ++k) {
    rig.master.sample();
    rig.master.apply(30.0);
  }
  EXPECT_EQ(rig.drive->periods(), 50u) << "realtime: one period a cycle";
  // The controller stalls for 20 ms: the next frame finds the drive's watchdog expired (the
  // drive's application runs after the frame: the tick after reads it).
  rig.now_ns += 20 * kPeriodNs;
  for (int k = 0; k < 2; ++k) {
    rig.master.sample();
    rig.master.apply(30.0);
  }
  EXPECT_EQ(rig.drive->esc().al_state(), AlState::kSafeOp);
  // Fault reaction active: without cycles (SAFEOP) the synchronous drive's time stands still.
  EXPECT_EQ(rig.master.power_state(), drive::PowerState::kFaultReactionActive);
  EXPECT_EQ(rig.master.error_code(), canopen::kEmcySyncLost) << rig.master.last_problem();
  EXPECT_EQ(rig.master.master().emergencies(), 1u) << "the drive's CoE emergency, met before 0x603F's answer";
  EXPECT_EQ(rig.master.master().last_emergency_code(), canopen::kEmcySyncLost);
  EXPECT_NE(std::string(rig.master.last_problem()).find("CoE emergency"), std::string::npos)
      << rig.master.last_problem();
  EXPECT_EQ(rig.master.fault_count(), 1u);
  EXPECT_EQ(rig.behind.power_state(), drive::PowerState::kFaultReactionActive) << "out of operation enabled: no force";
}

TEST(EthercatCia402Drive, AWarningTheDrivePostsIsReadWithinTenCyclesWithoutAFaultOrALostPeriod) {
  Rig rig(true);
  boot_and_run(rig, 5, 20.0);
  EXPECT_EQ(rig.master.emergencies(), 0u);
  // A manufacturer's warning (0xFF01) in the drive's send mailbox, no fault behind it.
  ASSERT_TRUE(rig.drive->slave().post_emergency(0xFF01));
  for (int k = 0; k < static_cast<int>(Cia402Drive::kMailboxPollCycles); ++k) {
    rig.master.sample();
    rig.master.apply(20.0);
  }
  EXPECT_EQ(rig.master.emergencies(), 1u) << "read by a cycle's look into the mailbox";
  EXPECT_EQ(rig.master.last_emergency_code(), 0xFF01);
  EXPECT_GE(rig.master.counters().mailbox_polls, 1u);
  EXPECT_EQ(rig.master.power_state(), drive::PowerState::kOperationEnabled);
  EXPECT_FALSE(rig.master.lost());
  EXPECT_EQ(rig.master.ticks(), 15u);
  EXPECT_EQ(rig.master.master().mailbox_unexpected(), 0u);
}

TEST(EthercatCia402Drive, TheBootRefusesAnotherDriveAndALockstepWithoutTheContractNamingWhy) {
  {
    Cia402DriveConfig config = Rig::rig_config();
    config.product_code = 0x12345678;
    Rig rig(true, config);
    try {
      rig.master.boot();
      FAIL() << "booted a drive of another product";
    } catch (const Cia402DriveError& e) {
      EXPECT_NE(std::string(e.what()).find("product 0x12345678"), std::string::npos) << e.what();
    }
  }
  {
    Cia402DriveConfig own = Rig::rig_config();  // the drive's own assignment taken as it is
    own.outputs_mapping.clear();
    own.inputs_mapping.clear();
    Rig rig(false, own);  // the CiA 402 dictionary alone: its TxPDO has no velocity actual
    try {
      rig.master.boot();
      FAIL() << "booted a drive whose inputs lack the velocity";
    } catch (const Cia402DriveError& e) {
      EXPECT_NE(std::string(e.what()).find("do not map 0x606C"), std::string::npos) << e.what();
    }
  }
  {
    Cia402DriveConfig config = Rig::rig_config();
    config.position = 1;
    Rig rig(true, config);
    EXPECT_THROW(rig.master.boot(), Cia402DriveError) << "one slave on the bus, none at position 1";
  }
  Cia402DriveConfig bad = Rig::rig_config();
  bad.watchdog_ms = 0;
  EXPECT_THROW(Rig(true, bad), std::invalid_argument);
}

TEST(EthercatCia402Drive, TheRigFilesMappingIsWrittenAndAnotherOrderDrivesTheSame) {
  // The objects in another order: the master writes it by SDO in PREOP, the drive takes it at
  // SAFEOP (its image and sync managers rebuilt), the master finds each object where it now is.
  Cia402DriveConfig config = Rig::rig_config();
  config.outputs_mapping = {{0x2002, 0, 32}, {0x6071, 0, 16}, {0x6040, 0, 16}};
  config.inputs_mapping = {{0x2001, 0, 32}, {0x6064, 0, 32}, {0x606C, 0, 32}, {0x6077, 0, 16}, {0x6041, 0, 16}};
  Rig rig(true, config);
  rig.master.boot();
  EXPECT_EQ(rig.master.layout().output_offset(0x6040), 6);
  EXPECT_EQ(rig.master.layout().input_offset(0x6041), 14);
  EXPECT_EQ(rig.drive->dictionary().get_or(kObjectTxPdoAssign, 0, 0), 2) << "96 bits: two TxPDOs of 64";
  rig.master.start();
  rig.master.enable_and_wait();
  run_against_reference(rig, 300);
  EXPECT_EQ(rig.drive->periods(), 300u);
}

TEST(EthercatCia402Drive, AMappingTheDriveRefusesStopsTheBootNamingTheObjectAndTheAbort) {
  Cia402DriveConfig config = Rig::rig_config();
  config.outputs_mapping = {{0x6040, 0, 16}, {0x6071, 0, 16}, {0x5FFF, 0, 16}};  // no such object
  Rig rig(true, config);
  try {
    rig.master.boot();
    FAIL() << "booted with a mapping of an object the drive does not have";
  } catch (const Cia402DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("0x1600:0 = 0x03 aborted"), std::string::npos) << e.what();
  }
  EXPECT_EQ(rig.drive->esc().al_state(), AlState::kPreOp) << "the boot stopped before SAFEOP";
}

TEST(EthercatCia402DriveConfig, ThePdoSectionIsReadAsEntriesAndBadOnesAreRefusedNamingTheKey) {
  const std::string root = std::string(PMLSM_SOURCE_DIR) + "/configs/ethercat/drive.yaml";
  const Cia402DriveConfig shipped = load_ethercat_config(root);
  ASSERT_EQ(shipped.outputs_mapping.size(), 7u);
  EXPECT_EQ(shipped.outputs_mapping[6], (canopen::PdoMapEntry{0x2002, 0, 32}));
  ASSERT_EQ(shipped.inputs_mapping.size(), 6u);
  EXPECT_EQ(shipped.mode, canopen::kModeCyclicSynchronousTorque);
  std::ifstream in(root);
  std::stringstream text;
  text << in.rdbuf();
  const std::string yaml = text.str();
  const std::string pdo = yaml.substr(yaml.find("\npdo:") + 1);
  const std::string without_pdo = yaml.substr(0, yaml.find("\npdo:") + 1);
  EXPECT_TRUE(parse_ethercat_config(without_pdo, "no pdo").outputs_mapping.empty()) << "the drive's own";
  const auto refused = [&](const std::string& section, const std::string& what) {
    try {
      parse_ethercat_config(without_pdo + section, "test");
      ADD_FAILURE() << "accepted:\n" << section;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  refused("pdo:\n  outputs: {value: [\"0x6040:0:16\"], source: \"chosen: x\"}\n", "pdo.inputs");
  refused(pdo + "  extra: {value: 1, source: \"chosen: x\"}\n", "pdo.extra");
  refused(
      "pdo:\n  outputs: {value: [\"0x6040:0:12\"], source: \"chosen: x\"}\n  inputs: {value: "
      "[\"0x6041:0:16\"], source: \"chosen: x\"}\n",
      "pdo.outputs[0]");
  refused(
      "pdo:\n  outputs: {value: [], source: \"chosen: x\"}\n  inputs: {value: [\"0x6041:0:16\"], source: "
      "\"chosen: x\"}\n",
      "pdo.outputs");
  // The mode by its name; another is refused with the choices.
  std::string csv = yaml;
  csv.replace(csv.find("mode: {value: cst"), 17, "mode: {value: csv");
  EXPECT_EQ(parse_ethercat_config(csv, "csv").mode, canopen::kModeCyclicSynchronousVelocity);
  std::string pv = yaml;
  pv.replace(pv.find("mode: {value: cst"), 17, "mode: {value: pv ");
  try {
    parse_ethercat_config(pv, "test");
    ADD_FAILURE() << "profile velocity accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("drive.mode: must be one of cst"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pmlsm::ethercat::backend_test
