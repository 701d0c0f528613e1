#include "pmlsm/analysis/sweep.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cmath>
#include <exception>
#include <mutex>
#include <random>
#include <set>
#include <stdexcept>
#include <thread>

#include <Eigen/Dense>

#include "pmlsm/sim/metrics.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void VerdictParams::validate() const {
  require_in_range("verdict.tail_s", tail_s, 1e-3, 3600.0);
  require_in_range("verdict.tail_windows", static_cast<double>(tail_windows), 2.0, 1000.0);
  require_in_range("verdict.limit_cycle_amplitude_m", limit_cycle_amplitude_m, 1e-9, 1.0);
  require_in_range("verdict.min_decay_rate_per_s", min_decay_rate_per_s, 0.0, 1e4);
  require_in_range("verdict.max_saturated_tail_share", max_saturated_tail_share, 0.0, 1.0);
  require_in_range("verdict.max_free_vibration_settling_s", max_free_vibration_settling_s, 1e-3, 3600.0);
  require_in_range("verdict.rest_command_band_mps", rest_command_band_mps, 0.0, 10.0);
  require_in_range("verdict.min_rest_s", min_rest_s, 0.0, 3600.0);
  require_in_range("verdict.max_rest_stretch_peak_m", max_rest_stretch_peak_m, 1e-9, 1.0);
  require_in_range("verdict.max_rest_compensation_rms_n", max_rest_compensation_rms_n, 0.0, 1e5);
  require_in_range("verdict.max_forced_ratio_to_pi", max_forced_ratio_to_pi, 1.0, 1e3);
}

namespace {
// Plants a sweep may hold: 1e5 of them at a few 10 ms per run are hours on one core.
constexpr double kMaxPlants = 100000;
}  // namespace

void SweepRange::validate(const SystemParams& nominal) const {
  if (key_path.rfind("plant.", 0) != 0) {
    throw std::invalid_argument(
        "key: the sweep moves the plant only (plant.*): the estimator's and the "
        "compensators' models stay as configured, got '" +
        key_path + "'");
  }
  SystemParams probe = nominal;
  Plausible range{0, 0, ""};
  try {
    real_parameter(probe, key_path, &range);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("key: ") + e.what());
  }
  require_finite("min", min);
  require_finite("max", max);
  if (!(min < max)) {
    throw std::invalid_argument("min (" + format_value(min) + ") must be below max (" + format_value(max) + ") for " +
                                key_path);
  }
  for (const double bound : {min, max}) {
    if (bound < range.min || bound > range.max) {
      throw std::invalid_argument(key_path + " must stay in [" + format_value(range.min) + ", " +
                                  format_value(range.max) + "] (" + range.reason + "), got " + format_value(bound));
    }
  }
}

void SweepSpec::validate(const SystemParams& nominal) const {
  if (ranges.empty()) throw std::invalid_argument("plants.parameters: at least one parameter to vary");
  std::set<std::string> seen;
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const SweepRange& r = ranges[i];
    const std::string at = "plants.parameters[" + std::to_string(i) + "]";
    if (!seen.insert(r.key_path).second) throw std::invalid_argument(at + ".key: '" + r.key_path + "' twice");
    try {
      r.validate(nominal);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(at + ": " + e.what());
    }
  }
  if (sampling.grid_points == 1 || sampling.grid_points > 101) {
    throw std::invalid_argument("plants.grid_points: must be 0 (no grid) or 2 to 101, got " +
                                std::to_string(sampling.grid_points));
  }
  const double grid = sampling.grid_points == 0
                          ? 0.0
                          : std::pow(static_cast<double>(sampling.grid_points), static_cast<double>(ranges.size()));
  const double plants = grid + (sampling.centre ? 1.0 : 0.0) + static_cast<double>(sampling.random);
  if (plants < 1 || plants > kMaxPlants) {
    throw std::invalid_argument("plants: grid, centre and random give " + format_value(plants) +
                                " plants; must be 1 to " + format_value(kMaxPlants));
  }
  std::set<CompensatorKind> kinds;
  for (CompensatorKind kind : compensators) {
    if (!kinds.insert(kind).second) {
      throw std::invalid_argument(std::string("compensators: '") + to_string(kind) + "' twice");
    }
  }
  if (scenarios.empty()) throw std::invalid_argument("scenarios: at least one");
  for (const Scenario& s : scenarios) s.validate(nominal.timing.control_period_s);
  if (identify_models) {
    identification_scenario.validate(nominal.timing.control_period_s);
    identification.validate();
  }
  verdict.validate();
}

