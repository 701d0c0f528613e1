// Frequency-response measurement, the pure part (pmlsm/analysis/frequency_response.hpp): the multisine,
// the estimates from a recorded run of a linear two-mass plant under a velocity PI, and the
// two-mass fit, against the plant's own parameters.
#include "pmlsm/analysis/frequency_response.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace pmlsm {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kPeriodS = 1e-3;

MultisineParams multisine_params() {
  MultisineParams p;
  p.amplitude_n = 60.0;
  p.min_frequency_hz = 1.0;
  p.max_frequency_hz = 60.0;
  p.resolution_hz = 0.25;
  p.period_s = kPeriodS;
  return p;
}

TwoMassFit plant(double load_mass_kg, double spring_n_per_m) {
  TwoMassFit m;
  m.motor_mass_kg = 20.0;
  m.load_mass_kg = load_mass_kg;
  m.spring_n_per_m = spring_n_per_m;
  m.spring_damping_n_s_per_m = 2.0;
  m.motor_viscous_n_s_per_m = 30.0;
  return m;
}

TEST(Multisine, IsPeriodicPeaksAtItsAmplitudeAndExcitesOnlyItsLines) {
  const Multisine m(multisine_params());
  ASSERT_EQ(m.ticks_per_period(), 4000u);
  EXPECT_EQ(m.lines().front(), 4u);   // 1 Hz
  EXPECT_EQ(m.lines().back(), 240u);  // 60 Hz
  double peak = 0;
  for (std::size_t t = 0; t < m.ticks_per_period(); ++t) {
    peak = std::max(peak, std::fabs(m.value(t)));
    ASSERT_EQ(m.value(t), m.value(t + 3 * m.ticks_per_period()));
  }
  EXPECT_NEAR(peak, 60.0, 1e-9);
  // The DFT of one period: the lines carry it all.
  const std::size_t n = m.ticks_per_period();
  double on = 0, off = 0;
  for (std::size_t k = 1; k < 400; ++k) {
    std::complex<double> x;
    for (std::size_t t = 0; t < n; ++t) x += m.value(t) * std::polar(1.0, -2.0 * kPi * double((k * t) % n) / double(n));
    const bool line = k >= 4 && k <= 240;
    (line ? on : off) += std::norm(x);
  }
  EXPECT_LT(off, 1e-18 * on);
}

TEST(TwoMassFit, RecoversTheModelFromItsExactResponse) {
  const TwoMassFit truth = plant(4.0, 13700.0);
  std::vector<FrequencyPoint> points;
  for (double f = 1.0; f <= 100.0; f += 0.5) points.push_back({f, two_mass_response(truth, f), 1.0, 1.0});
  const TwoMassFit fit = fit_two_mass(points, 0.9);
  EXPECT_NEAR(fit.motor_mass_kg, 20.0, 1e-6 * 20.0);
  EXPECT_NEAR(fit.load_mass_kg, 4.0, 1e-6 * 4.0);
  EXPECT_NEAR(fit.spring_n_per_m, 13700.0, 1e-6 * 13700.0);
  EXPECT_NEAR(fit.spring_damping_n_s_per_m, 2.0, 1e-5);
  EXPECT_NEAR(fit.motor_viscous_n_s_per_m, 30.0, 1e-4);
  EXPECT_NEAR(fit.anti_resonance_hz, std::sqrt(13700.0 / 4.0) / (2 * kPi), 1e-6);
  EXPECT_NEAR(fit.resonance_hz, std::sqrt(13700.0 * (1 / 4.0 + 1 / 20.0)) / (2 * kPi), 1e-3);
  EXPECT_LT(fit.rms_log_error, 1e-9);
}

/// A recorded excitation run: the two-mass plant (RK4 at 0.1 ms) under the velocity PI
/// F = R - K_p v_M - K_i integral(v_M), one 1 ms tick at a time. The force is held over a tick;
/// the velocity recorded with it is the motor's mean over that tick, as an encoder difference
/// gives it (both then describe the same interval).
struct Recording {
  std::vector<double> excitation, force, velocity;
};

