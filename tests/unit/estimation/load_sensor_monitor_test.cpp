// The load sensor's judge (pmlsm/estimation/load_sensor_monitor.hpp) with the shipped window (10
// ticks at 1 kHz): silent, saturated and jumping readings refused and, ten in a row, the sensor
// failed (at the rail: 300 in a row); a count that sticks while the load moves failed within the window, a load at rest
// not; and the Kalman filter back on the motor's side once the sensor failed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

#include "pmlsm/estimation/kalman_filter.hpp"
#include "pmlsm/estimation/load_sensor_monitor.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace load_sensor_monitor_test {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

LoadSensorMonitorParams shipped(LoadSensorKind kind) {
  LoadSensorParams sensor = test::shipped_params().load_sensor;
  sensor.kind = kind;
  return LoadSensorMonitorParams::of(sensor, test::shipped_params().timing.control_period_s);
}

TEST(LoadSensorMonitor, TheShippedWindowIsTenTicks) {
  const LoadSensorMonitorParams p = shipped(LoadSensorKind::kEncoder);
  EXPECT_EQ(p.window_ticks, 10u);
  EXPECT_FALSE(p.noisy) << "an encoder";
  EXPECT_TRUE(shipped(LoadSensorKind::kAccelerometer).noisy) << "100 ug/sqrt(Hz)";
}

TEST(LoadSensorMonitor, ASilentSensorFailsAfterItsWindowAndIsNotBelievedAgain) {
  LoadSensorMonitor monitor(shipped(LoadSensorKind::kEncoder));
  EXPECT_TRUE(monitor.judge(0, 0.0, kNaN, false, 0.0).use);
  for (std::uint64_t k = 1; k <= 9; ++k) {
    const LoadSensorVerdict v = monitor.judge(k, kNaN, kNaN, false, 0.0);
    EXPECT_FALSE(v.use);
    EXPECT_EQ(v.problem, LoadSensorFault::kSilent);
    EXPECT_FALSE(monitor.failed()) << k;
  }
  EXPECT_FALSE(monitor.judge(10, kNaN, kNaN, false, 0.0).use);
  EXPECT_TRUE(monitor.failed()) << "ten ticks (10 ms) without a reading";
  EXPECT_EQ(monitor.fault(), LoadSensorFault::kSilent);
  EXPECT_EQ(monitor.failed_at_tick(), 10u);
  EXPECT_FALSE(monitor.judge(11, 0.0, kNaN, false, 0.0).use) << "latched: a failed sensor is not believed again";
  // A few silent ticks between good ones: refused, not failed.
  LoadSensorMonitor gaps(shipped(LoadSensorKind::kEncoder));
  for (std::uint64_t k = 0; k < 100; ++k) gaps.judge(k, k % 5 == 0 ? kNaN : 0.0, kNaN, false, 0.0);
  EXPECT_FALSE(gaps.failed());
  EXPECT_EQ(gaps.rejected(), 20u);
}

TEST(LoadSensorMonitor, AJumpFasterThanTheLoadMovesIsRefusedAndTheNextCountsFromIt) {
  LoadSensorMonitor monitor(shipped(LoadSensorKind::kEncoder));
  EXPECT_TRUE(monitor.judge(0, 0.001, kNaN, false, 0.0).use);
  // 5 m/s x 1 ms = 5 mm a tick at most: 10 mm in one tick is a burst of counts.
  const LoadSensorVerdict jump = monitor.judge(1, 0.011, kNaN, false, 0.0);
  EXPECT_FALSE(jump.use);
  EXPECT_EQ(jump.problem, LoadSensorFault::kJumping);
  EXPECT_TRUE(monitor.judge(2, 0.011001, kNaN, false, 0.0).use) << "the new count is the reference";
  EXPECT_FALSE(monitor.failed());
  // Garbage every tick for the window: failed.
  for (std::uint64_t k = 3; k < 13; ++k) monitor.judge(k, (k % 2 == 0 ? 1.0 : -1.0), kNaN, false, 0.0);
  EXPECT_EQ(monitor.fault(), LoadSensorFault::kJumping);
}

