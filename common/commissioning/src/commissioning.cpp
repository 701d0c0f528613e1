#include "pmlsm/commissioning/commissioning.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <iterator>
#include <stdexcept>

#include "pmlsm/analysis/analysis_params.hpp"
#include "pmlsm/analysis/compensated_run.hpp"
#include "pmlsm/analysis/filter_design.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "pmlsm/sim/live_parameters.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void say(Transcript& transcript, const char* format, ...) {
  char text[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(text, sizeof text, format, args);
  va_end(args);
  if (transcript.echo) std::fputs(text, stdout);
  transcript.text += text;
}

namespace {

/// Scenario `i` of the basis run on `system` with a compensator, judged as the sweep judges it:
/// its verdict, then against PI alone's run of the same scenario.
RunVerdict judged_against_basis(const VerificationBasis& basis, std::size_t i, const SystemParams& system,
                                CompensatorKind kind) {
  RunVerdict v =
      judged_run(system, basis.file.spec.scenarios[i], {kind, basis.weights, false}, basis.file.spec.verdict);
  judge_against_pi_alone(v, basis.pi_alone[i], basis.file.spec.verdict);
  return v;
}

/// The factors the gain trial tries on a compensator's configured gain; the largest only as the
/// step above the one before it.
constexpr double kGainTrialFactors[] = {0.67, 0.8, 1.0, 1.25, 1.5, 2.0, 2.5};

}  // namespace

FrequencyResponseMeasurement measure_on_simulated_plant(const SystemParams& configured,
                                                        const MeasurementProgress& progress) {
  FrequencyResponseMeasurement measurement(frequency_response_params(configured), configured.velocity_pi_params());
  SimulatedDriveBackend drive(configured, PlantInitialCondition{});
  if (progress) progress(measurement, 0);
  run_measurement(drive, measurement, [&](std::uint64_t tick, std::uint64_t) {
    if (progress) progress(measurement, tick);
  });
  return measurement;
}

std::string describe(const LoopMargins& m) {
  char phase[64] = "not in the band", gain[64] = "not in the band";
  if (m.gain_crossover_found) {
    std::snprintf(phase, sizeof phase, "%.1f deg at %.1f Hz", m.phase_margin_deg, m.gain_crossover_hz);
  }
  if (m.phase_crossover_found) {
    std::snprintf(gain, sizeof gain, "%.2f dB at %.1f Hz", m.gain_margin_db, m.phase_crossover_hz);
  }
  return std::string("phase margin ") + phase + ", gain margin " + gain;
}

LoopVerdict judge_loop(const SystemParams& configured, const FrequencyResponseResult& result,
                       const FilterChain& filters, bool tune, Transcript& transcript) {
  const auto& targets = tuning_targets(configured);
  const double min_coherence = frequency_response_params(configured).min_coherence;
  LoopVerdict verdict;
  say(transcript, "velocity loop as measured (Kp %.6g N s/m): %s\n", configured.velocity_loop.kp_n_s_per_m,
      describe(loop_margins(result.points, 1.0, min_coherence)).c_str());
  std::string why;
  verdict.tuned = tune_velocity_pi(result.points, configured.velocity_loop.kp_n_s_per_m,
                                   configured.velocity_loop.ki_n_per_m, targets, min_coherence, why, &filters);
  const bool at_tuned = tune && verdict.tuned;
  const LoopMargins with_filters =
      loop_margins(result.points, at_tuned ? verdict.tuned->gain_scale : 1.0, min_coherence, &filters);
  verdict.margins = describe(with_filters);
  if (!filters.empty()) {
    say(transcript, "with the force command's filters at the %s gains: %s\n", at_tuned ? "tuned" : "configured",
        verdict.margins.c_str());
    verdict.filters_refused = !with_filters.gain_crossover_found || !with_filters.phase_crossover_found ||
                              with_filters.phase_margin_deg < targets.min_phase_margin_deg ||
                              with_filters.gain_margin_db < targets.min_gain_margin_db;
    if (verdict.filters_refused) {
      say(transcript, "the force command's filters are refused: they would leave %s (targets %.4g deg, %.4g dB)\n",
          verdict.margins.c_str(), targets.min_phase_margin_deg, targets.min_gain_margin_db);
    }
  }
  if (!verdict.tuned) {
    say(transcript, "velocity loop tuning (%.4g deg, %.4g dB): %s\n", targets.min_phase_margin_deg,
        targets.min_gain_margin_db, why.c_str());
    return verdict;
  }
  say(transcript, "velocity loop tuned to %.4g deg and %.4g dB: Kp %.6g N s/m, Ki %.6g N/m (x%.3f): %s\n",
      targets.min_phase_margin_deg, targets.min_gain_margin_db, verdict.tuned->kp_n_s_per_m, verdict.tuned->ki_n_per_m,
      verdict.tuned->gain_scale, describe(verdict.tuned->after).c_str());
  return verdict;
}

