// The velocity loop's margins read from a measured open loop and the PI tuned to targets
// (pmlsm/analysis/loop_tuning.hpp): against a loop whose margins are known in closed form, past a
// lightly damped mode the lines cannot unwrap, and on the simulated drive, where the loop
// measured again at the tuned gains must have the margins the tuner predicted.
#include "pmlsm/analysis/analysis_params.hpp"
#include "pmlsm/analysis/loop_tuning.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/analysis/compensated_run.hpp"
#include "pmlsm/analysis/frequency_response_measurement.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

constexpr double kLoopPi = 3.14159265358979323846;

/// Lines (every 0.25 Hz to 40 Hz, 40 a decade above, to 450 Hz) of a loop L(f), as measured:
/// the sensitivity S = 1 / (1 + L).
template <typename Loop>
std::vector<FrequencyPoint> lines_of(Loop&& loop) {
  std::vector<FrequencyPoint> points;
  for (double f = 2.0; f <= 450.0; f = f < 40.0 ? f + 0.25 : f * std::pow(10.0, 1.0 / 40.0)) {
    FrequencyPoint p;
    p.frequency_hz = f;
    p.sensitivity = 1.0 / (1.0 + loop(f));
    p.plant = 1.0;
    p.coherence = 1.0;
    points.push_back(p);
  }
  return points;
}

// L = K / (m s) e^{-s tau}: the gain crossover at w_c = K / m with a phase margin of
// 90 deg - w_c tau, the phase crossover at w_p = pi / (2 tau) with |L| = K / (m w_p).
TEST(LoopMargins, AreThoseOfALoopKnownInClosedForm) {
  const double gain = 10000.0, mass_kg = 24.0, delay_s = 1.5e-3;
  const auto loop = [&](double f) {
    const std::complex<double> s(0.0, 2 * kLoopPi * f);
    return gain / (mass_kg * s) * std::exp(-s * delay_s);
  };
  const LoopMargins m = loop_margins(lines_of(loop), 1.0, 0.9);
  const double wc = gain / mass_kg, wp = kLoopPi / (2 * delay_s);
  ASSERT_TRUE(m.gain_crossover_found);
  ASSERT_TRUE(m.phase_crossover_found);
  EXPECT_NEAR(m.gain_crossover_hz, wc / (2 * kLoopPi), 0.5);
  EXPECT_NEAR(m.phase_margin_deg, 90.0 - wc * delay_s * 180.0 / kLoopPi, 0.3);
  EXPECT_NEAR(m.phase_crossover_hz, wp / (2 * kLoopPi), 1.0);
  EXPECT_NEAR(m.gain_margin_db, -20.0 * std::log10(gain / (mass_kg * wp)), 0.05);
  // Doubling the gain: the gain margin falls by 6.02 dB.
  EXPECT_NEAR(loop_margins(lines_of(loop), 2.0, 0.9).gain_margin_db, m.gain_margin_db - 20 * std::log10(2.0), 0.05);

  // Four times the gain: the phase passes -180 deg where |L| = 1.6, resolved by the lines: a
  // negative gain margin (unstable), not a crossing skipped as a mode's jump.
  const LoopMargins unstable = loop_margins(lines_of(loop), 4.0, 0.9);
  ASSERT_TRUE(unstable.phase_crossover_found);
  EXPECT_NEAR(unstable.gain_margin_db, m.gain_margin_db - 20 * std::log10(4.0), 0.05);
  EXPECT_LT(unstable.gain_margin_db, 0.0);

  // Tuned to 45 deg + 2 and 8 dB + 1: the gain margin binds (it is the smaller here).
  TuningTargets targets{45.0, 8.0, 4.0, 2.0, 1.0};
  std::string why;
  const auto tuned = tune_velocity_pi(lines_of(loop), gain, 0.01, targets, 0.9, why);
  ASSERT_TRUE(tuned.has_value()) << why;
  EXPECT_GE(tuned->after.gain_margin_db, 9.0);
  EXPECT_LT(tuned->after.gain_margin_db, 9.0 + 20 * std::log10(1.01));
  EXPECT_GE(tuned->after.phase_margin_deg, 47.0);
  EXPECT_NEAR(tuned->kp_n_s_per_m, gain * tuned->gain_scale, 1e-9);
  EXPECT_NEAR(tuned->ki_n_per_m, 0.01 * tuned->gain_scale, 1e-15);
  EXPECT_NEAR(tuned->before.gain_margin_db, m.gain_margin_db, 1e-12);

  // Targets no gain meets: nothing, and why.
  targets.min_phase_margin_deg = 89.0;
  EXPECT_FALSE(tune_velocity_pi(lines_of(loop), gain, 0.01, targets, 0.9, why).has_value());
  EXPECT_NE(why.find("phase margin of 91 deg"), std::string::npos) << why;
  targets.min_phase_margin_deg = 0.0;
  EXPECT_THROW(tune_velocity_pi(lines_of(loop), gain, 0.01, targets, 0.9, why), std::invalid_argument);
}