std::vector<PlantSample> sample_plants(const SweepSpec& spec) {
  std::vector<PlantSample> plants;
  const std::size_t dims = spec.ranges.size();
  const std::uint64_t n = spec.sampling.grid_points;
  if (n >= 2) {
    std::uint64_t count = 1;
    for (std::size_t d = 0; d < dims; ++d) count *= n;
    for (std::uint64_t index = 0; index < count; ++index) {
      PlantSample plant{"grid " + std::to_string(index), std::vector<double>(dims)};
      std::uint64_t rest = index;
      // Row-major, the first parameter slowest: its digit is the most significant.
      for (std::size_t d = dims; d-- > 0;) {
        const double step = static_cast<double>(rest % n) / static_cast<double>(n - 1);
        rest /= n;
        const SweepRange& r = spec.ranges[d];
        plant.values[d] = r.min + step * (r.max - r.min);
      }
      plants.push_back(std::move(plant));
    }
  }
  if (spec.sampling.centre) {
    PlantSample plant{"centre", std::vector<double>(dims)};
    for (std::size_t d = 0; d < dims; ++d) plant.values[d] = 0.5 * (spec.ranges[d].min + spec.ranges[d].max);
    plants.push_back(std::move(plant));
  }
  // mt19937_64's sequence is fixed by the standard; the mapping to [0, 1) is ours (53 bits),
  // so a seed gives the same plants with any standard library.
  std::mt19937_64 rng(spec.sampling.seed);
  for (std::uint64_t i = 0; i < spec.sampling.random; ++i) {
    PlantSample plant{"random " + std::to_string(i), std::vector<double>(dims)};
    for (std::size_t d = 0; d < dims; ++d) {
      const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;
      plant.values[d] = spec.ranges[d].min + u * (spec.ranges[d].max - spec.ranges[d].min);
    }
    plants.push_back(std::move(plant));
  }
  return plants;
}

SystemParams plant_variant(const SystemParams& nominal, const SweepSpec& spec, const PlantSample& plant) {
  SystemParams params = nominal;
  for (std::size_t d = 0; d < spec.ranges.size(); ++d)
    real_parameter(params, spec.ranges[d].key_path) = plant.values[d];
  try {
    params.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("plant '" + plant.label + "': " + e.what());
  }
  return params;
}

std::string RunVerdict::faults() const {
  std::string out;
  const auto add = [&](bool on, const char* what) {
    if (on) out += (out.empty() ? "" : ", ") + std::string(what);
  };
  add(non_finite, "non-finite");
  add(sensor_failed, "sensor");
  add(limit_cycle, "limit cycle");
  add(saturated, "saturated");
  add(guard_trip_s >= 0, "guard");
  add(slow, "slow");
  add(residual, "residual");
  add(chatter, "chatter");
  return out;
}

