// The Kalman filter of section 3.5.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "pmlsm/config/sweep_file.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/analysis/compensated_run.hpp"
#include "pmlsm/analysis/sweep.hpp"
#include "pmlsm/estimation/kalman_filter.hpp"
#include "pmlsm/sim/metrics.hpp"
#include "pmlsm/plant/plant.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

TEST(Kalman, ModelMatrices34) {
  const KalmanParams p = test::shipped_params().kalman_params();
  const Eigen::Matrix3d a = KalmanFilter::continuous_a(p);
  EXPECT_DOUBLE_EQ(a(0, 2), -1.0 / 20.0);
  EXPECT_DOUBLE_EQ(a(1, 2), 1.0 / 4.0);
  EXPECT_DOUBLE_EQ(a(2, 0), 13700.0);
  EXPECT_DOUBLE_EQ(a(2, 1), -13700.0);
  EXPECT_DOUBLE_EQ(KalmanFilter::continuous_b(p)(0), 1.0 / 20.0);
}

/// The shipped filter with the paper's input u = F_{k-1} (no modelled friction or ripple), and the paper's Q (35) or
/// the shipped one.
KalmanParams force_input_only(KalmanParams p, bool paper_q) {
  p.friction_input.enabled = false;
  p.ripple_input.enabled = false;
  if (paper_q) p.process_noise_diag = Eigen::Vector3d(100.0, 10.0, 1.0);  // (35)
  return p;
}

TEST(Kalman, IsConsistentOnItsOwnLinearModel) {
  // Monte Carlo on (26)-(27) simulated exactly, w ~ N(0, Q), v ~ N(0, R),
  // x_0 ~ N(0, P_0), for the paper's Q and the shipped one (R = the paper's):
  // for a correct filter the normalised estimation error squared e^T P^-1 e is
  // chi-square with 3 degrees of freedom, mean 3. Independent runs, because
  // within one run the errors of v_L and F_s wander slowly (the paper's Q makes
  // their variance large) and successive samples are far from independent. The
  // modelled friction and ripple are off: this model has none.
  for (const bool paper_q : {true, false}) {
    SCOPED_TRACE(paper_q ? "paper Q" : "shipped Q");
    const KalmanParams p = force_input_only(test::shipped_params().kalman_params(), paper_q);
    KalmanFilter kf(p);
    std::mt19937_64 rng(7);
    std::normal_distribution<double> normal(0.0, 1.0);
    const int runs = 1000, steps = 300;
    double nees_sum = 0;
    for (int run = 0; run < runs; ++run) {
      Eigen::Vector3d x;
      for (int i = 0; i < 3; ++i) x(i) = std::sqrt(p.initial_covariance_diag(i)) * normal(rng);
      kf.reset(Eigen::Vector3d::Zero());
      double u_prev = 0;
      for (int k = 0; k < steps; ++k) {
        x = kf.phi() * x + kf.gamma() * u_prev;
        for (int i = 0; i < 3; ++i) x(i) += std::sqrt(p.process_noise_diag(i)) * normal(rng);
        const double y = x(0) + std::sqrt(p.measurement_noise) * normal(rng);
        kf.step({y, u_prev});
        u_prev = 200.0 * std::sin(0.05 * k);
      }
      const Eigen::Vector3d e = x - kf.state();
      nees_sum += e.dot(kf.covariance().ldlt().solve(e));
    }
    // Standard deviation of the mean: sqrt(6 / 1000) = 0.077; the band is 4 of them.
    EXPECT_NEAR(nees_sum / runs, 3.0, 0.31);
  }
}

