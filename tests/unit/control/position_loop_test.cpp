// The position loop over the velocity loop: its law, its bound, its origins and its fall back
// from the load's encoder to the motor's.
#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>

#include "pmlsm/control/position_loop.hpp"

namespace pmlsm {
namespace {

const double kNoReading = std::numeric_limits<double>::quiet_NaN();  // no believed load reading; a bad input

PositionLoopParams loop_on(PositionFeedback closes_on) {
  PositionLoopParams p;
  p.closes_on = closes_on;
  p.gain_per_s = 10.0;
  p.max_correction_mps = 0.01;
  return p;
}

TEST(PositionLoop, CorrectsFromEachEncodersOwnOrigin) {
  PositionLoop load(loop_on(PositionFeedback::kLoad));
  PositionLoop motor(loop_on(PositionFeedback::kMotor));
  // The scales' zeros differ (motor at 0.2 m, load at -0.05 m); each counts from its first reading.
  EXPECT_EQ(load.step({0.0, 0.2, -0.05}).correction_mps, 0.0);
  EXPECT_EQ(motor.step({0.0, 0.2, -0.05}).correction_mps, 0.0);
  // x_ref moved 100 um; the motor 100 um, the load 60 um (the spring stretched): the dual loop
  // asks 10/s x 40 um more, the semi-closed loop nothing.
  const PositionLoopOutput on_load = load.step({100e-6, 0.2 + 100e-6, -0.05 + 60e-6});
  EXPECT_TRUE(on_load.on_load);
  EXPECT_NEAR(on_load.position_error_m, 40e-6, 1e-12);
  EXPECT_NEAR(on_load.correction_mps, 400e-6, 1e-12);
  const PositionLoopOutput on_motor = motor.step({100e-6, 0.2 + 100e-6, -0.05 + 60e-6});
  EXPECT_FALSE(on_motor.on_load);
  EXPECT_NEAR(on_motor.correction_mps, 0.0, 1e-12);
}

TEST(PositionLoop, BoundsTheCorrectionAndCountsIt) {
  PositionLoop loop(loop_on(PositionFeedback::kMotor));
  loop.step({0.0, 0.0, kNoReading});
  // 5 mm behind: 50 mm/s asked, 10 mm/s given.
  EXPECT_DOUBLE_EQ(loop.step({5e-3, 0.0, kNoReading}).correction_mps, 0.01);
  EXPECT_DOUBLE_EQ(loop.step({-5e-3, 0.0, kNoReading}).correction_mps, -0.01);
  EXPECT_EQ(loop.counters().saturated, 2u);
}

TEST(PositionLoop, FallsBackToTheMotorsEncoderWithoutAJumpAndBack) {
  PositionLoop loop(loop_on(PositionFeedback::kLoad));
  loop.step({0.0, 0.0, 0.0});
  const PositionLoopOutput before = loop.step({1e-4, 1e-4, 0.7e-4});  // 30 um behind on the load
  ASSERT_NEAR(before.position_error_m, 30e-6, 1e-12);
  // The load's reading refused: the motor's encoder (30 um further on than the load) goes on from
  // the same error, not from its own (zero) one.
  const PositionLoopOutput fallen = loop.step({1e-4, 1e-4, kNoReading});
  EXPECT_FALSE(fallen.on_load);
  EXPECT_NEAR(fallen.position_error_m, 30e-6, 1e-12);
  EXPECT_NEAR(loop.step({1e-4, 1.1e-4, kNoReading}).position_error_m, 20e-6, 1e-12);  // it follows the motor now
  EXPECT_EQ(loop.counters().switches_to_motor, 1u);
  EXPECT_EQ(loop.counters().ticks_on_motor, 2u);
  // The load believed again: back on it, from the error the motor side left.
  const PositionLoopOutput back = loop.step({1e-4, 1.1e-4, 0.5e-4});
  EXPECT_TRUE(back.on_load);
  EXPECT_NEAR(back.position_error_m, 20e-6, 1e-12);
  EXPECT_NEAR(loop.step({1e-4, 1.1e-4, 0.6e-4}).position_error_m, 10e-6, 1e-12);
}

TEST(PositionLoop, NoneCorrectsNothingAndBadInputHoldsTheLastCorrection) {
  PositionLoop none(loop_on(PositionFeedback::kNone));
  EXPECT_EQ(none.step({1.0, 0.0, 0.0}).correction_mps, 0.0);
  EXPECT_EQ(none.counters().steps, 0u);

  PositionLoop loop(loop_on(PositionFeedback::kMotor));
  loop.step({0.0, 0.0, kNoReading});
  const double held = loop.step({1e-4, 0.0, kNoReading}).correction_mps;
  EXPECT_EQ(loop.step({kNoReading, 0.0, kNoReading}).correction_mps, held);
  EXPECT_EQ(loop.step({1e-4, kNoReading, kNoReading}).correction_mps, held);
  EXPECT_EQ(loop.counters().rejected_inputs, 2u);
}

TEST(PositionLoop, RefusesBadParametersNamingThem) {
  PositionLoopParams p = loop_on(PositionFeedback::kLoad);
  p.gain_per_s = -1.0;
  try {
    PositionLoop loop(p);
    FAIL() << "a negative gain was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gain_per_s"), std::string::npos) << e.what();
  }
  EXPECT_THROW(position_feedback_from_string("encoder"), std::invalid_argument);
  PositionLoop loop(loop_on(PositionFeedback::kLoad));
  EXPECT_THROW(loop.set_params(loop_on(PositionFeedback::kMotor)), std::invalid_argument);
  PositionLoopParams faster = loop_on(PositionFeedback::kLoad);
  faster.gain_per_s = 20.0;
  loop.set_params(faster);
  EXPECT_EQ(loop.params().gain_per_s, 20.0);
}

}  // namespace
}  // namespace pmlsm