// A lightly damped resonance under the PI: the loop's phase turns half a turn between two lines,
// which cannot be unwrapped; as measured on the 8 kg, 6850 N/m plant of the family, +120 deg at
// 5.25 Hz (28 dB) and -89.5 deg at 5.5 Hz (65.5 dB). That is no phase crossover (|L| >> 1 there),
// and the gain margin is the high-frequency one alone.
TEST(LoopMargins, ALightlyDampedModeBetweenTwoLinesIsNoGainMargin) {
  const double gain = 10000.0, mass_kg = 24.0, delay_s = 1.5e-3;
  const auto loop = [&](double f) {
    const std::complex<double> s(0.0, 2 * kLoopPi * f);
    return gain / (mass_kg * s) * std::exp(-s * delay_s);
  };
  std::vector<FrequencyPoint> points = lines_of(loop);
  const LoopMargins smooth = loop_margins(points, 1.0, 0.9);
  for (FrequencyPoint& p : points) {
    const auto measured = [&](double db, double deg) {
      p.sensitivity = 1.0 / (1.0 + std::polar(std::pow(10.0, db / 20.0), deg * kLoopPi / 180.0));
    };
    if (p.frequency_hz == 5.25) measured(28.07, 120.13);
    if (p.frequency_hz == 5.5) measured(65.55, -89.46);
  }
  const LoopMargins m = loop_margins(points, 1.0, 0.9);
  ASSERT_TRUE(m.phase_crossover_found);
  EXPECT_EQ(m.gain_margin_db, smooth.gain_margin_db);
  EXPECT_EQ(m.phase_crossover_hz, smooth.phase_crossover_hz);
}

// On the simulated drive (the nonlinear plant, its current loop, the encoder): the PI tuned from
// one measurement and measured again at the tuned gains has the margins the tuner predicted,
// within 1.5 deg and 0.6 dB, and meets the shipped targets (45 deg, 8 dB).
TEST(LoopTuning, TheLoopMeasuredAgainAtTheTunedGainsHasThePredictedMargins) {
  const auto measure = [](const SystemParams& p) {
    FrequencyResponseMeasurement m(frequency_response_params(p), p.velocity_pi_params());
    SimulatedDriveBackend drive(p, PlantInitialCondition{});
    run_measurement(drive, m, [](std::uint64_t, std::uint64_t) {});
    EXPECT_EQ(m.phase(), MeasurementPhase::kDone) << m.abort_reason();
    return evaluate_measurement(m);
  };
  SystemParams p = test::shipped_params();
  const double min_coherence = frequency_response_params(p).min_coherence;
  std::string why;
  const auto tuned = tune_velocity_pi(measure(p).points, p.velocity_loop.kp_n_s_per_m, p.velocity_loop.ki_n_per_m,
                                      tuning_targets(p), min_coherence, why);
  ASSERT_TRUE(tuned.has_value()) << why;
  p.velocity_loop.kp_n_s_per_m = tuned->kp_n_s_per_m;
  p.velocity_loop.ki_n_per_m = tuned->ki_n_per_m;
  const LoopMargins again = loop_margins(measure(p).points, 1.0, min_coherence);
  ASSERT_TRUE(again.gain_crossover_found && again.phase_crossover_found);
  EXPECT_NEAR(again.phase_margin_deg, tuned->after.phase_margin_deg, 1.5);
  EXPECT_NEAR(again.gain_margin_db, tuned->after.gain_margin_db, 0.6);
  EXPECT_GE(again.phase_margin_deg, 45.0);
  EXPECT_GE(again.gain_margin_db, 8.0);
  std::printf(
      "[ tuning     ] nominal plant: Kp 10000 -> %.0f N s/m; predicted %.1f deg, %.2f dB; measured again %.1f "
      "deg, %.2f dB\n",
      tuned->kp_n_s_per_m, tuned->after.phase_margin_deg, tuned->after.gain_margin_db, again.phase_margin_deg,
      again.gain_margin_db);
}