TEST(Kalman, TracksLoadVelocityAndSpringForceOnTheNoisyPlant) {
  // The nonlinear plant with encoder noise (2 um, twice the resolution),
  // friction and ripple, under the pulse reference with the PI loop alone (the
  // filter does not act on the plant, so both filters see the same motion):
  // each filter must follow the true load velocity and spring force it never
  // measures. The shipped filter trusts its v_M model (small Q_00), so the
  // encoder noise and the unmodelled lag of the drive's current loop reach its
  // F_s more than the paper's.
  struct Case {
    const char* name;
    bool paper;
    double max_rel_v, max_rel_f;
  };
  for (const Case& c : {Case{"paper", true, 0.15, 0.25},        // measured 8.7 %, 14.8 %
                        Case{"shipped", false, 0.25, 0.40}}) {  // measured 16.8 %, 28.8 %
    SystemParams params = test::shipped_params();
    if (c.paper) {
      params.kalman.friction_input.enabled = false;
      params.kalman.ripple_input.enabled = false;
      params.kalman.process_noise_diag = Eigen::Vector3d(100.0, 10.0, 1.0);
    }
    params.plant.encoder.position_noise_std_m = 2e-6;
    params.plant.encoder.noise_seed = 11;
    const Scenario scenario = test::shipped_scenario("pulse");
    const auto trace = run_scenario(params, scenario);
    double err_v = 0, err_f = 0, sig_v = 0, sig_f = 0;
    for (const TickRecord& r : trace) {
      if (r.time_s < 0.1) continue;  // past the start-up transient
      err_v += std::pow(r.est_load_velocity_mps - r.load_velocity_mps, 2);
      err_f += std::pow(r.est_spring_force_n - r.spring_force_n, 2);
      sig_v += r.load_velocity_mps * r.load_velocity_mps;
      sig_f += r.spring_force_n * r.spring_force_n;
    }
    const double rel_v = std::sqrt(err_v / sig_v), rel_f = std::sqrt(err_f / sig_f);
    std::printf("[ kalman     ] pulse, noisy plant, %s filter: v_L rms error %.1f %% of rms v_L, F_s %.1f %%\n", c.name,
                100 * rel_v, 100 * rel_f);
    EXPECT_LT(rel_v, c.max_rel_v) << c.name;
    EXPECT_LT(rel_f, c.max_rel_f) << c.name;
  }
}

/// The rms error of the estimated load velocity and spring force over the free vibration with the
/// PI loop alone, relative to their rms, with the load's sensor `kind` (sensors.load's shipped
/// values for it); and the filter's last variances of v_L and F_s.
struct LoadSensorRun {
  double rel_v = 0, rel_f = 0, var_v = 0, var_f = 0;
  std::uint64_t load_updates = 0;
};
LoadSensorRun free_vibration_with(LoadSensorKind kind) {
  SystemParams params = test::shipped_params();
  params.load_sensor.kind = kind;
  const Scenario scenario = test::shipped_scenario("free_vibration");
  ClosedLoop loop(params, scenario);
  double err_v = 0, err_f = 0, sig_v = 0, sig_f = 0;
  while (!loop.done()) {
    const TickRecord r = loop.step({});
    err_v += std::pow(r.est_load_velocity_mps - r.load_velocity_mps, 2);
    err_f += std::pow(r.est_spring_force_n - r.spring_force_n, 2);
    sig_v += r.load_velocity_mps * r.load_velocity_mps;
    sig_f += r.spring_force_n * r.spring_force_n;
  }
  LoadSensorRun run;
  run.rel_v = std::sqrt(err_v / sig_v);
  run.rel_f = std::sqrt(err_f / sig_f);
  run.var_v = loop.kalman().covariance()(1, 1);
  run.var_f = loop.kalman().covariance()(2, 2);
  run.load_updates = loop.kalman().counters().load_updates;
  return run;
}

TEST(Kalman, ASensorOnTheLoadCorrectsWhatTheMotorsEncoderCannotSee) {
  // The free vibration starts with the spring stretched (F_s = -274 N) and the motor held by the
  // PI: the motor's encoder sees the swing only through the motor, the load's sensor directly.
  const LoadSensorRun none = free_vibration_with(LoadSensorKind::kNone);
  const LoadSensorRun encoder = free_vibration_with(LoadSensorKind::kEncoder);
  const LoadSensorRun accelerometer = free_vibration_with(LoadSensorKind::kAccelerometer);
  for (const auto& [name, run] :
       {std::pair{"none", none}, std::pair{"encoder", encoder}, std::pair{"accelerometer", accelerometer}}) {
    std::printf(
        "[ kalman     ] free vibration, load sensor %s: v_L rms error %.1f %%, F_s %.1f %%; "
        "variances at the end v_L %.3g (m/s)^2, F_s %.3g N^2\n",
        name, 100 * run.rel_v, 100 * run.rel_f, run.var_v, run.var_f);
  }
  EXPECT_EQ(none.load_updates, 0u);
  EXPECT_GT(encoder.load_updates, 0u);
  EXPECT_GT(accelerometer.load_updates, 0u);
  EXPECT_LT(encoder.var_v, none.var_v) << "the load encoder's velocity: v_L's variance falls";
  EXPECT_LT(encoder.var_f, none.var_f);
  EXPECT_LT(accelerometer.var_f, none.var_f) << "the accelerometer reads F_s / m_L: F_s's variance falls";
  EXPECT_LT(encoder.rel_v, none.rel_v);
  EXPECT_LT(accelerometer.rel_f, none.rel_f);
}