namespace {

bool record_finite(const TickRecord& r) {
  return std::isfinite(r.force_command_n) && std::isfinite(r.motor_velocity_mps) &&
         std::isfinite(r.load_velocity_mps) && std::isfinite(r.motor_position_m) && std::isfinite(r.load_position_m);
}

// RMS of x - mean over values[begin, end).
double rms_about(const std::vector<double>& values, std::size_t begin, std::size_t end, double mean) {
  if (end <= begin) return 0.0;
  double sum = 0;
  for (std::size_t i = begin; i < end; ++i) sum += (values[i] - mean) * (values[i] - mean);
  return std::sqrt(sum / static_cast<double>(end - begin));
}

// Cost (23) per window of the run: a later window cheaper than the first is a decaying error.
// The last window's cost over the first's; NaN without two windows or with a free first one.
double last_to_first_window_cost(const std::vector<TickRecord>& trace, std::size_t window) {
  std::vector<double> window_costs;
  for (std::size_t begin = 1; window > 0 && begin + window <= trace.size(); begin += window) {
    double cost = 0;
    for (std::size_t k = begin; k < begin + window; ++k) {
      cost += std::fabs(trace[k].v_ref_mps - trace[k].load_velocity_mps);
    }
    window_costs.push_back(cost);
  }
  if (window_costs.size() >= 2 && window_costs.front() > 0) return window_costs.back() / window_costs.front();
  return std::numeric_limits<double>::quiet_NaN();
}

// Decay rate of the stretch from `begin` to its end, in `windows` equal windows: the
// least-squares slope of ln(RMS) over the windows' centres, negated. A window without motion
// (RMS 0) means the oscillation is gone: nothing left to decay (+inf).
double tail_decay_rate_per_s(const std::vector<double>& stretch, std::size_t begin, std::size_t windows, double mean,
                             double control_period_s) {
  const std::size_t per_window = (stretch.size() - begin) / windows;
  double sum_t = 0, sum_y = 0, sum_tt = 0, sum_ty = 0;
  bool silent = per_window == 0;
  for (std::size_t w = 0; w < windows && !silent; ++w) {
    const std::size_t from = begin + w * per_window;
    const double rms = rms_about(stretch, from, from + per_window, mean);
    if (!(rms > 0)) {
      silent = true;
      break;
    }
    const double t = (static_cast<double>(w) + 0.5) * static_cast<double>(per_window) * control_period_s;
    const double y = std::log(rms);
    sum_t += t;
    sum_y += y;
    sum_tt += t * t;
    sum_ty += t * y;
  }
  const double count = static_cast<double>(windows);
  const double spread = count * sum_tt - sum_t * sum_t;
  return silent || !(spread > 0) ? std::numeric_limits<double>::infinity() : -(count * sum_ty - sum_t * sum_y) / spread;
}

}  // namespace