// The position loop on the load's encoder (a drive's dual loop), judged from the same measurement:
// on the linear two-mass plant (no friction, no damping) its gain margin says where the loop on
// the plant turns unstable. At the gain the targets allow the load's swing after a move dies
// away; at 1.5 times the gain the measured margin says is critical, it grows.
TEST(PositionLoopTuning, TheLoadSidesMarginSaysWhereTheDualLoopTurnsUnstable) {
  SystemParams p = test::ideal_params();
  p.load_sensor.kind = LoadSensorKind::kEncoder;
  FrequencyResponseMeasurement m(frequency_response_params(p), p.velocity_pi_params());
  SimulatedDriveBackend drive(p, PlantInitialCondition{});
  run_measurement(drive, m, [](std::uint64_t, std::uint64_t) {});
  ASSERT_EQ(m.phase(), MeasurementPhase::kDone) << m.abort_reason();
  const FrequencyResponseResult r = evaluate_measurement(m);
  ASSERT_FALSE(r.load_points.empty());
  const double min_coherence = frequency_response_params(p).min_coherence;
  const std::vector<FrequencyPoint> points =
      position_loop_points(r.points, r.load_points, PositionFeedback::kLoad, p.timing.control_period_s);
  std::string why;
  const auto tuned = tune_position_gain(points, tuning_targets(p), min_coherence, why);
  ASSERT_TRUE(tuned.has_value()) << why;
  const double gain_per_s = tuned->first;
  const LoopMargins& at_tuned = tuned->second;
  // The phase turns through -180 deg at the load's mode on a held motor, sqrt(k / m_L).
  const double anti_hz = anti_resonance_hz(p.plant.mechanics.load_mass_kg, p.plant.mechanics.spring_n_per_m);
  EXPECT_NEAR(at_tuned.phase_crossover_hz, anti_hz, 0.02 * anti_hz);
  EXPECT_GE(at_tuned.gain_margin_db, 9.0 - 1e-9);
  const double critical_per_s = gain_per_s * std::pow(10.0, at_tuned.gain_margin_db / 20.0);

  // The spring's swing over the last two 0.3 s windows of the trapezoid's second at rest.
  const Scenario trapezoid = test::shipped_scenario("trapezoid");
  const auto growth = [&](double gain) {
    SystemParams run = p;
    run.position_loop.closes_on = PositionFeedback::kLoad;
    run.position_loop.gain_per_s = gain;
    run.position_loop.max_correction_mps = 1.0;             // linear: never at the bound
    run.compensator.standstill.stretch_gain_n_per_m = 0.0;  // the loop alone: no push after the stretch at rest
    const std::vector<TickRecord> trace = run_with_compensator(run, trapezoid, CompensatorSetup{});
    const auto rms = [&](std::size_t from, std::size_t to) {
      double mean = 0, square = 0;
      for (std::size_t k = from; k < to; ++k) mean += trace[k].motor_position_m - trace[k].load_position_m;
      mean /= static_cast<double>(to - from);
      for (std::size_t k = from; k < to; ++k) {
        const double d = trace[k].motor_position_m - trace[k].load_position_m - mean;
        square += d * d;
      }
      return std::sqrt(square / static_cast<double>(to - from));
    };
    const std::size_t n = trace.size(), w = 300;
    return rms(n - w, n) / rms(n - 2 * w, n - w);
  };
  const double at_allowed = growth(gain_per_s);
  const double beyond = growth(1.5 * critical_per_s);
  EXPECT_LT(at_allowed, 0.95) << "the swing at the allowed K_x " << gain_per_s << " 1/s does not die away";
  EXPECT_GT(beyond, 1.02) << "the swing at 1.5 x the critical K_x " << critical_per_s << " 1/s does not grow";
  std::printf(
      "[ dual loop  ] nominal linear plant: K_x up to %.3f 1/s (gain margin %.2f dB at %.2f Hz, critical %.3f 1/s); "
      "swing a 0.3 s window x%.3f at it, x%.3f at 1.5 x critical\n",
      gain_per_s, at_tuned.gain_margin_db, at_tuned.phase_crossover_hz, critical_per_s, at_allowed, beyond);
}