FilterChainParams design_force_command_filters(const SystemParams& configured, const FrequencyResponseResult& result,
                                               std::vector<ConfigOverride>& values, Transcript& transcript) {
  const FilterChainParams before = configured.force_command_filter_params();
  const auto& design_params = filter_design_params(configured);
  const FilterDesign design = design_notches(result.points, result.fit, before, tuning_targets(configured),
                                             frequency_response_params(configured).min_coherence,
                                             configured.timing.control_period_s, design_params);
  if (design.peaks.empty()) {
    say(transcript, "filter design: no resonance %.3g dB or more over the two-mass model above %.4g Hz; no notch\n",
        design_params.min_peak_db, design_params.min_frequency_hz);
  }
  for (const ResonancePeak& peak : design.peaks) {
    say(transcript, "filter design: resonance %.1f Hz, %.1f dB over the model, %.1f Hz wide: ", peak.frequency_hz,
        peak.height_db, peak.width_hz);
    if (!peak.slot_free) {
      say(transcript, "no free slot in filters.force_command; not placed\n");
      continue;
    }
    say(transcript, "the gains the margins allow x%.3f -> x%.3f with a notch: %s\n", peak.gain_scale_before,
        peak.gain_scale_with, peak.placed ? "placed" : "not placed (less than min_gain_increase)");
  }
  SystemParams designed = configured;
  designed.force_command_filters = design.chain;
  for (std::size_t i = 0; i < kFilterSlots; ++i) {
    const BiquadParams& slot = design.chain.slots[i];
    if (slot == before.slots[i]) continue;
    const std::string at = "filters.force_command.slot_" + std::to_string(i + 1);
    say(transcript, "filter design: %s = notch at %.2f Hz, damping %.4g, second_damping %.4g\n", at.c_str(),
        slot.frequency_hz, slot.damping, slot.second_damping);
    for (const std::string& key : filter_slot_keys(at)) values.push_back({key, parameter_text(designed, key)});
  }
  return design.chain;
}

std::vector<std::pair<std::string, double>> commissioned_parameters(const TwoMassFit& fit,
                                                                    const std::optional<IdentifiedLoad>& time_domain) {
  std::vector<std::pair<std::string, double>> values;
  if (time_domain) {
    for (const auto& [key, value] : identified_parameters(*time_domain)) {
      const bool load = key.find("load_mass_kg") != std::string::npos;
      const bool spring = key.find("spring_n_per_m") != std::string::npos;
      values.emplace_back(key, load ? fit.load_mass_kg : spring ? fit.spring_n_per_m : value);
    }
  } else {
    for (const char* model : {"kalman.model.", "compensator.state_feedback.model."}) {
      values.emplace_back(std::string(model) + "load_mass_kg", fit.load_mass_kg);
      values.emplace_back(std::string(model) + "spring_n_per_m", fit.spring_n_per_m);
    }
  }
  values.emplace_back("kalman.model.motor_mass_kg", fit.motor_mass_kg);
  values.emplace_back("compensator.state_feedback.model.motor_mass_kg", fit.motor_mass_kg);
  return values;
}