TEST(Kalman, ALoadEncodersCountMeasuresTheSpringOnAStuckMotor) {
  // The motor held by its bearings (its encoder still at 0), the load swinging 20 um on the spring
  // at sqrt(k / m_L), its encoder's zero 3 mm from the motor's: a swing whose 0.27 N the motor's
  // encoder cannot see and whose 1.2 mm/s the load's two counts resolve to a step in four. The
  // count itself, offset found from the load's momentum, carries the spring force.
  KalmanParams p = test::shipped_params().kalman_params();
  LoadSensorParams sensor = test::shipped_params().load_sensor;
  sensor.kind = LoadSensorKind::kEncoder;
  p.load_measurement = KalmanLoadMeasurement::of(sensor, p.period_s, 1e-6);
  const double k = p.model.spring_n_per_m;
  const double w = std::sqrt(k / p.model.load_mass_kg);
  const double amplitude_m = 20e-6, scale_offset_m = 3e-3;
  KalmanFilter kf(p);
  double err2 = 0, sig2 = 0, offset_n = 0;
  const int steps = 2000;
  for (int i = 0; i < steps; ++i) {
    const double x_l = amplitude_m * std::cos(w * i * p.period_s);
    KalmanInput in{0.0, 0.0, 0.0};
    in.load_position_m = std::floor((x_l + scale_offset_m) / sensor.resolution_m) * sensor.resolution_m;
    const KalmanEstimate e = kf.step(in);
    if (i >= steps / 2) {
      err2 += std::pow(e.spring_force_n - (-k * x_l), 2);
      sig2 += std::pow(k * x_l, 2);
    }
    offset_n = e.stretch_offset_n;
  }
  const double rel = std::sqrt(err2 / sig2);
  std::printf(
      "[ kalman     ] 20 um swing on a stuck motor, load encoder: F_s rms error %.1f %% over the last second; "
      "scales' offset %.2f N (true %.2f)\n",
      100 * rel, offset_n, -k * scale_offset_m);
  EXPECT_LT(rel, 0.2);
  EXPECT_NEAR(offset_n, -k * scale_offset_m, 0.02 * k * scale_offset_m);
}

TEST(Kalman, AnAccelerometersBiasIsTakenOutOfItsReadings) {
  // The motor held by its bearings, the load swinging 20 um at sqrt(k / m_L), an accelerometer
  // reading its acceleration plus 20 mg (a MEMS part's uncalibrated bias): the readings integrate to
  // the load's velocity, which stays bounded, so their mean is the bias. Left in, it reads as a
  // steady 0.8 N on the spring.
  const double bias_mps2 = 0.196;
  const auto run = [&](double prior_s) {
    KalmanParams p = test::shipped_params().kalman_params();
    LoadSensorParams sensor = test::shipped_params().load_sensor;
    sensor.kind = LoadSensorKind::kAccelerometer;
    p.load_measurement = KalmanLoadMeasurement::of(sensor, p.period_s, 1e-6);
    p.accelerometer_bias_prior_s = prior_s;
    const double k = p.model.spring_n_per_m;
    const double w = std::sqrt(k / p.model.load_mass_kg);
    KalmanFilter kf(p);
    double err2 = 0, sig2 = 0, bias = 0;
    const int steps = 2000;
    for (int i = 0; i < steps; ++i) {
      const double x_l = 20e-6 * std::cos(w * i * p.period_s);
      KalmanInput in{0.0, 0.0, 0.0};
      in.load_accel_mps2 = -w * w * x_l + bias_mps2;
      const KalmanEstimate e = kf.step(in);
      if (i >= steps / 2) {
        err2 += std::pow(e.spring_force_n - (-k * x_l), 2);
        sig2 += std::pow(k * x_l, 2);
      }
      bias = e.accelerometer_bias_mps2;
    }
    return std::pair{std::sqrt(err2 / sig2), bias};
  };
  const auto [taken_out, bias] = run(test::shipped_params().kalman.accelerometer_bias_prior_s);
  const auto [left_in, ignored] = run(1e6);
  std::printf(
      "[ kalman     ] 20 um swing on a stuck motor, accelerometer 20 mg off: F_s rms error %.1f %% (bias found "
      "%.4f of %.4f m/s^2); left in %.1f %%\n",
      100 * taken_out, bias, bias_mps2, 100 * left_in);
  EXPECT_NEAR(bias, bias_mps2, 0.05 * bias_mps2);
  EXPECT_LT(taken_out, 0.2);
  EXPECT_GT(left_in, 2 * taken_out);
}