// The commissioned factor of a compensator's gain: the cheapest that passes with the next step up
// passing too, else the cheapest that passes. The figures are the nominal plant's on
// configs/sweeps/all_references.yaml (the RNN's output scale: x1.5 cheapest but x2 fails, so
// x1.25; acceleration feedback: x1.5) and the light soft sticky corner's (the RNN: only x1.25).
TEST(GainTrial, TheCheapestFactorWithAPassingStepAboveIsChosen) {
  const auto choice = [](const std::vector<GainTrial>& trials) {
    const auto c = choose_gain_factor(trials);
    return c ? std::make_pair(c->factor, c->step_to_spare) : std::make_pair(0.0, false);
  };
  const std::vector<GainTrial> rnn = {{0.67, true, 0.4265}, {0.8, true, 0.3884}, {1.0, true, 0.3616},
                                      {1.25, true, 0.3381}, {1.5, true, 0.3192}, {2.0, false, 0.8403},
                                      {2.5, false, 1.4628}};
  EXPECT_EQ(choice(rnn), std::make_pair(1.25, true));
  const std::vector<GainTrial> accel = {{0.67, true, 0.4304}, {0.8, true, 0.4082}, {1.0, true, 0.3918},
                                        {1.25, true, 0.3784}, {1.5, true, 0.3639}, {2.0, true, 0.4038},
                                        {2.5, false, 1.3046}};
  EXPECT_EQ(choice(accel), std::make_pair(1.5, true));
  // The largest factor is only the step above: cheapest there, it is still not taken.
  EXPECT_EQ(choice({{1.0, true, 0.5}, {1.5, true, 0.4}, {2.0, true, 0.3}}), std::make_pair(1.5, true));
  // A failing factor between two passing ones disqualifies the one below it.
  EXPECT_EQ(choice({{1.0, true, 0.5}, {1.5, true, 0.3}, {2.0, false, 0.2}, {2.5, true, 0.1}}),
            std::make_pair(1.0, true));
  // No factor with a step to spare: the cheapest that passes, said so.
  const std::vector<GainTrial> corner = {{0.67, false, 0.5250}, {0.8, false, 0.4926}, {1.0, false, 0.4567},
                                         {1.25, true, 0.4526},  {1.5, false, 0.4058}, {2.0, false, 0.3938},
                                         {2.5, false, 0.8054}};
  EXPECT_EQ(choice(corner), std::make_pair(1.25, false));
  EXPECT_EQ(choice({{1.0, true, 0.5}}), std::make_pair(1.0, false));
  EXPECT_EQ(choose_gain_factor({{1.0, false, 0.5}, {1.5, false, 0.3}}), std::nullopt);
  EXPECT_EQ(choose_gain_factor({}), std::nullopt);
  for (const auto& [trials, message] :
       {std::pair<std::vector<GainTrial>, std::string>{{{1.0, true, 0.5}, {1.0, true, 0.4}}, "got 1 at position 2"},
        {{{0.0, true, 0.5}, {1.0, true, 0.4}}, "got 0 at position 1"}}) {
    try {
      choose_gain_factor(trials);
      ADD_FAILURE() << "accepted: " << message;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("positive and ascending, " + message), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace pmlsm
