// Input shaping (pmlsm/control/input_shaper.hpp): the impulses of ZV, ZVD and EI, the vibration
// they leave on their mode and near it, the discrete shaper's gain and timing, and a lightly
// damped mode driven through it at the control period.
#include "pmlsm/control/input_shaper.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace pmlsm {
namespace {

constexpr double kPi = 3.14159265358979323846;

InputShaperParams params(ShaperKind kind, double frequency_hz = 10.0, double damping_ratio = 0.0) {
  InputShaperParams p;
  p.kind = kind;
  p.frequency_hz = frequency_hz;
  p.damping_ratio = damping_ratio;
  p.vibration_tolerance = 0.05;
  p.period_s = 1e-3;
  return p;
}

TEST(InputShaper, UndampedImpulsesAreTheTextbooksAndSumToOne) {
  const auto zv = shaper_impulses(params(ShaperKind::kZv));
  ASSERT_EQ(zv.size(), 2u);
  EXPECT_NEAR(zv[0].amplitude, 0.5, 1e-15);
  EXPECT_NEAR(zv[1].time_s, 0.05, 1e-15);  // half the 10 Hz period
  const auto zvd = shaper_impulses(params(ShaperKind::kZvd));
  ASSERT_EQ(zvd.size(), 3u);
  EXPECT_NEAR(zvd[0].amplitude, 0.25, 1e-15);
  EXPECT_NEAR(zvd[1].amplitude, 0.5, 1e-15);
  EXPECT_NEAR(zvd[2].time_s, 0.1, 1e-15);
  const auto ei = shaper_impulses(params(ShaperKind::kEi));
  ASSERT_EQ(ei.size(), 3u);
  EXPECT_NEAR(ei[0].amplitude, 1.05 / 4, 1e-15);
  EXPECT_NEAR(ei[1].amplitude, 0.95 / 2, 1e-15);
  EXPECT_NEAR(ei[2].amplitude, 1.05 / 4, 1e-15);
  for (const ShaperKind kind : {ShaperKind::kZv, ShaperKind::kZvd, ShaperKind::kEi}) {
    for (const double zeta : {0.0, 0.05, 0.3}) {
      double sum = 0;
      for (const auto& i : shaper_impulses(params(kind, 10.0, zeta))) sum += i.amplitude;
      EXPECT_NEAR(sum, 1.0, 1e-15) << to_string(kind) << " zeta " << zeta;
    }
  }
  EXPECT_EQ(shaper_impulses(params(ShaperKind::kNone)).size(), 1u);
}

TEST(InputShaper, ZvAndZvdLeaveNoVibrationOnTheirModeAtAnyDamping) {
  for (const double zeta : {0.0, 0.02, 0.1, 0.5}) {
    for (const ShaperKind kind : {ShaperKind::kZv, ShaperKind::kZvd}) {
      EXPECT_LT(residual_vibration(shaper_impulses(params(kind, 9.3, zeta)), 9.3, zeta), 1e-12)
          << to_string(kind) << " zeta " << zeta;
    }
    EXPECT_NEAR(residual_vibration(shaper_impulses(params(ShaperKind::kNone)), 9.3, zeta), 1.0, 1e-15);
  }
}

/// The width of the band of frequencies around 10 Hz whose vibration stays at or below 5 %,
/// relative to 10 Hz (0.2: +-10 %).
double insensitive_band(ShaperKind kind, double zeta) {
  const auto impulses = shaper_impulses(params(kind, 10.0, zeta));
  double low = 10.0, high = 10.0;
  while (low > 1.0 && residual_vibration(impulses, low - 0.001, zeta) <= 0.05 + 1e-12) low -= 0.001;
  while (high < 19.0 && residual_vibration(impulses, high + 0.001, zeta) <= 0.05 + 1e-12) high += 0.001;
  return (high - low) / 10.0;
}

TEST(InputShaper, EiLeavesItsToleranceOnTheModeAndTheWidestBandBelowIt) {
  for (const double zeta : {0.0, 0.02, 0.05, 0.1}) {
    SCOPED_TRACE(zeta);
    const double at_mode = residual_vibration(shaper_impulses(params(ShaperKind::kEi, 10.0, zeta)), 10.0, zeta);
    // The tolerance itself undamped; below it with damping (the damped form is conservative).
    EXPECT_LE(at_mode, 0.05 + 1e-12);
    EXPECT_GT(at_mode, zeta == 0.0 ? 0.05 - 1e-12 : 0.03);
    const double zv = insensitive_band(ShaperKind::kZv, zeta);
    const double zvd = insensitive_band(ShaperKind::kZvd, zeta);
    const double ei = insensitive_band(ShaperKind::kEi, zeta);
    EXPECT_GT(zvd, 2.0 * zv) << zv << " " << zvd;
    EXPECT_GT(ei, 1.25 * zvd) << zvd << " " << ei;
  }
  // Undamped, the textbook widths: ZV +-3.2 %, ZVD +-14.4 %, EI +-19.9 % (5 % tolerance).
  EXPECT_NEAR(insensitive_band(ShaperKind::kZv, 0.0), 0.064, 0.002);
  EXPECT_NEAR(insensitive_band(ShaperKind::kZvd, 0.0), 0.288, 0.004);
}

TEST(InputShaper, TheDiscreteShaperKeepsGainAndMeanTimeOfTheImpulses) {
  // 9.3 Hz: impulse times fall between ticks, so each is split over two.
  for (const ShaperKind kind : {ShaperKind::kNone, ShaperKind::kZv, ShaperKind::kZvd, ShaperKind::kEi}) {
    SCOPED_TRACE(to_string(kind));
    const InputShaperParams p = params(kind, 9.3, 0.03);
    const InputShaper shaper(p);
    double gain = 0, mean_tick = 0, impulses_mean_s = 0;
    for (std::size_t j = 0; j < shaper.tap_weights().size(); ++j) {
      gain += shaper.tap_weights()[j];
      mean_tick += static_cast<double>(j) * shaper.tap_weights()[j];
    }
    for (const auto& i : shaper_impulses(p)) impulses_mean_s += i.amplitude * i.time_s;
    EXPECT_NEAR(gain, 1.0, 1e-12);
    EXPECT_NEAR(mean_tick * p.period_s, impulses_mean_s, 1e-12);
    EXPECT_LE(static_cast<double>(shaper.tap_weights().size() - 1) * p.period_s, shaper.span_s() + p.period_s);
  }
}

/// Residual amplitude of a mode x'' + 2 zeta w x' + w^2 x = w^2 u after a unit step of the
/// command through `shaper` (u held over each 1 ms period; RK4 at 0.1 ms), once the shaper's
/// span is over: the largest |x - 1| from then on.
double residual_after_step(InputShaper shaper, double frequency_hz, double zeta) {
  const double w = 2.0 * kPi * frequency_hz;
  double x = 0, v = 0, worst = 0;
  const auto f = [&](double xx, double vv, double u) { return w * w * (u - xx) - 2.0 * zeta * w * vv; };
  for (int k = 0; k < 2000; ++k) {
    const double u = shaper.step(1.0);
    for (int sub = 0; sub < 10; ++sub) {
      const double h = 1e-4;
      const double k1x = v, k1v = f(x, v, u);
      const double k2x = v + 0.5 * h * k1v, k2v = f(x + 0.5 * h * k1x, v + 0.5 * h * k1v, u);
      const double k3x = v + 0.5 * h * k2v, k3v = f(x + 0.5 * h * k2x, v + 0.5 * h * k2v, u);
      const double k4x = v + h * k3v, k4v = f(x + h * k3x, v + h * k3v, u);
      x += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x);
      v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    }
    if ((k + 1) * 1e-3 > shaper.span_s() + 1e-3) worst = std::max(worst, std::fabs(x - 1.0));
  }
  return worst;
}