TEST(Kalman, WithoutALoadSensorTheLoadsReadingsChangeNothing) {
  // A filter declared without a load sensor ignores load readings it is given: step for step the
  // filter without them (the filter before the load's sensor existed).
  const KalmanParams params = test::shipped_params().kalman_params();
  ASSERT_EQ(params.load_measurement.kind, LoadSensorKind::kNone);
  KalmanFilter given(params);
  KalmanFilter plain(params);
  for (int k = 0; k < 500; ++k) {
    const double v = 0.1 * std::sin(0.02 * k);
    KalmanInput with_load{v, 50.0 * std::cos(0.03 * k), 0.001 * k};
    with_load.load_position_m = 0.002 * std::sin(0.05 * k);
    with_load.load_accel_mps2 = 3.0 * std::cos(0.05 * k);
    const KalmanEstimate a = given.step(with_load);
    const KalmanEstimate b = plain.step({v, 50.0 * std::cos(0.03 * k), 0.001 * k});
    ASSERT_EQ(a.load_velocity_mps, b.load_velocity_mps) << k;
    ASSERT_EQ(a.spring_force_n, b.spring_force_n) << k;
    ASSERT_EQ(a.covariance_diag, b.covariance_diag) << k;
    ASSERT_FALSE(a.load_measurement_used);
  }
  // With a sensor declared, the variance is the declaration's: an encoder's two counts over T^2.
  LoadSensorParams sensor = test::shipped_params().load_sensor;
  sensor.kind = LoadSensorKind::kEncoder;
  const KalmanLoadMeasurement encoder = KalmanLoadMeasurement::of(sensor, 1e-3, 1e-6);
  EXPECT_NEAR(encoder.variance, 2.0 * 1e-12 / 12.0 / 1e-6, 1e-15);
  EXPECT_NEAR(encoder.stretch_variance_m2, 2.0 * 1e-12 / 12.0, 1e-24) << "the load's count and the motor's";
  sensor.kind = LoadSensorKind::kAccelerometer;
  EXPECT_GT(KalmanLoadMeasurement::of(sensor, 1e-3, 1e-6).variance, 0.0);
}

TEST(Kalman, RejectsNonFiniteMeasurementAndInput) {
  KalmanFilter kf(test::shipped_params().kalman_params());
  KalmanFilter reference(test::shipped_params().kalman_params());
  kf.step({0.1, 10.0});
  reference.step({0.1, 10.0});
  const KalmanEstimate e = kf.step({std::numeric_limits<double>::quiet_NaN(), 10.0});
  EXPECT_FALSE(e.measurement_used);
  EXPECT_TRUE(kf.state().allFinite());
  kf.step({0.1, std::numeric_limits<double>::infinity()});
  EXPECT_TRUE(kf.state().allFinite());
  EXPECT_EQ(kf.counters().rejected_measurements, 1u);
  EXPECT_EQ(kf.counters().rejected_inputs, 1u);
  // The rejected input was replaced by the last finite one (10 N).
  reference.step({std::numeric_limits<double>::quiet_NaN(), 10.0});
  reference.step({0.1, 10.0});
  EXPECT_LT((kf.state() - reference.state()).norm(), 1e-12);
}

// ------------------------------------------- the modelled disturbance in the input

/// The shipped filter with both disturbance inputs on (their shipped values: the plant's).
KalmanParams with_disturbance_input(KalmanParams p, bool friction, bool ripple) {
  p.friction_input.enabled = friction;
  p.ripple_input.enabled = ripple;
  return p;
}