double error_percent(double measured, double truth) { return 100.0 * (measured / truth - 1.0); }

std::optional<FrequencyResponseResult> measured_response(const SystemParams& p, std::string& why) {
  const FrequencyResponseMeasurement m = measure_on_simulated_plant(p);
  if (m.phase() != MeasurementPhase::kDone) {
    why = "the measurement ended early: " + m.abort_reason();
    return std::nullopt;
  }
  try {
    return evaluate_measurement(m);
  } catch (const std::invalid_argument& e) {
    why = e.what();
    return std::nullopt;
  }
}

VerificationBasis verification_basis(const std::string& sweep_path, const SystemParams& commissioned) {
  VerificationBasis basis{sweep_path, load_sweep_file(sweep_path, commissioned), {}, {}};
  if (!basis.file.weights_path.empty()) basis.weights = load_rnn_weights(basis.file.weights_path).weights;
  for (const Scenario& scenario : basis.file.spec.scenarios) {
    basis.pi_alone.push_back(
        judged_run(commissioned, scenario, {CompensatorKind::kNone, {}, false}, basis.file.spec.verdict));
  }
  return basis;
}

bool passes_against(const RunVerdict& v, const RunVerdict& pi_alone) {
  return v.faults().empty() && v.cost < pi_alone.cost;
}

Verification verify_commissioned(const VerificationBasis& basis, const SystemParams& commissioned, std::ostream& csv,
                                 const std::string& row_prefix, Transcript& transcript) {
  const SweepFile& file = basis.file;
  std::vector<CompensatorKind> kinds{CompensatorKind::kNone};
  kinds.insert(kinds.end(), file.spec.compensators.begin(), file.spec.compensators.end());
  say(transcript, "verification (%s: scenarios, compensators, verdict) on the plant with the commissioned system:\n",
      basis.path.c_str());
  Verification outcome;
  for (std::size_t i = 0; i < file.spec.scenarios.size(); ++i) {
    const Scenario& scenario = file.spec.scenarios[i];
    const RunVerdict& pi_alone = basis.pi_alone[i];
    say(transcript, "  %-16s", scenario.name.c_str());
    for (const CompensatorKind kind : kinds) {
      RunVerdict v = kind == CompensatorKind::kNone ? pi_alone : judged_against_basis(basis, i, commissioned, kind);
      if (kind == CompensatorKind::kNone) judge_against_pi_alone(v, pi_alone, file.spec.verdict);
      const bool passed = kind == CompensatorKind::kNone || passes_against(v, pi_alone);
      if (kind != CompensatorKind::kNone) {
        ++outcome.runs;
        outcome.failed_runs += passed ? 0 : 1;
        outcome.worst_cost_ratio = std::max(outcome.worst_cost_ratio, v.cost / pi_alone.cost);
      }
      outcome.passed = outcome.passed && passed;
      say(transcript, "  %s %.3f%s%s", to_string(kind), v.cost, v.faults().empty() ? "" : (" " + v.faults()).c_str(),
          passed ? "" : " (fails)");
      csv << row_prefix << scenario.name << ',' << to_string(kind) << ',' << v.cost << ',' << v.cost / pi_alone.cost
          << ",\"" << v.faults() << "\"," << v.tail_force_rms_n << ',' << v.tail_compensation_rms_n << '\n';
    }
    say(transcript, "\n");
  }
  say(transcript, "verification: %s\n",
      outcome.passed ? "every compensator clean and cheaper than PI alone on every scenario"
                     : "a compensator failed (see the table)");
  return outcome;
}

SystemParams commissioned_system(const SystemParams& configured,
                                 const std::vector<std::pair<std::string, double>>& values, const FilterChain& filters,
                                 const TwoMassFit& fit, bool simulate) {
  SystemParams commissioned = configured;
  for (const auto& [key, value] : values) real_parameter(commissioned, key) = value;
  commissioned.force_command_filters = filters.params();
  if (!simulate) {
    commissioned.plant.mechanics.motor_mass_kg = fit.motor_mass_kg;
    commissioned.plant.mechanics.load_mass_kg = fit.load_mass_kg;
    commissioned.plant.mechanics.spring_n_per_m = fit.spring_n_per_m;
  }
  commissioned.validate();
  return commissioned;
}