Recording record(const TwoMassFit& m, const Multisine& excitation, std::size_t periods) {
  const double kp = 10000.0, ki = 0.01;  // the shipped velocity PI (Table 3)
  double x_m = 0, v_m = 0, x_l = 0, v_l = 0, integral = 0;
  Recording r;
  const auto accel = [&](double xm, double vm, double xl, double vl, double f, double& am, double& al) {
    const double spring = m.spring_n_per_m * (xm - xl) + m.spring_damping_n_s_per_m * (vm - vl);
    am = (f - spring - m.motor_viscous_n_s_per_m * vm) / m.motor_mass_kg;
    al = spring / m.load_mass_kg;
  };
  for (std::uint64_t k = 0; k < periods * excitation.ticks_per_period(); ++k) {
    const double e = excitation.value(k);
    const double f = e - kp * v_m - ki * integral;
    const double x_start = x_m;
    for (int sub = 0; sub < 10; ++sub) {
      const double h = kPeriodS / 10;
      double a1m, a1l, a2m, a2l, a3m, a3l, a4m, a4l;
      accel(x_m, v_m, x_l, v_l, f, a1m, a1l);
      accel(x_m + h / 2 * v_m, v_m + h / 2 * a1m, x_l + h / 2 * v_l, v_l + h / 2 * a1l, f, a2m, a2l);
      accel(x_m + h / 2 * (v_m + h / 2 * a1m), v_m + h / 2 * a2m, x_l + h / 2 * (v_l + h / 2 * a1l), v_l + h / 2 * a2l,
            f, a3m, a3l);
      accel(x_m + h * (v_m + h / 2 * a2m), v_m + h * a3m, x_l + h * (v_l + h / 2 * a2l), v_l + h * a3l, f, a4m, a4l);
      x_m += h * (v_m + h / 6 * (a1m + a2m + a3m));
      x_l += h * (v_l + h / 6 * (a1l + a2l + a3l));
      v_m += h / 6 * (a1m + 2 * a2m + 2 * a3m + a4m);
      v_l += h / 6 * (a1l + 2 * a2l + 2 * a3l + a4l);
    }
    integral += v_m * kPeriodS;
    r.excitation.push_back(e);
    r.force.push_back(f);
    r.velocity.push_back((x_m - x_start) / kPeriodS);
  }
  return r;
}

// The plant family's corners (load 2-8 kg, spring 6850-27400 N/m) and the nominal plant: the
// modes come out within 0.5 %, the masses and the spring within 2 %, through the loop.
TEST(FrequencyResponse, MeasuredUnderThePiLoopTheFitFindsTheModesOfEveryPlantOfTheFamily) {
  const Multisine excitation(multisine_params());
  for (const auto& [load_kg, spring] : std::vector<std::pair<double, double>>{
           {4.0, 13700.0}, {2.0, 6850.0}, {2.0, 27400.0}, {8.0, 6850.0}, {8.0, 27400.0}}) {
    SCOPED_TRACE(std::to_string(load_kg) + " kg, " + std::to_string(spring) + " N/m");
    const TwoMassFit truth = plant(load_kg, spring);
    const Recording r = record(truth, excitation, 4);
    const auto points = estimate_frequency_response(excitation, r.excitation, r.force, r.velocity, 1);
    ASSERT_EQ(points.size(), excitation.lines().size());
    for (const FrequencyPoint& p : points) EXPECT_GT(p.coherence, 0.999) << p.frequency_hz;
    // The stiff PI rejects a slow disturbance (|S| small, |L| large at 1 Hz).
    EXPECT_LT(std::abs(points.front().sensitivity), 0.05);
    EXPECT_GT(std::abs(points.front().open_loop()), 20.0);
    const TwoMassFit fit = fit_two_mass(points, 0.99);
    const double anti_hz = std::sqrt(spring / load_kg) / (2 * kPi);
    const double resonance_hz = std::sqrt(spring * (1 / load_kg + 1 / 20.0)) / (2 * kPi);
    EXPECT_NEAR(fit.anti_resonance_hz, anti_hz, 0.005 * anti_hz);
    EXPECT_NEAR(fit.resonance_hz, resonance_hz, 0.005 * resonance_hz);
    EXPECT_NEAR(fit.load_mass_kg, load_kg, 0.02 * load_kg);
    EXPECT_NEAR(fit.motor_mass_kg, 20.0, 0.02 * 20.0);
    EXPECT_NEAR(fit.spring_n_per_m, spring, 0.02 * spring);
    EXPECT_LT(fit.rms_log_error, 0.02);
  }
}

TEST(FrequencyResponse, BadRecordingsAndParametersAreRefusedByName) {
  const Multisine excitation(multisine_params());
  const std::vector<double> three_periods(3 * excitation.ticks_per_period(), 1.0);
  struct Case {
    std::vector<double> r, f, v;
    std::size_t settle;
    const char* expected;
  };
  std::vector<double> with_nan = three_periods;
  with_nan[123] = std::numeric_limits<double>::quiet_NaN();
  for (const Case& c : {Case{three_periods, three_periods, {1.0}, 1, "differ in length"},
                        Case{three_periods, three_periods, three_periods, 2, "need 2 to settle and 2 to average"},
                        Case{three_periods, with_nan, three_periods, 1, "non-finite value at tick 123"}}) {
    try {
      estimate_frequency_response(excitation, c.r, c.f, c.v, c.settle);
      ADD_FAILURE() << "accepted: " << c.expected;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
    }
  }
  MultisineParams above_nyquist = multisine_params();
  above_nyquist.max_frequency_hz = 600.0;
  EXPECT_THROW(Multisine{above_nyquist}, std::invalid_argument);
  MultisineParams no_amplitude = multisine_params();
  no_amplitude.amplitude_n = 0.0;
  EXPECT_THROW(Multisine{no_amplitude}, std::invalid_argument);
  // Incoherent lines are not fitted.
  std::vector<FrequencyPoint> noisy;
  for (double f = 1.0; f <= 60.0; f += 1.0) noisy.push_back({f, two_mass_response(plant(4.0, 13700.0), f), 1.0, 0.5});
  try {
    fit_two_mass(noisy, 0.9);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("0 lines with coherence"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pmlsm