namespace {

// The tail's ticks [begin, n) and its last window [n - last_window, n).
struct TailSpan {
  std::size_t n = 0, tail = 0, begin = 0, last_window = 1;
};

TailSpan tail_span(std::size_t n, double control_period_s, const VerdictParams& verdict) {
  TailSpan span;
  span.n = n;
  span.tail = std::min<std::size_t>(n, static_cast<std::size_t>(std::llround(verdict.tail_s / control_period_s)));
  span.begin = n - span.tail;
  span.last_window = std::max<std::size_t>(1, span.tail / static_cast<std::size_t>(verdict.tail_windows));
  return span;
}

// The spring stretch x_L - x_M over the tail: its amplitude about its mean and how fast it decays;
// whether the tail and the run's end are at rest; a limit cycle at rest; hunting at a standstill
// (the stretch's peak in the last window about that window's mean: the first windows may still
// hold the last edge's decaying transient).
void judge_tail_stretch(const std::vector<TickRecord>& trace, const TailSpan& span, double control_period_s,
                        const VerdictParams& verdict, RunVerdict& out) {
  const std::size_t n = span.n;
  std::vector<double> stretch(n);
  for (std::size_t k = 0; k < n; ++k) stretch[k] = trace[k].load_position_m - trace[k].motor_position_m;
  double mean = 0;
  for (std::size_t k = span.begin; k < n; ++k) mean += stretch[k];
  mean /= static_cast<double>(std::max<std::size_t>(span.tail, 1));
  out.tail_stretch_amplitude_m = std::sqrt(2.0) * rms_about(stretch, span.begin, n, mean);
  out.tail_decay_rate_per_s = tail_decay_rate_per_s(stretch, span.begin, static_cast<std::size_t>(verdict.tail_windows),
                                                    mean, control_period_s);
  std::size_t resting = 0;  // ticks at rest up to the end
  while (resting < n && std::fabs(trace[n - 1 - resting].command_mps) <= verdict.rest_command_band_mps) ++resting;
  out.rest_tail = resting >= span.tail;
  if (out.rest_tail) {
    out.tail_unforced_amplitude_m = out.tail_stretch_amplitude_m;
    out.tail_unforced_decay_rate_per_s = out.tail_decay_rate_per_s;
  } else {
    const std::vector<double> unforced = unforced_stretch(trace, span.begin, n, control_period_s);
    out.tail_unforced_amplitude_m = std::sqrt(2.0) * rms_about(unforced, 0, unforced.size(), 0.0);
    out.tail_unforced_decay_rate_per_s =
        tail_decay_rate_per_s(unforced, 0, static_cast<std::size_t>(verdict.tail_windows), 0.0, control_period_s);
  }
  out.standstill =
      out.rest_tail && static_cast<double>(resting) * control_period_s >= verdict.min_rest_s * (1.0 - 1e-9);
  // A moving tail holds the reference's forced response: judged against PI alone's instead.
  out.limit_cycle = out.rest_tail && std::isfinite(out.tail_stretch_amplitude_m) &&
                    out.tail_stretch_amplitude_m >= verdict.limit_cycle_amplitude_m &&
                    !(out.tail_decay_rate_per_s >= verdict.min_decay_rate_per_s);
  double last_mean = 0;
  for (std::size_t k = n - span.last_window; k < n; ++k) last_mean += stretch[k];
  last_mean /= static_cast<double>(span.last_window);
  for (std::size_t k = n - span.last_window; k < n; ++k) {
    out.rest_stretch_peak_m = std::max(out.rest_stretch_peak_m, std::fabs(stretch[k] - last_mean));
  }
  out.residual = out.standstill && !(out.rest_stretch_peak_m <= verdict.max_rest_stretch_peak_m);
}

// The forces: the force command about its mean and the compensation over the tail; chatter at a
// standstill (the compensation over the last window: the first may still be damping the last
// edge's swing, which is the compensation's job); saturation (the force command at its limit,
// the velocity PI's output after the compensation).
void judge_tail_forces(const std::vector<TickRecord>& trace, const TailSpan& span, double force_limit_n,
                       const VerdictParams& verdict, RunVerdict& out) {
  const std::size_t n = span.n;
  const double tail_ticks = static_cast<double>(std::max<std::size_t>(span.tail, 1));
  double force_mean = 0;
  for (std::size_t k = span.begin; k < n; ++k) force_mean += trace[k].force_command_n;
  force_mean /= tail_ticks;
  double force_square = 0, compensation_square = 0, rest_square = 0;
  for (std::size_t k = span.begin; k < n; ++k) {
    const double compensation_square_k = trace[k].compensation_force_n * trace[k].compensation_force_n;
    force_square += (trace[k].force_command_n - force_mean) * (trace[k].force_command_n - force_mean);
    compensation_square += compensation_square_k;
    if (k >= n - span.last_window) rest_square += compensation_square_k;
  }
  out.tail_force_rms_n = std::sqrt(force_square / tail_ticks);
  out.tail_compensation_rms_n = std::sqrt(compensation_square / tail_ticks);
  out.rest_compensation_rms_n = std::sqrt(rest_square / static_cast<double>(span.last_window));
  out.chatter = out.standstill && !(out.rest_compensation_rms_n <= verdict.max_rest_compensation_rms_n);

  std::size_t saturated = 0;
  std::size_t saturated_tail = 0;
  const double at_limit = force_limit_n * (1.0 - 1e-9);
  for (std::size_t k = 0; k < n; ++k) {
    if (std::fabs(trace[k].force_command_n) >= at_limit) {
      ++saturated;
      if (k >= span.begin) ++saturated_tail;
    }
  }
  out.saturated_share = static_cast<double>(saturated) / static_cast<double>(n);
  out.saturated_tail_share =
      span.tail == 0 ? 0.0 : static_cast<double>(saturated_tail) / static_cast<double>(span.tail);
  out.saturated = out.saturated_tail_share > verdict.max_saturated_tail_share;
}

}  // namespace

