// Notches designed from a measured response (pmlsm/analysis/filter_design.hpp): on the simulated
// drive's measured response (the two-mass plant, its current loop, the sampling), and on that
// response with a structural mode multiplied into it, as a motor frame or an encoder mount adds
// one above the two-mass model's band.
#include "pmlsm/analysis/analysis_params.hpp"
#include "pmlsm/analysis/filter_design.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "pmlsm/analysis/frequency_response_measurement.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

constexpr double kDesignPi = 3.14159265358979323846;

/// The shipped plant's response as the commissioning measures it (one measurement per binary).
const FrequencyResponseResult& measured_nominal() {
  static const FrequencyResponseResult result = [] {
    const SystemParams p = test::shipped_params();
    FrequencyResponseMeasurement m(frequency_response_params(p), p.velocity_pi_params());
    SimulatedDriveBackend drive(p, PlantInitialCondition{});
    run_measurement(drive, m, [](std::uint64_t, std::uint64_t) {});
    return evaluate_measurement(m);
  }();
  return result;
}

/// M(s) = (s^2 + 2 z_n w s + w^2) / (s^2 + 2 z_d w s + w^2): a mode of height z_n / z_d at f.
std::complex<double> mode(double f, double centre_hz, double numerator_damping, double denominator_damping) {
  const std::complex<double> s(0.0, 2 * kDesignPi * f);
  const double w = 2 * kDesignPi * centre_hz;
  return (s * s + 2 * numerator_damping * w * s + w * w) / (s * s + 2 * denominator_damping * w * s + w * w);
}

/// The measured lines with the mode in the plant: G M, and the loop C G M (S = 1 / (1 + L M)).
std::vector<FrequencyPoint> with_mode(double centre_hz, double numerator_damping, double denominator_damping) {
  std::vector<FrequencyPoint> points = measured_nominal().points;
  for (FrequencyPoint& p : points) {
    const std::complex<double> m = mode(p.frequency_hz, centre_hz, numerator_damping, denominator_damping);
    p.plant *= m;
    p.sensitivity = 1.0 / (1.0 + p.open_loop() * m);
  }
  return points;
}

FilterDesignParams shipped_design() { return filter_design_params(test::shipped_params()); }

TEST(FilterDesign, TheTwoMassPlantHasNoResonanceAboveItsModel) {
  const SystemParams p = test::shipped_params();
  const FrequencyResponseResult& r = measured_nominal();
  const double min_coherence = frequency_response_params(p).min_coherence;
  const FilterDesign design = design_notches(r.points, r.fit, p.force_command_filter_params(), tuning_targets(p),
                                             min_coherence, p.timing.control_period_s, shipped_design());
  EXPECT_TRUE(design.peaks.empty()) << design.peaks.front().frequency_hz << " Hz, " << design.peaks.front().height_db
                                    << " dB";
  EXPECT_EQ(design.placed, 0u);
  EXPECT_EQ(design.chain.slots[0].kind, FilterKind::kNone);
  // Nothing stands out over the model above its band: the largest bump is a fraction of a dB.
  FilterDesignParams any = shipped_design();
  any.min_peak_db = 0.1;
  const auto bumps = resonance_peaks(r.points, r.fit, min_coherence, p.timing.control_period_s, any);
  const double largest_db = bumps.empty() ? 0.0 : bumps.front().height_db;
  EXPECT_LT(largest_db, 1.0);
  std::printf("[ design     ] nominal plant: the largest bump over the model above %.0f Hz: %.2f dB\n",
              any.min_frequency_hz, largest_db);
}