void tune_state_feedback_filter(const VerificationBasis& basis, SystemParams& commissioned,
                                std::vector<ConfigOverride>& text_values, Transcript& transcript) {
  if (commissioned.compensator.state_feedback.output_filter_enabled) return;
  const SweepFile& file = basis.file;
  SystemParams filtered = commissioned;
  filtered.compensator.state_feedback.output_filter_enabled = true;
  bool clean = true;
  double ratio_without = 0, ratio_with = 0;
  std::string costs;
  for (std::size_t i = 0; i < file.spec.scenarios.size(); ++i) {
    const Scenario& scenario = file.spec.scenarios[i];
    const RunVerdict& pi_alone = basis.pi_alone[i];
    const RunVerdict without = judged_against_basis(basis, i, commissioned, CompensatorKind::kState);
    const RunVerdict with = judged_against_basis(basis, i, filtered, CompensatorKind::kState);
    clean = clean && with.faults().empty();
    ratio_without += without.cost / pi_alone.cost;
    ratio_with += with.cost / pi_alone.cost;
    char line[160];
    std::snprintf(line, sizeof line, "%s%s %.3f -> %.3f%s", costs.empty() ? "" : ", ", scenario.name.c_str(),
                  without.cost, with.cost, with.faults().empty() ? "" : (" " + with.faults()).c_str());
    costs += line;
  }
  const auto n = static_cast<double>(file.spec.scenarios.size());
  const bool better = clean && ratio_with < ratio_without;
  say(transcript,
      "state feedback's output filter (%s at %.4g Hz) on the commissioned system: %s; mean cost over PI alone's "
      "%.4f -> %.4f: %s\n",
      to_string(filtered.compensator.state_feedback.output_filter.kind),
      filtered.compensator.state_feedback.output_filter.frequency_hz, costs.c_str(), ratio_without / n, ratio_with / n,
      better ? "on" : "stays off");
  if (!better) return;
  commissioned = filtered;
  text_values.push_back({"compensator.state_feedback.output_filter.enabled", "true"});
}

void tune_compensator_gains(const VerificationBasis& basis, SystemParams& commissioned,
                            std::vector<ConfigOverride>& text_values, Transcript& transcript) {
  const SweepFile& file = basis.file;
  const std::vector<RunVerdict>& pi_alone = basis.pi_alone;
  const auto scenarios = static_cast<double>(file.spec.scenarios.size());
  for (const CompensatorKind kind : file.spec.compensators) {
    if (kind != CompensatorKind::kAccel && kind != CompensatorKind::kRnn) continue;
    const bool accel = kind == CompensatorKind::kAccel;
    const std::string key = accel ? "compensator.acceleration_feedback.gain_kg" : "compensator.rnn.output_scale";
    const auto gain_of = [accel](SystemParams& system) -> double& {
      return accel ? system.compensator.acceleration_feedback.gain_kg : system.compensator.rnn.output_scale;
    };
    const double configured = gain_of(commissioned);
    std::vector<GainTrial> trials;
    std::string costs;
    for (const double factor : kGainTrialFactors) {
      SystemParams trial_system = commissioned;
      gain_of(trial_system) = configured * factor;
      GainTrial trial{factor, true, 0.0};
      for (std::size_t i = 0; i < file.spec.scenarios.size(); ++i) {
        const RunVerdict v = judged_against_basis(basis, i, trial_system, kind);
        trial.passes = trial.passes && passes_against(v, pi_alone[i]);
        trial.mean_cost_ratio += v.cost / pi_alone[i].cost / scenarios;
      }
      char line[96];
      std::snprintf(line, sizeof line, "%sx%.3g %.4f%s", costs.empty() ? "" : ", ", factor, trial.mean_cost_ratio,
                    trial.passes ? "" : " (fails)");
      costs += line;
      trials.push_back(trial);
    }
    const std::optional<GainChoice> chosen = choose_gain_factor(trials);
    say(transcript, "%s on the commissioned system (mean cost over PI alone's, x its configured %.4g): %s: %s\n",
        key.c_str(), configured, costs.c_str(),
        !chosen ? "none passes, stays"
                : ("x" + format_value(chosen->factor) + (chosen->step_to_spare ? "" : " (no step to spare)")).c_str());
    if (!chosen || chosen->factor == 1.0) continue;
    gain_of(commissioned) = configured * chosen->factor;
    text_values.push_back({key, format_value(gain_of(commissioned))});
  }
}

