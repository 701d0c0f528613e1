// The sensor on the load (pmlsm/plant/load_sensor.hpp) against its equations: an encoder's count
// and latency, an accelerometer's noise density, bandwidth, bias walk and rail, seeded; none reads
// nothing; and the simulated drive reads it from the plant beside the motor's encoder, off by
// default in the shipped system file.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "pmlsm/config/config.hpp"
#include "pmlsm/plant/load_sensor.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/simulated_drive.hpp"

namespace pmlsm {
namespace load_sensor_test {

constexpr double kPeriodS = 1e-3;
constexpr double kTwoPi = 6.283185307179586476925;

/// No sensor, each kind's values plausible (the shipped file's).
LoadSensorParams none() {
  LoadSensorParams p;
  p.resolution_m = 1e-6;
  p.noise_density_mps2_per_sqrt_hz = 9.80665e-4;
  p.bandwidth_hz = 1000.0;
  p.range_mps2 = 156.9064;
  p.fault_after_s = 0.01;
  p.saturated_fail_after_s = 0.3;
  p.max_speed_mps = 5.0;
  p.stuck_travel_m = 5e-4;
  return p;
}

LoadSensorParams encoder(double resolution_m, std::uint32_t latency_ticks = 0) {
  LoadSensorParams p = none();
  p.kind = LoadSensorKind::kEncoder;
  p.resolution_m = resolution_m;
  p.latency_ticks = latency_ticks;
  return p;
}

LoadSensorParams accelerometer() {
  LoadSensorParams p = none();
  p.kind = LoadSensorKind::kAccelerometer;
  p.noise_density_mps2_per_sqrt_hz = 0.0;
  p.bandwidth_hz = 1e5;  // a gain of 1 - e^-628: the input itself
  return p;
}

TEST(LoadSensor, WithoutASensorNothingIsMeasured) {
  LoadSensor sensor(none(), kPeriodS);
  const LoadSensorReading r = sensor.step(0.01, 3.0);
  EXPECT_TRUE(std::isnan(r.position_m));
  EXPECT_TRUE(std::isnan(r.acceleration_mps2));
  EXPECT_EQ(sensor.counters().readings, 0u);
}

TEST(LoadSensor, AnEncoderCountsTheLoadsPositionDownToItsResolutionAfterItsLatency) {
  LoadSensor sensor(encoder(1e-6, 2), kPeriodS);
  sensor.reset(0.5);
  std::vector<double> readings;
  for (const double x : {0.5000017, 0.5000029, -0.0000005, 0.25}) readings.push_back(sensor.step(x, 0.0).position_m);
  // Two ticks late: the rest position twice, then the first two positions floored to the count.
  EXPECT_DOUBLE_EQ(readings[0], 0.5);
  EXPECT_DOUBLE_EQ(readings[1], 0.5);
  EXPECT_NEAR(readings[2], 0.500001, 1e-12);
  EXPECT_NEAR(readings[3], 0.500002, 1e-12);
  LoadSensor now(encoder(1e-6), kPeriodS);
  EXPECT_NEAR(now.step(-0.0000005, 0.0).position_m, -1e-6, 1e-15) << "a count below zero, as floor counts";
  EXPECT_TRUE(std::isnan(now.step(0.0, 0.0).acceleration_mps2));
}

TEST(LoadSensor, AnAccelerometersNoiseHasItsDensityOverTheSamplingBand) {
  LoadSensorParams p = accelerometer();
  p.noise_density_mps2_per_sqrt_hz = 1e-3;
  p.noise_seed = 7;
  LoadSensor sensor(p, kPeriodS);
  double sum = 0, sum_sq = 0;
  const int n = 200000;
  for (int k = 0; k < n; ++k) {
    const double y = sensor.step(0.0, 0.0).acceleration_mps2;
    sum += y;
    sum_sq += y * y;
  }
  // White over f_s / 2 = 500 Hz: sigma = N sqrt(500 Hz) = 22.4 mm/s^2.
  const double mean = sum / n;
  const double std = std::sqrt(sum_sq / n - mean * mean);
  EXPECT_NEAR(std, 1e-3 * std::sqrt(500.0), 0.01 * 1e-3 * std::sqrt(500.0));
  EXPECT_NEAR(mean, 0.0, 5.0 * std / std::sqrt(static_cast<double>(n)));
  // The same seed, the same readings.
  LoadSensor again(p, kPeriodS);
  LoadSensor same(p, kPeriodS);
  for (int k = 0; k < 100; ++k)
    ASSERT_EQ(again.step(0.0, 1.0).acceleration_mps2, same.step(0.0, 1.0).acceleration_mps2);
}

TEST(LoadSensor, AnAccelerometersBandwidthIsAFirstOrderLowPassAtTheTick) {
  LoadSensorParams p = accelerometer();
  p.bandwidth_hz = 20.0;
  LoadSensor sensor(p, kPeriodS);
  // A step of 1 m/s^2 reaches 1 - e^-1 after one time constant, 1 / (2 pi 20 Hz) = 7.96 ms.
  const double gain = 1.0 - std::exp(-kTwoPi * 20.0 * kPeriodS);
  double y = 0.0;
  for (int k = 1; k <= 8; ++k) {
    y = sensor.step(0.0, 1.0).acceleration_mps2;
    ASSERT_NEAR(y, 1.0 - std::pow(1.0 - gain, k), 1e-12) << "tick " << k;
  }
  EXPECT_NEAR(y, 1.0 - std::exp(-8.0 * kTwoPi * 20.0 * kPeriodS), 1e-12);
  // A sine at the bandwidth comes out near 1 / sqrt(2) of its amplitude.
  LoadSensor sine(p, kPeriodS);
  double peak = 0.0;
  for (int k = 0; k < 2000; ++k) {
    const double out = sine.step(0.0, std::sin(kTwoPi * 20.0 * k * kPeriodS)).acceleration_mps2;
    if (k > 1000) peak = std::max(peak, std::abs(out));
  }
  EXPECT_NEAR(peak, 1.0 / std::sqrt(2.0), 0.03);
}

TEST(LoadSensor, AnAccelerometersBiasWalksAndItsRailSaturatesTheReading) {
  LoadSensorParams p = accelerometer();
  p.bias_mps2 = 0.2;
  p.bias_drift_mps2_per_sqrt_s = 0.01;
  p.noise_seed = 3;
  LoadSensor sensor(p, kPeriodS);
  EXPECT_NEAR(sensor.step(0.0, 0.0).acceleration_mps2, 0.2, 1e-3) << "the bias is read at rest";
  // After 100 s the walk's spread is D sqrt(t) = 0.1 m/s^2: it moved, and not by 10 sigma.
  for (int k = 0; k < 100000; ++k) sensor.step(0.0, 0.0);
  EXPECT_NE(sensor.bias_mps2(), 0.2);
  EXPECT_LT(std::abs(sensor.bias_mps2() - 0.2), 1.0);
  LoadSensorParams railed = accelerometer();
  railed.range_mps2 = 10.0;
  LoadSensor rail(railed, kPeriodS);
  const LoadSensorReading r = rail.step(0.0, 25.0);
  EXPECT_EQ(r.acceleration_mps2, 10.0);
  EXPECT_TRUE(r.saturated);
  EXPECT_FALSE(rail.step(0.0, -9.0).saturated);
  EXPECT_EQ(rail.counters().saturated, 1u);
  // A truth that is not finite holds the last reading, counted.
  EXPECT_EQ(rail.step(0.0, std::nan("")).acceleration_mps2, -9.0);
  EXPECT_EQ(rail.counters().rejected_inputs, 1u);
}

TEST(LoadSensor, BadParametersAreRefusedByName) {
  LoadSensorParams p = encoder(0.0);
  EXPECT_THROW(LoadSensor(p, kPeriodS), std::invalid_argument);
  p = encoder(1e-6, LoadSensorParams::kMaxLatencyTicks + 1);
  try {
    LoadSensor sensor(p, kPeriodS);
    FAIL() << "a latency past the line accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("latency_ticks"), std::string::npos) << e.what();
  }
  EXPECT_THROW(LoadSensor(encoder(1e-6), 0.0), std::invalid_argument);
  EXPECT_THROW(load_sensor_kind_from_string("gyro"), std::invalid_argument);
  EXPECT_EQ(load_sensor_kind_from_string("accelerometer"), LoadSensorKind::kAccelerometer);
}

TEST(LoadSensor, TheSimulatedDriveReadsTheLoadBesideTheMotorsEncoder) {
  SystemParams params = load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml");
  EXPECT_EQ(params.load_sensor.kind, LoadSensorKind::kNone) << "the paper's rig: the motor's encoder only";
  PlantInitialCondition initial;
  initial.load_position_m = 5e-4;  // the spring stretched half a millimetre
  {
    SimulatedDriveBackend drive(params, initial);
    const drive::Measurement m = drive.sample();
    EXPECT_TRUE(std::isnan(m.load_position_m));
    EXPECT_TRUE(std::isnan(m.load_acceleration_mps2));
  }
  params.load_sensor.kind = LoadSensorKind::kEncoder;
  {
    SimulatedDriveBackend drive(params, initial);
    const drive::Measurement m = drive.sample();
    EXPECT_NEAR(m.load_position_m, 5e-4, 1e-6);
    EXPECT_NEAR(m.position_m, 0.0, 1e-6) << "the motor's encoder reads the motor";
  }
  params.load_sensor.kind = LoadSensorKind::kAccelerometer;
  params.load_sensor.noise_density_mps2_per_sqrt_hz = 0.0;
  params.load_sensor.bandwidth_hz = 1e5;
  {
    SimulatedDriveBackend drive(params, initial);
    const drive::Measurement m = drive.sample();
    // The stretched spring pulls the load back: a_l = -k (x_l - x_m) / m_l (less its friction).
    EXPECT_LT(m.load_acceleration_mps2, 0.0);
    EXPECT_NEAR(m.load_acceleration_mps2, drive.simulated_drive().plant().truth().load_accel_mps2, 1e-9);
  }
}

TEST(LoadSensor, ACutCableSilencesItFromItsTime) {
  LoadSensorParams p = load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml").load_sensor;
  EXPECT_EQ(p.silent_after_s, 0.0) << "never, as shipped";
  p.kind = LoadSensorKind::kEncoder;
  p.silent_after_s = 0.005;
  LoadSensor sensor(p, 1e-3);
  sensor.reset(0.0);
  for (int k = 0; k < 10; ++k) {
    const LoadSensorReading r = sensor.step(1e-3 * k, 0.0);
    EXPECT_EQ(std::isnan(r.position_m), k >= 5) << k;
  }
  EXPECT_EQ(sensor.counters().silent, 5u);
  sensor.reset(0.0);  // a new run: read again until its time
  EXPECT_FALSE(std::isnan(sensor.step(0.0, 0.0).position_m));
}

// In the loop: the cable cut at 0.5 s, the filter's judge fails the sensor ten ticks later, and the
// run says so: the trace's records from then on, the reason the results table and the exit code use.
TEST(LoadSensor, ASensorThatFailsInTheLoopIsReportedWithItsTickAndWhy) {
  SystemParams params = load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml");
  params.load_sensor.kind = LoadSensorKind::kEncoder;
  const Scenario pulse =
      load_scenario(std::string(PMLSM_SOURCE_DIR) + "/configs/scenarios/pulse.yaml", params.timing.control_period_s);
  EXPECT_EQ(load_sensor_failure_reason(run_scenario(params, pulse)), "") << "a sensor that reads throughout";
  params.load_sensor.silent_after_s = 0.5;
  const std::vector<TickRecord> trace = run_scenario(params, pulse);
  EXPECT_EQ(trace[400].load_sensor_use, LoadSensorUse::kUsed);
  EXPECT_FALSE(std::isnan(trace[499].load_position_measured_m));
  EXPECT_TRUE(std::isnan(trace[500].load_position_measured_m));
  EXPECT_EQ(trace[500].load_sensor_use, LoadSensorUse::kRefused);
  EXPECT_EQ(trace[500].load_sensor_fault, LoadSensorFault::kSilent);
  EXPECT_EQ(trace[509].load_sensor_use, LoadSensorUse::kFailed) << "bad for 10 ms in a row";
  EXPECT_EQ(trace.back().load_sensor_use, LoadSensorUse::kFailed) << "latched";
  EXPECT_EQ(load_sensor_failure_reason(trace),
            "the load's sensor failed at tick 509 (t = 0.509 s): silent (no reading); the estimate from then on "
            "is the motor side's alone");
}

}  // namespace load_sensor_test
}  // namespace pmlsm