std::vector<double> unforced_stretch(const std::vector<TickRecord>& trace, std::size_t begin, std::size_t end,
                                     double control_period_s) {
  end = std::min(end, trace.size());
  if (end <= begin) return {};
  const auto rows = static_cast<Eigen::Index>(end - begin);
  const std::size_t spacing =
      std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(kForcedResponseTapSpacing_s / control_period_s)));
  // Columns: a constant (the stretch's mean) and V_ref(t_k - j spacing), each scaled to unit norm
  // so the pivoting QR can tell a reference that does not move (a cruise: the taps are the constant
  // again) and drop what it does not span.
  Eigen::MatrixXd a(rows, kForcedResponseTaps + 1);
  Eigen::VectorXd y(rows);
  for (Eigen::Index r = 0; r < rows; ++r) {
    const std::size_t k = begin + static_cast<std::size_t>(r);
    y(r) = trace[k].load_position_m - trace[k].motor_position_m;
    a(r, 0) = 1.0;
    for (int j = 1; j <= kForcedResponseTaps; ++j) {
      const std::size_t lag = static_cast<std::size_t>(j - 1) * spacing;
      a(r, j) = trace[k >= lag ? k - lag : 0].v_ref_mps;
    }
  }
  for (Eigen::Index c = 0; c < a.cols(); ++c) {
    const double norm = a.col(c).norm();
    if (norm > 0) a.col(c) /= norm;
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  qr.setThreshold(1e-9);
  const Eigen::VectorXd residual = y - a * qr.solve(y);
  return {residual.data(), residual.data() + residual.size()};
}

RunVerdict judge_run(const std::vector<TickRecord>& trace, const Scenario& scenario, double control_period_s,
                     double force_limit_n, const VerdictParams& verdict) {
  RunVerdict out;
  if (trace.empty()) {
    out.non_finite = true;
    return out;
  }
  for (const TickRecord& r : trace) {
    if (r.plant_fault_state != nullptr || !record_finite(r)) out.non_finite = true;
    if (r.guard_tripped && out.guard_trip_s < 0) out.guard_trip_s = r.time_s;
    if (r.load_sensor_use == LoadSensorUse::kFailed) out.sensor_failed = true;
  }
  const ScenarioMetrics metrics = compute_metrics(trace, scenario, control_period_s);
  out.cost = metrics.cost_true;
  out.settling_s = metrics.load_settling_time_s;
  out.slow = scenario.initial_load_displacement_m != 0.0 && !(out.settling_s <= verdict.max_free_vibration_settling_s);
  out.last_to_first_window_cost = last_to_first_window_cost(
      trace, static_cast<std::size_t>(std::llround(scenario.cost_window_s / control_period_s)));

  double x_ref_m = 0;
  for (std::size_t k = 0; k + 1 < trace.size(); ++k) x_ref_m += trace[k].v_ref_mps * control_period_s;
  out.end_position_error_m = x_ref_m - (trace.back().load_position_m - trace.front().load_position_m);

  const TailSpan span = tail_span(trace.size(), control_period_s, verdict);
  judge_tail_stretch(trace, span, control_period_s, verdict, out);
  judge_tail_forces(trace, span, force_limit_n, verdict, out);
  if (out.non_finite) {
    out.limit_cycle = out.saturated = out.slow = out.residual = out.chatter = false;  // one fault says it all
  }
  return out;
}

RunVerdict judged_run(const SystemParams& params, const Scenario& scenario, const CompensatorSetup& compensator,
                      const VerdictParams& verdict) {
  return judge_run(run_with_compensator(params, scenario, compensator), scenario, params.timing.control_period_s,
                   params.velocity_loop.force_limit_n, verdict);
}

void judge_against_pi_alone(RunVerdict& run, const RunVerdict& pi_alone, const VerdictParams& verdict) {
  if (run.rest_tail || run.non_finite) return;
  run.limit_cycle =
      std::isfinite(run.tail_unforced_amplitude_m) &&
      run.tail_unforced_amplitude_m >= verdict.limit_cycle_amplitude_m &&
      run.tail_unforced_amplitude_m > verdict.max_forced_ratio_to_pi * pi_alone.tail_unforced_amplitude_m &&
      !(run.tail_unforced_decay_rate_per_s >= verdict.min_decay_rate_per_s);
}

const SweepRun& SweepResult::run(std::size_t plant, std::size_t compensator, std::size_t scenario) const {
  const std::size_t scenarios = runs.size() / std::max<std::size_t>(1, plants.size() * compensators.size());
  return runs.at((plant * compensators.size() + compensator) * scenarios + scenario);
}