namespace {

/// The position loop (position_loop.closes_on not none) judged from the same measurement at the
/// velocity loop's gains it will run with: its margins at the configured K_x and the largest K_x the
/// targets allow, printed; with --tune that K_x goes into `values`. Returns false when the
/// configured K_x leaves the loop short of its margins and --tune does not replace it.
bool judge_position_loop(const SystemParams& configured, const FrequencyResponseResult& result,
                         const FilterChain& filters, const LoopVerdict& loop, bool tune,
                         std::vector<std::pair<std::string, double>>& values, Transcript& transcript) {
  const PositionLoopParams& position = configured.position_loop;
  if (position.closes_on == PositionFeedback::kNone) return true;
  const auto& targets = tuning_targets(configured);
  const double min_coherence = frequency_response_params(configured).min_coherence;
  const double velocity_scale = tune && loop.tuned ? loop.tuned->gain_scale : 1.0;
  const std::vector<FrequencyPoint> points =
      position_loop_points(result.points, result.load_points, position.closes_on, configured.timing.control_period_s,
                           velocity_scale, &filters);
  const LoopMargins configured_margins = position_loop_margins(points, position.gain_per_s, min_coherence);
  say(transcript, "position loop on the %s's encoder at K_x %.4g 1/s: %s\n", to_string(position.closes_on),
      position.gain_per_s, describe(configured_margins).c_str());
  std::string why;
  const auto tuned = tune_position_gain(points, targets, min_coherence, why);
  if (!tuned) {
    say(transcript, "position loop tuning (%.4g deg, %.4g dB): %s\n", targets.min_phase_margin_deg,
        targets.min_gain_margin_db, why.c_str());
  } else {
    say(transcript, "position loop: the margins allow K_x up to %.4g 1/s: %s\n", tuned->first,
        describe(tuned->second).c_str());
    if (tune) {
      values.emplace_back("position_loop.gain_per_s", tuned->first);
      return true;
    }
  }
  return margins_met(configured_margins, targets);
}

}  // namespace