TEST(LoadSensorMonitor, ACountThatSticksWhileTheMotorTravelsFailsALoadAtRestDoesNot) {
  // The motor at 0.2 m/s (0.2 mm a tick), the load's count frozen: 0.5 mm of travel and ten
  // repeats (10 ms) later, stuck.
  LoadSensorMonitor moving(shipped(LoadSensorKind::kEncoder));
  for (std::uint64_t k = 0; k <= 10; ++k) moving.judge(k, 0.002, kNaN, false, 0.0002 * static_cast<double>(k));
  EXPECT_EQ(moving.fault(), LoadSensorFault::kStuck);
  EXPECT_EQ(moving.failed_at_tick(), 10u) << "ten repeats of the count: 10 ms";
  // At rest, however long, with the motor jittering a few counts about the load: not stuck.
  LoadSensorMonitor resting(shipped(LoadSensorKind::kEncoder));
  for (std::uint64_t k = 0; k < 10000; ++k) {
    resting.judge(k, 0.002, kNaN, false, 0.002 + 3e-6 * (static_cast<double>(k % 7) - 3.0));
  }
  EXPECT_FALSE(resting.failed()) << "a load at rest keeps its count";
}

TEST(LoadSensorMonitor, AnAccelerometerAtItsRailOrRepeatingItselfFails) {
  // At the rail: refused at once, failed after saturated_fail_after_s (0.3 s) there in a row.
  LoadSensorMonitor railed(shipped(LoadSensorKind::kAccelerometer));
  for (std::uint64_t k = 0; k < 299; ++k) {
    const LoadSensorVerdict v = railed.judge(k, kNaN, 156.9, true, 0.0);
    EXPECT_FALSE(v.use);
    EXPECT_EQ(v.problem, LoadSensorFault::kSaturated);
  }
  EXPECT_FALSE(railed.failed());
  EXPECT_EQ(railed.rejected(), 299u);
  railed.judge(299, kNaN, 156.9, true, 0.0);
  EXPECT_EQ(railed.fault(), LoadSensorFault::kSaturated);
  EXPECT_EQ(railed.failed_at_tick(), 299u);
  // A swing's peaks past the rail (17 ms at 28 g on a 16 g part), then live readings: used again,
  // the rail's repeated value no sign of a stuck part.
  LoadSensorMonitor peaked(shipped(LoadSensorKind::kAccelerometer));
  for (std::uint64_t k = 0; k < 17; ++k) peaked.judge(k, kNaN, -156.9, true, 0.0);
  EXPECT_TRUE(peaked.judge(17, kNaN, -150.0, false, 0.0).use);
  EXPECT_TRUE(peaked.judge(18, kNaN, -140.0, false, 0.0).use);
  EXPECT_FALSE(peaked.failed());
  LoadSensorMonitor repeating(shipped(LoadSensorKind::kAccelerometer));
  for (std::uint64_t k = 0; k <= 10; ++k) repeating.judge(k, kNaN, 0.25, false, 0.0);
  EXPECT_EQ(repeating.fault(), LoadSensorFault::kStuck) << "a live part's noise moves every tick";
  LoadSensorParams quiet = test::shipped_params().load_sensor;
  quiet.kind = LoadSensorKind::kAccelerometer;
  quiet.noise_density_mps2_per_sqrt_hz = 0.0;
  LoadSensorMonitor noiseless(LoadSensorMonitorParams::of(quiet, 1e-3));
  for (std::uint64_t k = 0; k < 100; ++k) noiseless.judge(k, kNaN, 0.25, false, 0.0);
  EXPECT_FALSE(noiseless.failed()) << "a noiseless part may repeat itself";
}

TEST(LoadSensorMonitor, TheFilterFallsBackOnTheMotorsSideWhenTheSensorFails) {
  SystemParams params = test::shipped_params();
  params.load_sensor.kind = LoadSensorKind::kEncoder;
  KalmanFilter with_sensor(params.kalman_params());
  KalmanInput in{0.0, 0.0, 0.0};
  for (int k = 0; k < 20; ++k) {
    in.load_position_m = 0.0;
    EXPECT_EQ(with_sensor.step(in).load_measurement_used, k > 0) << k;  // a velocity from the second on
  }
  in.load_position_m = kNaN;
  KalmanEstimate e;
  for (int k = 0; k < 10; ++k) e = with_sensor.step(in);
  EXPECT_TRUE(e.load_sensor_failed);
  EXPECT_EQ(with_sensor.load_monitor().fault(), LoadSensorFault::kSilent);
  // From then on the load's readings are not used, whatever they say.
  in.load_position_m = 0.05;
  for (int k = 0; k < 5; ++k) {
    const KalmanEstimate after = with_sensor.step(in);
    EXPECT_FALSE(after.load_measurement_used);
    EXPECT_TRUE(std::isfinite(after.spring_force_n));
  }
}

}  // namespace load_sensor_monitor_test
}  // namespace pmlsm
