// The drive application's cyclic synchronous modes over the shipped system's simulated drive: in
// velocity mode the drive's own PI (VelocityPi, the system file's gains) follows 0x60FF with 0x60B2
// inside its saturation, period for period what VelocityPi stepped beside it on the same readings
// computes; in position mode its position loop brings the motor to 0x607A; 0x6060 takes only the
// modes 0x6502 offers, and a drive without own loops cannot offer velocity or position.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "pmlsm/canopen/cia402_application.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/sdo.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/control/velocity_pi.hpp"
#include "pmlsm/sim/simulated_drive.hpp"

namespace application_modes {
namespace {

using namespace pmlsm;
using namespace pmlsm::canopen;

struct QuietEvents final : Cia402ApplicationEvents {
  void log(bool, const std::string&, std::int64_t) override {}
  void emergency(std::uint16_t) override { ++emergencies; }
  int emergencies = 0;
};

SystemParams shipped() { return load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml"); }

Cia402ApplicationParams params_with_loops(const SystemParams& system) {
  Cia402ApplicationParams p;
  p.scaling = {675.0, 1e6};
  p.own_loops = DriveOwnLoopsParams::like_controller(system.velocity_loop, system.timing.control_period_s);
  return p;
}

ObjectDictionary dictionary(std::uint32_t modes) {
  Cia402DictionaryConfig c;
  c.rated_torque = 675000;
  c.supported_drive_modes = modes;
  return make_cia402_dictionary(NodeId(1), c);
}

/// The simulated drive behind the application, in `mode`, walked to operation enabled.
struct Rig {
  explicit Rig(std::int8_t mode)
      : system(shipped()),
        drive(system, PlantInitialCondition{}),
        od(dictionary(kSupportedModesCyclicSynchronous)),
        app(params_with_loops(system), od, drive, events) {
    EXPECT_TRUE(od.write(kObjectModesOfOperation, 0, {static_cast<std::uint8_t>(mode), 1}).ok());
    for (const std::int64_t cw : {0x06, 0x07, 0x0F}) {
      od.set(kObjectControlword, 0, cw);
      app.apply_controlword(0);
    }
    EXPECT_TRUE(app.enabled());
  }
  SystemParams system;
  SimulatedDriveBackend drive;
  ObjectDictionary od;
  QuietEvents events;
  Cia402Application app;
};

TEST(Cia402ApplicationModes, TheModesOfOperationAreThoseTheSupportedDriveModesOffer) {
  ObjectDictionary torque_only = dictionary(kSupportedModesTorque);
  EXPECT_EQ(torque_only.get_or(kObjectSupportedDriveModes, 0, 0), 0x200);
  EXPECT_EQ(torque_only.write(kObjectModesOfOperation, 0, {9, 1}).abort_code, kAbortValueRange);
  EXPECT_EQ(torque_only.write(kObjectModesOfOperation, 0, {8, 1}).abort_code, kAbortValueRange);
  EXPECT_TRUE(torque_only.write(kObjectModesOfOperation, 0, {10, 1}).ok());

  ObjectDictionary all = dictionary(kSupportedModesCyclicSynchronous);
  EXPECT_EQ(all.get_or(kObjectSupportedDriveModes, 0, 0), 0x380);
  for (const std::uint32_t mode : {8U, 9U, 10U}) EXPECT_TRUE(all.write(kObjectModesOfOperation, 0, {mode, 1}).ok());
  EXPECT_EQ(all.write(kObjectModesOfOperation, 0, {1, 1}).abort_code, kAbortValueRange);     // profile position
  EXPECT_EQ(all.write(kObjectModesOfOperation, 0, {0xF6, 1}).abort_code, kAbortValueRange);  // -10

  Cia402DictionaryConfig no_torque;
  no_torque.supported_drive_modes = 1U << 8;
  EXPECT_THROW(make_cia402_dictionary(NodeId(1), no_torque), std::invalid_argument);
  EXPECT_EQ(mode_from_string("csv"), kModeCyclicSynchronousVelocity);
  EXPECT_THROW(mode_from_string("pv"), std::invalid_argument);
}

TEST(Cia402ApplicationModes, ADriveWithoutOwnLoopsCannotOfferVelocityOrPosition) {
  const SystemParams system = shipped();
  SimulatedDriveBackend drive(system, PlantInitialCondition{});
  QuietEvents events;
  Cia402ApplicationParams p;
  p.scaling = {675.0, 1e6};
  ObjectDictionary od = dictionary(kSupportedModesCyclicSynchronous);
  EXPECT_THROW(Cia402Application(p, od, drive, events), std::invalid_argument);
  Cia402ApplicationParams bad = params_with_loops(system);
  bad.own_loops->position_gain_per_s = 0.0;
  EXPECT_THROW(Cia402Application(bad, od, drive, events), std::invalid_argument);
}

TEST(Cia402ApplicationModes, VelocityModeIsTheVelocityPiOnTheDrivesReadingsWithTheTorqueOffsetInside) {
  Rig rig(kModeCyclicSynchronousVelocity);
  VelocityPiParams pi_params = rig.system.velocity_loop;
  pi_params.period_s = rig.system.timing.control_period_s;
  VelocityPi beside(pi_params);
  const UnitScaling& scaling = rig.app.scaling();
  double before_mps = 0.0;
  for (int k = 0; k < 500; ++k) {
    const std::int32_t target = k < 250 ? 100000 : -50000;  // 0.1 m/s, then -0.05 m/s
    const std::int16_t offset = static_cast<std::int16_t>(k % 7 - 3);
    rig.od.set(kObjectTargetVelocity, 0, target);
    rig.od.set(kObjectTorqueOffset, 0, offset);
    const double v_mps = rig.drive.simulated_drive().tick_velocity_mps();  // the reading the period starts from
    const double expected_n =
        beside.step({scaling.increments_to_velocity(target), v_mps, scaling.per_mille_to_force(offset)}).force_n;
    rig.app.step_period(k);
    ASSERT_DOUBLE_EQ(rig.app.applied_force_n(), expected_n) << "period " << k;
    before_mps = v_mps;
  }
  EXPECT_EQ(rig.od.get_or(kObjectModesOfOperationDisplay, 0, 0), kModeCyclicSynchronousVelocity);
  EXPECT_NEAR(before_mps, -0.05, 0.01);  // it follows the target
  EXPECT_EQ(rig.app.mode(), kModeCyclicSynchronousVelocity);
}

TEST(Cia402ApplicationModes, PositionModeBringsTheMotorToTheTargetPosition) {
  Rig rig(kModeCyclicSynchronousPosition);
  rig.od.set(kObjectTargetPosition, 0, 2000);  // 2 mm
  for (int k = 0; k < 2000; ++k) rig.app.step_period(k);
  EXPECT_EQ(rig.od.get_or(kObjectModesOfOperationDisplay, 0, 0), kModeCyclicSynchronousPosition);
  EXPECT_NEAR(static_cast<double>(rig.od.get_or(kObjectPositionActual, 0, 0)), 2000.0, 20.0);
  EXPECT_NEAR(static_cast<double>(rig.od.get_or(kObjectVelocityActual, 0, 0)), 0.0, 2000.0);

  // Back to torque mode in operation: the target torque alone, the loops' state left behind.
  ASSERT_TRUE(rig.od.write(kObjectModesOfOperation, 0, {10, 1}).ok());
  rig.od.set(kObjectTargetTorque, 0, 10);
  rig.od.set(kObjectTorqueOffset, 0, 0);
  rig.app.step_period(2000);
  EXPECT_DOUBLE_EQ(rig.app.applied_force_n(), 6.75);
  EXPECT_EQ(rig.od.get_or(kObjectModesOfOperationDisplay, 0, 0), kModeCyclicSynchronousTorque);
}

TEST(Cia402ApplicationModes, OutsideOperationEnabledTheLoopsApplyNothing) {
  Rig rig(kModeCyclicSynchronousVelocity);
  rig.od.set(kObjectControlword, 0, 0x07);  // disable operation
  rig.app.apply_controlword(0);
  rig.od.set(kObjectTargetVelocity, 0, 100000);
  for (int k = 0; k < 50; ++k) rig.app.step_period(k);
  EXPECT_EQ(rig.app.applied_force_n(), 0.0);
  EXPECT_EQ(rig.events.emergencies, 0);
}

}  // namespace
}  // namespace application_modes
