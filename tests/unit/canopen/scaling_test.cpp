// Unit scaling: force <-> per mille of the rated force, position and velocity <-> increments.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "pmlsm/canopen/scaling.hpp"

namespace {

using namespace pmlsm::canopen;

UnitScaling scaling(double rated_force_n = 200.0, double increments_per_metre = 1e6) {
  return UnitScaling(ScalingConfig{rated_force_n, increments_per_metre});
}

TEST(ScalingTest, ConfigIsValidatedWithTheOffendingValue) {
  try {
    scaling(-1.0);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "rated_force_n: must be > 0, got -1");
  }
  try {
    scaling(100.0, 0.0);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "increments_per_metre: must be > 0, got 0");
  }
  EXPECT_THROW(scaling(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  EXPECT_THROW(scaling(100.0, std::numeric_limits<double>::infinity()), std::invalid_argument);
  EXPECT_THROW(scaling(0.0001), std::invalid_argument);  // 0 mN
  EXPECT_THROW(scaling(5e6), std::invalid_argument);     // over UNSIGNED32 mN
  EXPECT_THROW(UnitScaling::from_rated_torque_object(0, 1e6), std::invalid_argument);
}

TEST(ScalingTest, ForcePerMilleOfTheRatedForce) {
  const UnitScaling s = scaling(200.0);
  EXPECT_EQ(s.rated_torque_object(), 200000u);
  EXPECT_EQ(s.force_to_per_mille(200.0).value, 1000);
  EXPECT_EQ(s.force_to_per_mille(-50.0).value, -250);
  EXPECT_EQ(s.force_to_per_mille(0.0).value, 0);
  EXPECT_DOUBLE_EQ(s.per_mille_to_force(1000), 200.0);
  EXPECT_DOUBLE_EQ(s.per_mille_to_force(-1), -0.2);
  // Rounding to nearest, halves away from zero: 0.1 N = 0.5 per mille.
  EXPECT_EQ(s.force_to_per_mille(0.1).value, 1);
  EXPECT_EQ(s.force_to_per_mille(-0.1).value, -1);
  EXPECT_EQ(s.force_to_per_mille(0.09).value, 0);
  EXPECT_FALSE(s.force_to_per_mille(0.09).saturated);
}

TEST(ScalingTest, ForceSaturatesAtInteger16) {
  const UnitScaling s = scaling(200.0);
  // 32767 per mille = 6553.4 N.
  EXPECT_EQ(s.force_to_per_mille(6553.4).value, 32767);
  EXPECT_FALSE(s.force_to_per_mille(6553.4).saturated);
  const auto high = s.force_to_per_mille(1e6);
  EXPECT_EQ(high.value, 32767);
  EXPECT_TRUE(high.saturated);
  const auto low = s.force_to_per_mille(-1e6);
  EXPECT_EQ(low.value, -32768);
  EXPECT_TRUE(low.saturated);
  EXPECT_EQ(s.force_to_per_mille(-6553.6).value, -32768);
  EXPECT_FALSE(s.force_to_per_mille(-6553.6).saturated);
  EXPECT_TRUE(s.force_to_per_mille(std::numeric_limits<double>::infinity()).saturated);
  const auto nan = s.force_to_per_mille(std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(nan.value, 0);
  EXPECT_TRUE(nan.saturated);
}

TEST(ScalingTest, ForceRoundTripWithinHalfAStep) {
  const UnitScaling s = scaling(137.5);
  const double step = 137.5 / 1000.0;
  for (double f = -4000.0; f <= 4000.0; f += 12.345) {
    const auto pm = s.force_to_per_mille(f);
    ASSERT_FALSE(pm.saturated);
    EXPECT_LE(std::abs(s.per_mille_to_force(pm.value) - f), step / 2 + 1e-9) << f;
  }
  for (int pm = -32768; pm <= 32767; pm += 97) {
    const auto back = s.force_to_per_mille(s.per_mille_to_force(static_cast<std::int16_t>(pm)));
    EXPECT_EQ(back.value, pm);
  }
}

TEST(ScalingTest, RatedTorqueObjectIsWhatBothSidesUse) {
  const UnitScaling from_object = UnitScaling::from_rated_torque_object(137500, 1e6);
  EXPECT_EQ(from_object.rated_torque_object(), 137500u);
  EXPECT_DOUBLE_EQ(from_object.per_mille_to_force(1000), 137.5);
  // 0x6076 holds mN: a config value below 1 mN resolution is rounded, and the per-mille values
  // use the rounded value, as the drive does.
  const UnitScaling rounded = scaling(100.0004);
  EXPECT_EQ(rounded.rated_torque_object(), 100000u);
  EXPECT_DOUBLE_EQ(rounded.per_mille_to_force(1000), 100.0);
}

TEST(ScalingTest, PositionAndVelocity) {
  const UnitScaling s = scaling(100.0, 1e6);  // 1 um encoder
  EXPECT_EQ(s.metres_to_increments(0.0125).value, 12500);
  const UnitScaling quarter = scaling(100.0, 4.0);            // exact halves in binary
  EXPECT_EQ(quarter.metres_to_increments(-0.125).value, -1);  // -0.5: half away from zero
  EXPECT_EQ(quarter.metres_to_increments(0.375).value, 2);    // 1.5
  EXPECT_EQ(quarter.velocity_to_increments(0.125).value, 1);
  EXPECT_DOUBLE_EQ(s.increments_to_metres(12500), 0.0125);
  EXPECT_EQ(s.velocity_to_increments(0.25).value, 250000);
  EXPECT_DOUBLE_EQ(s.increments_to_velocity(-250000), -0.25);
  for (std::int32_t inc : {-2000000000, -12345, 0, 1, 987654321}) {
    EXPECT_EQ(s.metres_to_increments(s.increments_to_metres(inc)).value, inc);
    EXPECT_EQ(s.velocity_to_increments(s.increments_to_velocity(inc)).value, inc);
  }
  const auto far = s.metres_to_increments(3000.0);  // 3e9 increments
  EXPECT_EQ(far.value, std::numeric_limits<std::int32_t>::max());
  EXPECT_TRUE(far.saturated);
  EXPECT_EQ(s.velocity_to_increments(-3000.0).value, std::numeric_limits<std::int32_t>::min());
  EXPECT_TRUE(s.velocity_to_increments(std::nan("")).saturated);
}

}  // namespace