TEST(InputShaper, AStepThroughTheShaperLeavesTheModeAlmostQuiet) {
  const double f = 9.3, zeta = 0.02;  // the nominal load mode, lightly damped
  const double unshaped = residual_after_step(InputShaper(params(ShaperKind::kNone, f, zeta)), f, zeta);
  EXPECT_GT(unshaped, 0.5);
  for (const ShaperKind kind : {ShaperKind::kZv, ShaperKind::kZvd, ShaperKind::kEi}) {
    const double shaped = residual_after_step(InputShaper(params(kind, f, zeta)), f, zeta);
    // The 1 ms hold of each command adds a little of its own; EI leaves its 5 % by design.
    EXPECT_LT(shaped, (kind == ShaperKind::kEi ? 0.06 : 0.01) * unshaped) << to_string(kind) << " " << shaped;
  }
  // A mode 10 % off the design: ZVD and EI keep most of their effect, ZV does not.
  const double off = f * 1.1;
  const double zv_off = residual_after_step(InputShaper(params(ShaperKind::kZv, f, zeta)), off, zeta);
  const double zvd_off = residual_after_step(InputShaper(params(ShaperKind::kZvd, f, zeta)), off, zeta);
  EXPECT_GT(zv_off, 3.0 * zvd_off) << zv_off << " " << zvd_off;
}

TEST(InputShaper, ANonFiniteCommandIsRejectedAndTheLastOneHeld) {
  InputShaper shaper(params(ShaperKind::kZvd, 50.0));
  shaper.reset(0.2);
  EXPECT_DOUBLE_EQ(shaper.step(0.2), 0.2);
  EXPECT_DOUBLE_EQ(shaper.step(std::numeric_limits<double>::quiet_NaN()), 0.2);
  EXPECT_DOUBLE_EQ(shaper.step(std::numeric_limits<double>::infinity()), 0.2);
  EXPECT_EQ(shaper.rejected_inputs(), 2u);
}

TEST(InputShaper, InvalidParametersAreRefusedByName) {
  struct Case {
    InputShaperParams p;
    const char* expected;
  };
  InputShaperParams bad_frequency = params(ShaperKind::kZv, 0.0);
  InputShaperParams bad_damping = params(ShaperKind::kZvd, 10.0, 0.6);
  InputShaperParams bad_tolerance = params(ShaperKind::kEi);
  bad_tolerance.vibration_tolerance = 0.0;
  InputShaperParams too_slow = params(ShaperKind::kZvd, 0.05);
  InputShaperParams bad_period = params(ShaperKind::kNone);
  bad_period.period_s = 0.0;
  for (const Case& c :
       {Case{bad_frequency, "frequency_hz"}, Case{bad_damping, "damping_ratio"},
        Case{bad_tolerance, "vibration_tolerance"}, Case{too_slow, "over 10 s"}, Case{bad_period, "period_s"}}) {
    try {
      InputShaper shaper(c.p);
      ADD_FAILURE() << "accepted: " << c.expected;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(shaper_kind_from_string("ei"), ShaperKind::kEi);
  EXPECT_THROW(shaper_kind_from_string("zvdd"), std::invalid_argument);
}

}  // namespace
}  // namespace pmlsm