CommissionDecision decide(const CommissioningChoices& o, const SystemParams& configured,
                          const FrequencyResponseResult& result, const std::optional<IdentifiedLoad>& time_domain,
                          std::ostream& verification_csv, const std::string& row_prefix, Transcript& transcript) {
  CommissionDecision d;
  d.filters = o.design_filters ? design_force_command_filters(configured, result, d.text_values, transcript)
                               : configured.force_command_filter_params();
  const FilterChain filters(d.filters);
  d.loop = judge_loop(configured, result, filters, o.tune, transcript);
  if (d.loop.filters_refused || (o.tune && !d.loop.tuned)) {
    say(transcript, "commission: %s; nothing written\n",
        d.loop.filters_refused ? "the force command's filters leave the loop short of its margins"
                               : "--tune: no gains meet the margins");
    d.exit_code = kExitVerdictFailed;
    return d;
  }
  d.values = commissioned_parameters(result.fit, time_domain);
  if (o.tune) {
    d.values.emplace_back("velocity_loop.kp_n_s_per_m", d.loop.tuned->kp_n_s_per_m);
    d.values.emplace_back("velocity_loop.ki_n_per_m", d.loop.tuned->ki_n_per_m);
  }
  if (!judge_position_loop(configured, result, filters, d.loop, o.tune, d.values, transcript)) {
    say(transcript,
        "commission: the position loop's gain leaves it short of its margins; nothing written "
        "(--tune sets the gain the margins allow)\n");
    d.exit_code = kExitVerdictFailed;
    return d;
  }
  SystemParams commissioned = commissioned_system(configured, d.values, filters, result.fit, o.simulate);
  if (o.verify.empty()) {
    d.commissioned = commissioned;
    return d;
  }
  const VerificationBasis basis = verification_basis(o.verify, commissioned);
  if (o.tune) {
    tune_state_feedback_filter(basis, commissioned, d.text_values, transcript);
    tune_compensator_gains(basis, commissioned, d.text_values, transcript);
  }
  d.commissioned = commissioned;
  d.verification = verify_commissioned(basis, commissioned, verification_csv, row_prefix, transcript);
  if (!d.verification->passed) {
    say(transcript, "commission: the verification failed; nothing written (--no-verify writes it regardless)\n");
    d.exit_code = kExitVerdictFailed;
  }
  return d;
}

std::optional<FamilyRow> family_row(const CommissioningChoices& o, const SystemParams& p,
                                    const Scenario& identification, std::ostream& verification_csv,
                                    const std::string& label, std::string& why) {
  const auto r = measured_response(p, why);
  if (!r) return std::nullopt;
  std::optional<IdentifiedLoad> time_domain;
  try {
    time_domain = commission_load(p, identification, IdentificationParams{});
  } catch (const std::invalid_argument& e) {
    why = std::string("the time-domain fit: ") + e.what();
    return std::nullopt;
  }
  const auto& truth = p.plant.mechanics;
  const double anti_hz = anti_resonance_hz(truth.load_mass_kg, truth.spring_n_per_m);
  const double res_hz = resonance_hz(truth.motor_mass_kg, truth.load_mass_kg, truth.spring_n_per_m);
  FamilyRow row;
  const double errors[5] = {error_percent(r->fit.anti_resonance_hz, anti_hz),
                            error_percent(r->fit.resonance_hz, res_hz),
                            error_percent(r->fit.load_mass_kg, truth.load_mass_kg),
                            error_percent(r->fit.spring_n_per_m, truth.spring_n_per_m),
                            error_percent(r->fit.motor_mass_kg, truth.motor_mass_kg)};
  std::copy(std::begin(errors), std::end(errors), std::begin(row.errors));
  if (r->load_fit) {
    row.load_side_error_percent = error_percent(r->load_fit->anti_resonance_hz, anti_hz);
    row.load_sensor_gain = r->load_fit->gain;
  }
  Transcript quiet{{}, false};
  row.decision = decide(o, p, *r, time_domain, verification_csv, label + ",", quiet);
  if (!row.decision.loop.tuned) {
    why = "velocity loop tuning: no gains meet the margins";
    return std::nullopt;
  }
  SystemParams at_tuned = p;
  at_tuned.velocity_loop.kp_n_s_per_m = row.decision.loop.tuned->kp_n_s_per_m;
  at_tuned.velocity_loop.ki_n_per_m = row.decision.loop.tuned->ki_n_per_m;
  const auto again = measured_response(at_tuned, why);
  if (!again) return std::nullopt;
  row.tuned_kp_n_s_per_m = row.decision.loop.tuned->kp_n_s_per_m;
  const FilterChain filters(row.decision.filters);
  row.tuned = loop_margins(again->points, 1.0, frequency_response_params(p).min_coherence, &filters);
  return row;
}

bool margins_met(const LoopMargins& m, const TuningTargets& targets) {
  return m.gain_crossover_found && m.phase_crossover_found && m.phase_margin_deg >= targets.min_phase_margin_deg &&
         m.gain_margin_db >= targets.min_gain_margin_db;
}

}  // namespace pmlsm