/// The message of the std::invalid_argument KalmanFilter(p) throws, or "" with a failure.
std::string construction_error(const KalmanParams& p) {
  try {
    KalmanFilter kf(p);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  ADD_FAILURE() << "no std::invalid_argument";
  return "";
}

TEST(KalmanDisturbanceInput, BadValuesThrowNamingTheValue) {
  // Checked whether or not the input is enabled: a bad value is a config error either way.
  for (const bool enabled : {false, true}) {
    SCOPED_TRACE(enabled ? "enabled" : "disabled");
    const KalmanParams good = with_disturbance_input(test::shipped_params().kalman_params(), enabled, enabled);
    struct Case {
      std::function<void(KalmanParams&)> edit;
      std::vector<std::string> expected;
    };
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    const std::vector<Case> cases{
        {[](KalmanParams& p) { p.friction_input.model.coulomb_n = -20; },
         {"friction_input.coulomb_n: must be in [0, 10000]", "got -20"}},
        {[](KalmanParams& p) { p.friction_input.model.viscous_n_s_per_m = -0.5; },
         {"friction_input.viscous_n_s_per_m: must be in [0, 100000]", "got -0.5"}},
        {[&](KalmanParams& p) { p.friction_input.model.viscous_n_s_per_m = nan; },
         {"friction_input.viscous_n_s_per_m: must be finite", "nan"}},
        {[](KalmanParams& p) { p.friction_input.model.regularisation_velocity_mps = 0; },
         {"friction_input.regularisation_velocity_mps: must be in [1e-07, 1]", "got 0"}},
        {[](KalmanParams& p) { p.ripple_input.model.scale_n = -10; },
         {"ripple_input.scale_n: must be in [0, 10000]", "got -10"}},
        {[&](KalmanParams& p) { p.ripple_input.model.amplitude_2 = inf; },
         {"ripple_input.amplitude_2: must be finite", "inf"}},
        {[](KalmanParams& p) { p.ripple_input.model.spatial_freq_1_rad_per_m = -418; },
         {"ripple_input.spatial_freq_1_rad_per_m: must be in [0, 100000]", "got -418"}},
    };
    for (const Case& c : cases) {
      KalmanParams bad = good;
      c.edit(bad);
      const std::string message = construction_error(bad);
      for (const std::string& part : c.expected) {
        EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
      }
    }
    EXPECT_NO_THROW(KalmanFilter kf(good));
  }
}

TEST(KalmanDisturbanceInput, FrictionIsEquation11WithASmoothSign) {
  KalmanFrictionInput f;
  f.model.coulomb_n = 20;
  f.model.viscous_n_s_per_m = 30;
  f.model.regularisation_velocity_mps = 2e-3;
  // Exact outside the band, opposing the motion.
  EXPECT_DOUBLE_EQ(f.force_n(0.1), -(20.0 + 30.0 * 0.1));
  EXPECT_DOUBLE_EQ(f.force_n(-0.1), 20.0 + 30.0 * 0.1);
  EXPECT_DOUBLE_EQ(f.force_n(2e-3), -(20.0 + 30.0 * 2e-3));
  // Inside: the cubic w (3 - w^2) / 2, odd, zero at rest.
  EXPECT_DOUBLE_EQ(f.force_n(0.0), 0.0);
  EXPECT_DOUBLE_EQ(f.force_n(1e-3), -(20.0 * 0.5 * (3.0 - 0.25) / 2.0 + 30.0 * 1e-3));
  EXPECT_DOUBLE_EQ(f.force_n(-1e-3), -f.force_n(1e-3));
}

TEST(KalmanDisturbanceInput, RippleIsThePlantsEquation10) {
  // With the plant's values (the shipped ones) the filter's ripple model is the plant's force.
  const SystemParams& sp = test::shipped_params();
  const KalmanRippleInput ripple = sp.kalman_params().ripple_input;
  ASSERT_GT(ripple.model.scale_n, 0.0);
  Plant plant(sp.plant);
  for (const double x : {0.0, 1.3e-3, 4.1e-3, 7.7e-3, -0.0123, 0.25}) {
    plant.reset({x, 0.0, x, 0.0});
    EXPECT_NEAR(ripple.force_n(x), plant.truth().ripple_n, 1e-9) << "x = " << x;
  }
}

TEST(KalmanDisturbanceInput, TimeUpdateUsesForcePlusFrictionAndRippleOfThePeriod) {
  // u_{k-1} = F_{k-1} + F_friction(y_k) + F_ripple((x_{k-1} + x_k) / 2): a filter with
  // the inputs on must match the paper's filter fed that u by hand (the standstill hold off: it
  // replaces some measurement updates, tested on its own below; so is the thrust lag).
  KalmanParams shipped = test::shipped_params().kalman_params();
  shipped.standstill_hold.enabled = false;
  shipped.thrust_lag_s = 0.0;  // the force as the thrust: the lag is tested on its own below
  const KalmanParams off = with_disturbance_input(shipped, false, false);
  const KalmanParams on = with_disturbance_input(off, true, true);
  KalmanFilter modelled(on), by_hand(off);
  double position_m = 0.0, previous_m = 0.0;
  for (int k = 0; k < 400; ++k) {
    const double velocity_mps = 0.2 * std::sin(0.02 * k) + (k % 7 == 0 ? 1e-3 : 0.0);
    previous_m = position_m;
    position_m += velocity_mps * off.period_s;
    const double force_n = 150.0 * std::cos(0.03 * k);
    // The first step has no x_{k-1}: x_k stands in for it.
    const double midpoint_m = k == 0 ? position_m : 0.5 * (previous_m + position_m);
    const double u_n = force_n + on.friction_input.force_n(velocity_mps) + on.ripple_input.force_n(midpoint_m);
    const KalmanEstimate e = modelled.step({velocity_mps, force_n, position_m});
    by_hand.step({velocity_mps, u_n, position_m});
    ASSERT_NEAR(e.input_force_n, u_n, 1e-9) << "k = " << k;
    ASSERT_LT((modelled.state() - by_hand.state()).norm(), 1e-9) << "k = " << k;
  }
  // Off, the input is the force alone (the paper's filter).
  KalmanFilter paper(off);
  EXPECT_DOUBLE_EQ(paper.step({0.1, 42.0, 0.004}).input_force_n, 42.0);
}

TEST(KalmanDisturbanceInput, NonFinitePositionIsCountedAndTheLastOneUsed) {
  const KalmanParams on = with_disturbance_input(test::shipped_params().kalman_params(), false, true);
  KalmanFilter kf(on);
  kf.step({0.1, 0.0, 0.004});
  const KalmanEstimate e = kf.step({0.1, 0.0, std::numeric_limits<double>::quiet_NaN()});
  EXPECT_EQ(kf.counters().rejected_inputs, 1u);
  EXPECT_DOUBLE_EQ(e.input_force_n, on.ripple_input.force_n(0.004));
  EXPECT_TRUE(kf.state().allFinite());
}

// Behaviour in the loop: after the free-vibration start (0.02 m, F_s = -274 N
// unknown to the filter) the load velocity estimate of a filter that trusts its
// v_M model (the shipped small Q_00) is good only when the bearing friction is
// in its input (the motor hardly moves, so the ripple matters little here); the
// paper's Q never finds the start. PI only, so the filter does not act on the
// plant and every run sees the same motion.
TEST(KalmanDisturbanceInput, ShrinksTheFreeVibrationEstimateError) {
  const Scenario free = test::shipped_scenario("free_vibration");
  const auto error_mps = [&](const Eigen::Vector3d& q, bool friction, bool ripple) {
    SystemParams p = test::shipped_params();
    p.kalman.process_noise_diag = q;
    p.kalman.friction_input.enabled = friction;
    p.kalman.ripple_input.enabled = ripple;
    // RMS over the first second, while the load rings: what a compensator acts on.
    double sum = 0;
    std::size_t n = 0;
    for (const TickRecord& r : run_scenario(p, free)) {
      if (r.time_s >= 1.0) break;
      sum += std::pow(r.est_load_velocity_mps - r.load_velocity_mps, 2);
      ++n;
    }
    return std::sqrt(sum / static_cast<double>(n));
  };
  const Eigen::Vector3d paper_q(100.0, 10.0, 1.0), shipped_q = test::shipped_params().kalman.process_noise_diag;
  const double paper = error_mps(paper_q, false, false);
  const double without = error_mps(shipped_q, false, false);
  const double with_friction = error_mps(shipped_q, true, false);
  const double with_both = error_mps(shipped_q, true, true);
  std::printf(
      "[ kalman     ] free vibration, v_L rms error over 1 s: paper Q %.1f mm/s; shipped Q: "
      "force only %.1f, + friction %.1f, + friction and ripple %.1f mm/s\n",
      1e3 * paper, 1e3 * without, 1e3 * with_friction, 1e3 * with_both);
  EXPECT_LT(with_friction, 0.7 * without);  // measured 67.5 / 108.5 = 0.62
  EXPECT_LT(with_both, 0.7 * without);
  EXPECT_LT(with_both, 0.2 * paper);  // measured 68.2 / 588.6 = 0.12
}

// ------------------------------------------- the thrust lag

TEST(KalmanThrustLag, InputIsTheMeanThrustOfAFirstOrderCurrentLoop) {
  // A step of F = 100 N from rest: the thrust F(t) = F (1 - e^{-t / tau}) of the lag, averaged
  // over each period, period after period; without the lag the input is the command itself.
  KalmanParams p = with_disturbance_input(test::shipped_params().kalman_params(), false, false);
  p.thrust_lag_s = 3e-4;
  const double t_s = p.period_s, tau_s = p.thrust_lag_s, force_n = 100.0;
  KalmanFilter lagged(p);
  for (int k = 1; k <= 6; ++k) {  // step k: F_{k-1} = F has acted for k periods
    // The mean of F (1 - e^{-t / tau}) over [(k - 1) T, k T].
    const double mean_n =
        force_n * (1.0 - (tau_s / t_s) * (std::exp(-(k - 1) * t_s / tau_s) - std::exp(-k * t_s / tau_s)));
    EXPECT_NEAR(lagged.step({0.0, force_n, 0.0}).input_force_n, mean_n, 1e-9) << "period " << k;
  }
  p.thrust_lag_s = 0.0;
  KalmanFilter paper(p);
  EXPECT_DOUBLE_EQ(paper.step({0.0, force_n, 0.0}).input_force_n, force_n);
}

TEST(KalmanThrustLag, BadValuesThrowNamingTheValue) {
  KalmanParams p = test::shipped_params().kalman_params();
  for (const double bad : {-1e-4, 2.0, std::numeric_limits<double>::quiet_NaN()}) {
    p.thrust_lag_s = bad;
    EXPECT_NE(construction_error(p).find("thrust_lag_s"), std::string::npos) << bad;
  }
}

// Behaviour in the loop: a compensation force that chatters at 167 Hz (+-300 N, a period of six
// ticks, as the RNN did on stiff 5 kg plants) on top of the free vibration. The current loop
// (3000 rad/s) leaves each step of the command 32 % short in its period; a filter that takes the
// command for the thrust reads the shortfall as spring force, and so feeds the chatter back to
// the compensator that made it.
TEST(KalmanThrustLag, KeepsACompensatorsChatterOutOfTheSpringForceEstimate) {
  const Scenario free = test::shipped_scenario("free_vibration");
  const auto error_n = [&](double thrust_lag_s) {
    SystemParams p = test::shipped_params();
    p.kalman.thrust_lag_s = thrust_lag_s;
    ClosedLoop loop(p, free);
    double sum = 0;
    std::size_t n = 0;
    for (int k = 0; k < 1000; ++k) {
      const TickRecord r = loop.step({k % 6 < 3 ? 300.0 : -300.0, 0.0});
      if (k < 200) continue;  // the start (F_s = -274 N, unknown to the filter) found
      sum += std::pow(r.est_spring_force_n - r.spring_force_n, 2);
      ++n;
    }
    return std::sqrt(sum / static_cast<double>(n));
  };
  const double command = error_n(0.0);
  const double lagged = error_n(test::shipped_params().kalman.thrust_lag_s);
  std::printf(
      "[ kalman     ] 167 Hz, +-300 N chatter: F_s rms error %.2f N (input = command), "
      "%.2f N (the current loop's lag modelled)\n",
      command, lagged);
  // Measured 32.2 against 52.3 N. The simulated drive's thrust lags a little more than its design
  // 1 / w_c (sampled at 31.25 us): a lag of 0.5 ms in the filter leaves 24.7 N; a rig would take
  // tau_i from a step of its current loop.
  EXPECT_LT(lagged, 0.75 * command);
}

// ------------------------------------------- the standstill hold

/// Largest |F_s| estimate and the number of sign changes of F_s over `steps` steps of a motor at
/// rest (y = 0, no force), from a start with the load swinging (F_s = start_n, v_L = v_M = 0).
struct HeldSwing {
  double largest_late_n = 0;  ///< max |F_s-hat| over the second half of the steps
  int sign_changes = 0;
  std::uint64_t holds = 0;
};
HeldSwing swing_at_rest(const KalmanParams& p, double start_n, int steps) {
  KalmanFilter kf(p);
  kf.reset(Eigen::Vector3d(0.0, 0.0, start_n));
  HeldSwing out;
  double previous_n = start_n;
  for (int k = 0; k < steps; ++k) {
    const double f_n = kf.step({0.0, 0.0, 0.0}).spring_force_n;
    if (k >= steps / 2) out.largest_late_n = std::max(out.largest_late_n, std::abs(f_n));
    if ((f_n > 0) != (previous_n > 0)) ++out.sign_changes;
    previous_n = f_n;
  }
  out.holds = kf.counters().standstill_holds;
  return out;
}

TEST(KalmanStandstillHold, KeepsTheSwingOfALoadOnAStuckMotor) {
  // Nominal model: the load swings on the clamped spring at sqrt(k / m_L) = 58.5 rad/s (107 ms);
  // 12 N is above the held share (0.25 x 20 N). 200 ms of y = 0, as the encoder of a stuck
  // motor reads.
  KalmanParams held = test::shipped_params().kalman_params();
  ASSERT_TRUE(held.standstill_hold.enabled);
  KalmanParams normal = held;
  normal.standstill_hold.enabled = false;
  const HeldSwing with = swing_at_rest(held, 12.0, 200), without = swing_at_rest(normal, 12.0, 200);
  std::printf(
      "[ kalman     ] load swinging at 12 N on a motor at rest, 200 ms: |F_s-hat| over the last 100 ms "
      "up to %.2f N with the hold (%d sign changes), %.2f N without (%d)\n",
      with.largest_late_n, with.sign_changes, without.largest_late_n, without.sign_changes);
  EXPECT_EQ(with.holds, 200u);
  EXPECT_EQ(without.holds, 0u);
  EXPECT_GT(with.largest_late_n, 0.5 * 12.0);     // the swing is kept ...
  EXPECT_GE(with.sign_changes, 3);                // ... and swings: nearly four half periods in 200 ms
  EXPECT_LT(without.largest_late_n, 0.2 * 12.0);  // the normal update explains it away
}

TEST(KalmanStandstillHold, LeavesSmallSwingsMovingMotorsAndThePapersFilterAlone) {
  const KalmanParams p = test::shipped_params().kalman_params();
  // Below the share (0.25 x 20 N = 5 N): the normal update.
  EXPECT_EQ(swing_at_rest(p, 4.0, 50).holds, 0u);
  EXPECT_GT(swing_at_rest(p, 6.0, 1).holds, 0u);
  // A motor moving faster than max_velocity_mps: the encoder sees the forces, no hold.
  KalmanFilter moving(p);
  moving.reset(Eigen::Vector3d(0.0, 0.0, 12.0));
  moving.step({2.0 * p.standstill_hold.max_velocity_mps, 0.0, 0.0});
  EXPECT_EQ(moving.counters().standstill_holds, 0u);
  // Without the friction input (the paper's filter) the hold is off.
  KalmanParams paper = p;
  paper.friction_input.enabled = false;
  EXPECT_EQ(swing_at_rest(paper, 12.0, 50).holds, 0u);
}

TEST(KalmanStandstillHold, BadValuesThrowNamingTheValue) {
  KalmanParams p = test::shipped_params().kalman_params();
  p.standstill_hold.max_velocity_mps = 0;
  EXPECT_NE(construction_error(p).find("standstill_hold.max_velocity_mps: must be in [1e-06, 1]"), std::string::npos);
  p = test::shipped_params().kalman_params();
  p.standstill_hold.min_ring_share = -0.5;
  EXPECT_NE(construction_error(p).find("standstill_hold.min_ring_share: must be in [0, 100]"), std::string::npos);
}

// In the loop: a heavy, soft load (8 kg, 6,850 N/m, 30 N of bearing friction; the filter's model
// that plant's) under acceleration feedback, judged as the identified family's sweep judges. After
// the pulse's edges the motor sticks while the load still swings; without the hold the estimate
// loses the swing and the compensation leaves it.
TEST(KalmanStandstillHold, DampsTheSwingLeftOnAHeavySoftLoad) {
  const Scenario pulse = test::shipped_scenario("pulse");
  const VerdictParams verdict =
      load_sweep_verdict(std::string(PMLSM_SOURCE_DIR) + "/configs/sweeps/plant_family_identified.yaml");
  const auto run = [&](bool hold) {
    SystemParams p = test::shipped_params();
    for (const auto& [key, value] :
         std::vector<std::pair<std::string, double>>{{"plant.mechanics.load_mass_kg", 8.0},
                                                     {"plant.mechanics.spring_n_per_m", 6850.0},
                                                     {"plant.friction.coulomb_n", 30.0},
                                                     {"plant.friction.viscous_n_s_per_m", 15.0},
                                                     {"kalman.model.load_mass_kg", 8.0},
                                                     {"kalman.model.spring_n_per_m", 6850.0},
                                                     {"kalman.friction_input.coulomb_n", 30.0},
                                                     {"kalman.friction_input.viscous_n_s_per_m", 15.0}}) {
      real_parameter(p, key) = value;
    }
    p.kalman.standstill_hold.enabled = hold;
    // The filter the hold was found on, the command taken for the thrust: with the current loop's
    // lag modelled the estimate keeps more of the swing without the hold (tail 1.11 mm, the hold's
    // 1.07 mm: it no longer halves it, and both stay over the verdict's 0.5 mm). And the gain
    // schedule's limit of that time, K_a 200 kg on this load: at a limit of 2 (320 kg) the hold
    // still shrinks the tail (0.54 against 0.82 mm) but costs a little (16.80 against 16.22).
    p.kalman.thrust_lag_s = 0.0;
    p.compensator.max_gain_scale = 1.25;
    p.validate();
    const auto trace = run_with_compensator(p, pulse, {CompensatorKind::kAccel, {}, false});
    return judge_run(trace, pulse, p.timing.control_period_s, p.velocity_loop.force_limit_n, verdict);
  };
  const RunVerdict with = run(true), without = run(false);
  std::printf(
      "[ kalman     ] 8 kg, 6850 N/m, 30 N, acceleration feedback, pulse: tail swing %.2f mm with the hold, "
      "%.2f mm without; cost %.2f and %.2f\n",
      with.tail_stretch_amplitude_m * 1e3, without.tail_stretch_amplitude_m * 1e3, with.cost, without.cost);
  EXPECT_LT(with.tail_stretch_amplitude_m, 0.7 * without.tail_stretch_amplitude_m);  // measured 1.08 / 1.97 mm
  EXPECT_LT(with.cost, without.cost);
}

}  // namespace
}  // namespace pmlsm