namespace {

// The sweep's plants and its runs in order (plant, compensator, scenario), PI alone first on
// every plant; the verdicts are filled by the runs.
SweepResult sweep_layout(const SweepSpec& spec) {
  SweepResult result;
  result.plants = sample_plants(spec);
  result.compensators.push_back(CompensatorKind::kNone);
  for (CompensatorKind kind : spec.compensators) {
    if (kind != CompensatorKind::kNone) result.compensators.push_back(kind);
  }
  if (spec.identify_models) result.identified.resize(result.plants.size());
  const std::size_t per_plant = result.compensators.size() * spec.scenarios.size();
  result.runs.resize(result.plants.size() * per_plant);
  for (std::size_t i = 0; i < result.runs.size(); ++i) {
    result.runs[i].plant = i / per_plant;
    result.runs[i].compensator = (i % per_plant) / spec.scenarios.size();
    result.runs[i].scenario = i % spec.scenarios.size();
  }
  return result;
}

// Each run against PI alone on its plant and scenario: the cost ratio, and passed when clean and
// cheaper (PI alone passes by definition).
void compare_with_pi_alone(SweepResult& result, const VerdictParams& verdict) {
  for (SweepRun& run : result.runs) {
    const SweepRun& pi = result.run(run.plant, 0, run.scenario);
    judge_against_pi_alone(run.verdict, pi.verdict, verdict);
    run.cost_ratio_to_pi =
        pi.verdict.cost > 0 ? run.verdict.cost / pi.verdict.cost : std::numeric_limits<double>::quiet_NaN();
    const bool clean = run.verdict.faults().empty();
    run.passed = run.compensator == 0 || (clean && run.verdict.cost < pi.verdict.cost);
  }
}

}  // namespace

SweepResult run_sweep(const SystemParams& nominal, const SweepSpec& spec, const std::vector<double>& rnn_weights,
                      unsigned threads, const SweepProgress& progress) {
  spec.validate(nominal);
  SweepResult result = sweep_layout(spec);
  std::vector<SystemParams> variants;
  variants.reserve(result.plants.size());
  for (const PlantSample& plant : result.plants) variants.push_back(plant_variant(nominal, spec, plant));

  // Commissioning first (every plant's identification), then the runs: one pool, two phases.
  const std::size_t commissioning = spec.identify_models ? variants.size() : 0;
  const std::size_t jobs = commissioning + result.runs.size();
  std::atomic<std::size_t> next{0};
  std::size_t done = 0;
  std::size_t commissioned = 0;
  std::condition_variable all_commissioned;
  std::mutex progress_mutex;
  std::exception_ptr failure;
  const auto work = [&] {
    for (;;) {
      const std::size_t job = next.fetch_add(1);
      if (job >= jobs) return;
      if (job < commissioning) {
        try {
          result.identified[job] = commission_load(variants[job], spec.identification_scenario, spec.identification);
          variants[job] = with_identified_load(variants[job], result.identified[job]);
        } catch (const std::exception& e) {
          const std::lock_guard<std::mutex> lock(progress_mutex);
          if (!failure) {
            failure = std::make_exception_ptr(
                std::invalid_argument("plant '" + result.plants[job].label + "': identification: " + e.what()));
          }
          next = jobs;
        }
        const std::lock_guard<std::mutex> lock(progress_mutex);
        ++commissioned;
        all_commissioned.notify_all();
        continue;
      }
      if (commissioning > 0) {
        // A run needs its plant's identified models: wait until every commissioning job ended.
        std::unique_lock<std::mutex> lock(progress_mutex);
        all_commissioned.wait(lock, [&] { return commissioned == commissioning || failure; });
        if (failure) return;
      }
      SweepRun& run = result.runs[job - commissioning];
      try {
        const SystemParams& params = variants[run.plant];
        const Scenario& scenario = spec.scenarios[run.scenario];
        CompensatorSetup setup;
        setup.kind = result.compensators[run.compensator];
        if (setup.kind == CompensatorKind::kRnn) setup.rnn_weights = rnn_weights;
        run.verdict = judged_run(params, scenario, setup, spec.verdict);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(progress_mutex);
        if (!failure) failure = std::current_exception();
        next = jobs;
        all_commissioned.notify_all();
        return;
      }
      const std::lock_guard<std::mutex> lock(progress_mutex);
      ++done;
      if (progress) progress(done, result.runs.size());
    }
  };
  const unsigned count = threads != 0 ? threads : std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < count; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  compare_with_pi_alone(result, spec.verdict);
  return result;
}

}  // namespace pmlsm
