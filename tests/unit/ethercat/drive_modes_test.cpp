// Our EtherCAT master's CiA 402 drive in cyclic synchronous velocity and position against the
// virtual drive closing those loops itself (the system's velocity PI), in this thread: the boot
// writes the mode and finds its targets in the mapping (or names the one missing, or the mode the
// drive refuses); in velocity mode a setpoint through the seam is, tick for tick, the simulated
// drive stepped directly with VelocityPi on its readings (target and torque offset as the
// dictionary carries them), the reading's applied force the drive's torque demand; in position
// mode the drive follows the reference's motion from where it was enabled. And a sensor on the load
// (a load encoder's 0x60E4:1, an accelerometer's 0x2003) reaches the master's reading where mapped.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/control/velocity_pi.hpp"
#include "pmlsm/ethercat/cia402_drive.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "shipped_drive.hpp"

namespace pmlsm::ethercat::modes_test {
namespace {

constexpr std::int64_t kPeriodNs = 1'000'000;

canopen::PdoMapEntry entry(std::uint16_t index, std::uint8_t bits) { return {index, 0, bits}; }

/// The shipped rig file in `mode`, the outputs mapping the mode's target and offsets, the inputs
/// the torque demand too.
Cia402DriveConfig config_in(std::int8_t mode) {
  Cia402DriveConfig c = test::ShippedDrive::rig_config();
  c.mode = mode;
  c.outputs_mapping = {entry(canopen::kObjectControlword, 16),    entry(canopen::kObjectTargetVelocity, 32),
                       entry(canopen::kObjectTargetPosition, 32), entry(canopen::kObjectVelocityOffset, 32),
                       entry(canopen::kObjectTorqueOffset, 16),   entry(canopen::kObjectCommandTick, 32)};
  c.inputs_mapping = {entry(canopen::kObjectStatusword, 16),     entry(canopen::kObjectTorqueActual, 16),
                      entry(canopen::kObjectVelocityActual, 32), entry(canopen::kObjectPositionActual, 32),
                      entry(canopen::kObjectTorqueDemand, 16),   entry(canopen::kObjectPeriodsStepped, 32)};
  return c;
}

/// The virtual drive (the CANopen device's dictionary, own loops or not) on a segment of its own,
/// a period per frame; our master on it.
struct ModesRig : test::ShippedDrive {
  ModesRig(const Cia402DriveConfig& config, bool own_loops, const std::function<void(SystemParams&)>& edit = {})
      : test::ShippedDrive(edit),
        drive(make_drive(true, own_loops)),
        segment({&drive->esc()}),
        link(segment, [this] { drive->after_frame(now_ns += kPeriodNs); }),
        master(config, link) {}
  void boot_and_enable() {
    master.boot();
    master.start();
    master.enable_and_wait();
  }
  std::unique_ptr<VirtualEthercatDrive> drive;
  VirtualSegment segment;
  std::int64_t now_ns = 0;
  VirtualSegmentLink link;
  Cia402Drive master;
};

TEST(EthercatDriveModes, VelocityModeIsTheDrivesOwnPiOnItsReadingsWithTheCompensationAsTorqueOffset) {
  ModesRig rig(config_in(canopen::kModeCyclicSynchronousVelocity), true);
  rig.boot_and_enable();
  EXPECT_EQ(rig.drive->dictionary().get_or(canopen::kObjectModesOfOperationDisplay, 0, 0),
            canopen::kModeCyclicSynchronousVelocity);

  SimulatedDriveBackend reference(rig.system, PlantInitialCondition{});
  for (const auto c :
       {drive::DriveCommand::kShutdown, drive::DriveCommand::kSwitchOn, drive::DriveCommand::kEnableOperation}) {
    ASSERT_TRUE(reference.request(c).accepted);
  }
  VelocityPi pi(
      canopen::DriveOwnLoopsParams::like_controller(rig.system.velocity_loop, rig.system.timing.control_period_s)
          .velocity);
  const canopen::UnitScaling& scaling = rig.master.scaling();
  drive::Measurement expected = reference.sample();
  double expected_force_n = 0.0;
  double farthest_m = 0.0;
  for (int k = 0; k < 600; ++k) {
    const drive::Measurement m = rig.master.sample();
    ASSERT_FALSE(rig.master.lost()) << "tick " << k << ": " << rig.master.last_problem();
    ASSERT_EQ(scaling.metres_to_increments(m.position_m).value, scaling.metres_to_increments(expected.position_m).value)
        << "tick " << k;
    if (k > 0) {  // the force the drive's loop applied over the tick before: its torque demand
      ASSERT_EQ(scaling.force_to_per_mille(m.applied_force_n).value, scaling.force_to_per_mille(expected_force_n).value)
          << "tick " << k;
    }
    drive::Setpoint s;
    s.velocity_mps = 0.1 * std::sin(2.0 * M_PI * k / 300.0);
    s.feedforward_force_n = 15.0 * std::cos(2.0 * M_PI * k / 70.0);
    s.force_n = 999.0;  // the controller's whole force: not this mode's
    rig.master.apply_setpoint(s);
    // The drive's loop on the same reading, with the target and offset as the dictionary holds them.
    const double target_mps = scaling.increments_to_velocity(scaling.velocity_to_increments(s.velocity_mps).value);
    const double offset_n = scaling.per_mille_to_force(scaling.force_to_per_mille(s.feedforward_force_n).value);
    expected_force_n = pi.step({target_mps, expected.velocity_mps, offset_n}).force_n;
    reference.apply(expected_force_n);
    expected = reference.sample();
    farthest_m = std::max(farthest_m, std::abs(expected.position_m));
  }
  EXPECT_GT(farthest_m, 5e-3) << "the setpoint moved the motor (0.1 m/s for 150 ms: 9.5 mm)";
  EXPECT_EQ(rig.master.counters().working_counter_errors, 0u);
  EXPECT_EQ(rig.master.fault_count(), 0u);
}

TEST(EthercatDriveModes, PositionModeFollowsTheReferencesMotionFromWhereTheDriveWasEnabled) {
  ModesRig rig(config_in(canopen::kModeCyclicSynchronousPosition), true);
  rig.boot_and_enable();
  const double start_m = rig.master.sample().position_m;
  double x_ref_m = 0.25;  // wherever the controller's integral stands: the drive moves from where it is
  double worst_error_m = 0.0;
  drive::Measurement m;
  for (int k = 0; k < 1500; ++k) {
    const double v_mps = k < 1000 ? 0.05 * std::sin(M_PI * k / 1000.0) : 0.0;
    drive::Setpoint s;
    s.velocity_mps = v_mps;
    s.position_m = x_ref_m;
    rig.master.apply_setpoint(s);
    x_ref_m += v_mps * 1e-3;
    m = rig.master.sample();
    ASSERT_FALSE(rig.master.lost()) << "tick " << k << ": " << rig.master.last_problem();
    worst_error_m = std::max(worst_error_m, std::abs(m.position_m - start_m - (x_ref_m - 0.25)));
  }
  const double travel_m = x_ref_m - 0.25;  // 0.05 m/s x 2/pi x 1 s
  EXPECT_NEAR(travel_m, 0.0318, 1e-3);
  EXPECT_NEAR(m.position_m - start_m, travel_m, 10e-6) << "at rest on the target, to 10 increments";
  EXPECT_LT(worst_error_m, 1e-3) << "following error under 1 mm on the way";
  EXPECT_EQ(rig.master.fault_count(), 0u);
}

TEST(EthercatDriveModes, TheBootNamesTheTargetTheMappingLacksAndTheModeTheDriveRefuses) {
  {
    Cia402DriveConfig c = config_in(canopen::kModeCyclicSynchronousVelocity);
    c.outputs_mapping.erase(c.outputs_mapping.begin() + 1);  // no 0x60FF
    ModesRig rig(c, true);
    try {
      rig.master.boot();
      FAIL() << "booted without the target velocity";
    } catch (const Cia402DriveError& e) {
      EXPECT_NE(std::string(e.what()).find("0x60FF (target velocity)"), std::string::npos) << e.what();
    }
  }
  {
    ModesRig rig(config_in(canopen::kModeCyclicSynchronousPosition), false);  // a torque-only drive
    try {
      rig.master.boot();
      FAIL() << "a torque-only drive took cyclic synchronous position";
    } catch (const Cia402DriveError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("0x6060:0 (modes of operation, csp)"), std::string::npos) << what;
      EXPECT_NE(what.find("0x06090030"), std::string::npos) << what;
    }
  }
}

TEST(EthercatDriveModes, OutsideOperationEnabledTheTargetsHoldTheDriveStill) {
  ModesRig rig(config_in(canopen::kModeCyclicSynchronousPosition), true);
  rig.boot_and_enable();
  ASSERT_TRUE(rig.master.request(drive::DriveCommand::kDisableOperation).accepted);
  drive::Setpoint s;
  s.velocity_mps = 0.2;
  s.position_m = 1.0;
  s.feedforward_force_n = 50.0;
  for (int k = 0; k < 20; ++k) {
    rig.master.sample();
    rig.master.apply_setpoint(s);
  }
  const canopen::ObjectDictionary& od = rig.drive->dictionary();
  EXPECT_EQ(od.get_or(canopen::kObjectTargetPosition, 0, -1), od.get_or(canopen::kObjectPositionActual, 0, -2));
  EXPECT_EQ(od.get_or(canopen::kObjectVelocityOffset, 0, -1), 0);
  EXPECT_EQ(od.get_or(canopen::kObjectTorqueOffset, 0, -1), 0);
  EXPECT_EQ(rig.drive->applied_force_n(), 0.0);
}

// A sensor on the load (sensors.load), read by the virtual drive from its plant and carried in its
// inputs: a load encoder's position in 0x60E4:1, an accelerometer's reading in 0x2003; the master's
// reading holds them where the inputs map them, NaN where they do not.
TEST(EthercatLoadSensor, TheLoadsSensorReachesTheMasterThroughTheDrivesInputs) {
  for (const LoadSensorKind kind : {LoadSensorKind::kEncoder, LoadSensorKind::kAccelerometer}) {
    const bool encoder = kind == LoadSensorKind::kEncoder;
    Cia402DriveConfig c = test::ShippedDrive::rig_config();
    c.inputs_mapping.push_back(encoder ? canopen::PdoMapEntry{canopen::kObjectAdditionalPositionActual, 1, 32}
                                       : canopen::PdoMapEntry{canopen::kObjectLoadAcceleration, 0, 32});
    ModesRig rig(c, false, [&](SystemParams& s) {
      s.load_sensor.kind = kind;
      s.load_sensor.noise_density_mps2_per_sqrt_hz = 0.0;
      s.load_sensor.bandwidth_hz = 1e5;  // the reading is the truth, to the unit
    });
    rig.boot_and_enable();
    EXPECT_EQ(rig.master.load_sensor(), encoder ? LoadSensorKind::kEncoder : LoadSensorKind::kAccelerometer);
    double widest_stretch_m = 0.0;
    for (int k = 0; k < 400; ++k) {
      const drive::Measurement m = rig.master.sample();
      ASSERT_FALSE(rig.master.lost()) << rig.master.last_problem();
      const Plant& plant = rig.behind.simulated_drive().plant();  // where the drive read its sensor
      if (encoder) {
        ASSERT_TRUE(std::isnan(m.load_acceleration_mps2));
        ASSERT_NEAR(m.load_position_m, plant.state().load_position_m, 1e-6) << "tick " << k;
        widest_stretch_m = std::max(widest_stretch_m, std::abs(m.load_position_m - m.position_m));
      } else {
        ASSERT_TRUE(std::isnan(m.load_position_m));
        ASSERT_NEAR(m.load_acceleration_mps2, plant.truth().load_accel_mps2, 1e-6) << "tick " << k;
      }
      rig.master.apply(120.0 * std::sin(2.0 * M_PI * k / 150.0));
    }
    if (encoder) {
      EXPECT_GT(widest_stretch_m, 10e-6) << "the load's own position, not the motor's";
    }
  }
  // Unmapped: no sensor in the reading, whatever the drive has.
  ModesRig rig(test::ShippedDrive::rig_config(), false,
               [](SystemParams& s) { s.load_sensor.kind = LoadSensorKind::kEncoder; });
  rig.boot_and_enable();
  EXPECT_EQ(rig.master.load_sensor(), LoadSensorKind::kNone);
  EXPECT_TRUE(std::isnan(rig.master.sample().load_position_m));
}

}  // namespace
}  // namespace pmlsm::ethercat::modes_test