// A 250 Hz mode 23.5 dB high (z 0.3 over 0.02) where |L| is about 0.25: the loop it leaves cannot
// hold the measured gain. The notch is found within 3 % of the mode, placed in slot 1, and lets
// the tuner raise the gain to within 10 % of what the loop without the mode allows.
TEST(FilterDesign, ANotchOnAStructuralModeGivesTheLoopItsGainBack) {
  const SystemParams p = test::shipped_params();
  const double min_coherence = frequency_response_params(p).min_coherence;
  const auto& targets = tuning_targets(p);
  const double period_s = p.timing.control_period_s;
  const std::vector<FrequencyPoint> points = with_mode(250.0, 0.3, 0.02);
  const FilterDesign design = design_notches(points, measured_nominal().fit, p.force_command_filter_params(), targets,
                                             min_coherence, period_s, shipped_design());
  ASSERT_EQ(design.placed, 1u);
  const ResonancePeak& peak = design.peaks.front();
  EXPECT_TRUE(peak.placed);
  EXPECT_TRUE(peak.slot_free);
  EXPECT_NEAR(peak.frequency_hz, 250.0, 7.5);
  EXPECT_GT(peak.height_db, 12.0);
  EXPECT_EQ(design.chain.slots[0], peak.notch);
  EXPECT_EQ(peak.notch.kind, FilterKind::kNotch);
  EXPECT_LT(peak.notch.damping, peak.notch.second_damping);

  std::string why;
  const auto without_mode = tune_velocity_pi(measured_nominal().points, 1.0, 1.0, targets, min_coherence, why, nullptr);
  ASSERT_TRUE(without_mode.has_value()) << why;
  EXPECT_LT(peak.gain_scale_before, 0.7 * without_mode->gain_scale);
  EXPECT_GT(peak.gain_scale_with, 0.9 * without_mode->gain_scale);
  // The loop with the notch, as the tuner reads it, meets the targets at that gain.
  const FilterChain chain(design.chain);
  const LoopMargins m = loop_margins(points, peak.gain_scale_with, min_coherence, &chain);
  EXPECT_GE(m.phase_margin_deg, targets.min_phase_margin_deg);
  EXPECT_GE(m.gain_margin_db, targets.min_gain_margin_db);
  std::printf(
      "[ design     ] 250 Hz mode: notch at %.1f Hz (%.1f dB, %.1f Hz wide): gain x%.3f -> x%.3f (x%.3f "
      "without the mode)\n",
      peak.frequency_hz, peak.height_db, peak.width_hz, peak.gain_scale_before, peak.gain_scale_with,
      without_mode->gain_scale);
}

// A mode found but of no use to the loop is not placed: a low, broad peak far below the gain
// crossover's influence, and every peak when no slot is free.
TEST(FilterDesign, ANotchThatBuysNoGainOrHasNoSlotIsNotPlaced) {
  const SystemParams p = test::shipped_params();
  const double min_coherence = frequency_response_params(p).min_coherence;
  const double period_s = p.timing.control_period_s;
  const std::vector<FrequencyPoint> points = with_mode(250.0, 0.3, 0.02);
  FilterChainParams full = p.force_command_filter_params();
  for (BiquadParams& slot : full.slots) {  // unit lead-lags: in use, flat
    slot.kind = FilterKind::kLeadLag;
    slot.frequency_hz = slot.second_frequency_hz = 100.0;
  }
  const FilterDesign no_slot = design_notches(points, measured_nominal().fit, full, tuning_targets(p), min_coherence,
                                              period_s, shipped_design());
  ASSERT_FALSE(no_slot.peaks.empty());
  EXPECT_EQ(no_slot.placed, 0u);
  EXPECT_FALSE(no_slot.peaks.front().placed);
  EXPECT_FALSE(no_slot.peaks.front().slot_free);
  EXPECT_EQ(no_slot.chain.slots[0], full.slots[0]);

  // 9.5 dB at 330 Hz (z 0.12 over 0.04), above the phase crossover: found (7 dB between the
  // lines), but its phase lead below it helps the gain margin, which a notch would take away.
  const FilterDesign low =
      design_notches(with_mode(330.0, 0.12, 0.04), measured_nominal().fit, p.force_command_filter_params(),
                     tuning_targets(p), min_coherence, period_s, shipped_design());
  ASSERT_FALSE(low.peaks.empty());
  std::printf("[ design     ] 330 Hz mode: found at %.1f Hz (%.1f dB): gain x%.3f -> x%.3f with a notch\n",
              low.peaks.front().frequency_hz, low.peaks.front().height_db, low.peaks.front().gain_scale_before,
              low.peaks.front().gain_scale_with);
  EXPECT_FALSE(low.peaks.front().placed);
  EXPECT_LT(low.peaks.front().gain_scale_with,
            low.peaks.front().gain_scale_before * shipped_design().min_gain_increase);
  EXPECT_EQ(low.placed, 0u);

  // A low peak let through (min_peak_db 1): the search's shallower trials stop at no notch at all.
  FilterDesignParams any = shipped_design();
  any.min_peak_db = 1.0;
  EXPECT_NO_THROW(design_notches(with_mode(330.0, 0.06, 0.04), measured_nominal().fit, p.force_command_filter_params(),
                                 tuning_targets(p), min_coherence, period_s, any));
}

TEST(FilterDesign, RefusesInvalidSettings) {
  FilterDesignParams d = shipped_design();
  d.min_peak_db = 0.0;
  EXPECT_THROW(d.validate(), std::invalid_argument);
  d = shipped_design();
  d.min_gain_increase = 1.0;
  EXPECT_THROW(d.validate(), std::invalid_argument);
  const FrequencyResponseResult& r = measured_nominal();
  EXPECT_THROW(resonance_peaks(r.points, r.fit, 0.9, 0.0, shipped_design()), std::invalid_argument);
}

}  // namespace
}  // namespace pmlsm
