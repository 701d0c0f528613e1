#include "pmlsm/analysis/loop_tuning.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

constexpr double kDegreesPerRadian = 57.295779513082320876;
constexpr double kRadiansPerTurn = 6.283185307179586477;
/// A phase step between two lines smaller than this is a resolved crossing, not a mode's jump.
constexpr double kResolvedStepDeg = 90.0;

struct LoopLine {
  double log_f = 0;
  double log_mag = 0;    ///< ln |L|
  double phase_deg = 0;  ///< unwrapped along the lines
};

std::vector<LoopLine> loop_lines(const std::vector<FrequencyPoint>& points, double gain_scale, double min_coherence,
                                 const FilterChain* filters) {
  std::vector<LoopLine> lines;
  lines.reserve(points.size());
  for (const FrequencyPoint& p : points) {
    const std::complex<double> l = gain_scale * p.open_loop() *
                                   (filters != nullptr ? filters->response(p.frequency_hz) : std::complex<double>(1.0));
    if (p.coherence < min_coherence || !std::isfinite(std::abs(l)) || std::abs(l) == 0) continue;
    double phase = std::arg(l) * kDegreesPerRadian;
    if (!lines.empty()) phase += 360.0 * std::round((lines.back().phase_deg - phase) / 360.0);
    lines.push_back({std::log(p.frequency_hz), std::log(std::abs(l)), phase});
  }
  return lines;
}

double between(double a, double b, double t) { return a + (b - a) * t; }

/// Both crossovers read and both margins at least the targets plus their allowances.
bool meets_with_allowances(const LoopMargins& m, const TuningTargets& targets) {
  return m.gain_crossover_found && m.phase_crossover_found &&
         m.phase_margin_deg >= targets.min_phase_margin_deg + targets.phase_allowance_deg &&
         m.gain_margin_db >= targets.min_gain_margin_db + targets.gain_allowance_db;
}

}  // namespace

LoopMargins loop_margins(const std::vector<FrequencyPoint>& points, double gain_scale, double min_coherence,
                         const FilterChain* filters) {
  const std::vector<LoopLine> lines = loop_lines(points, gain_scale, min_coherence, filters);
  LoopMargins m;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const LoopLine& a = lines[i - 1];
    const LoopLine& b = lines[i];
    // Gain crossover: ln |L| through 0.
    if ((a.log_mag > 0) != (b.log_mag > 0)) {
      const double t = a.log_mag / (a.log_mag - b.log_mag);
      const double phase = between(a.phase_deg, b.phase_deg, t);
      const double margin = 180.0 + (phase - 360.0 * std::floor((phase + 180.0) / 360.0));
      if (!m.gain_crossover_found || margin < m.phase_margin_deg) {
        m.phase_margin_deg = margin;
        m.gain_crossover_hz = std::exp(between(a.log_f, b.log_f, t));
      }
      m.gain_crossover_found = true;
    }
    // Phase crossover: the phase through -180 + 360 k.
    const double ka = std::floor((a.phase_deg + 180.0) / 360.0), kb = std::floor((b.phase_deg + 180.0) / 360.0);
    // The phase of a lightly damped mode can turn half a turn between two lines, where
    // unwrapping cannot tell its direction; such a "crossing" has |L| >> 1 and is no gain margin
    // (at those frequencies the sampling's delay is a few degrees). A crossing the lines resolve
    // (the phase moved less than kResolvedStepDeg between them) is one whatever |L|: with
    // |L| > 1 its margin is negative, the loop unstable (or stable only for more gain).
    if (ka != kb) {
      const double crossing = 360.0 * std::max(ka, kb) - 180.0;
      const double t = (crossing - a.phase_deg) / (b.phase_deg - a.phase_deg);
      const double margin_db = -20.0 / std::log(10.0) * between(a.log_mag, b.log_mag, t);
      const bool resolved = std::abs(b.phase_deg - a.phase_deg) < kResolvedStepDeg;
      if ((margin_db > 0 || resolved) && (!m.phase_crossover_found || margin_db < m.gain_margin_db)) {
        m.gain_margin_db = margin_db;
        m.phase_crossover_hz = std::exp(between(a.log_f, b.log_f, t));
        m.phase_crossover_found = true;
      }
    }
  }
  return m;
}

void TuningTargets::validate() const { check_declared_ranges(*this); }

std::optional<TunedGains> tune_velocity_pi(const std::vector<FrequencyPoint>& points, double kp_n_s_per_m,
                                           double ki_n_per_m, const TuningTargets& targets, double min_coherence,
                                           std::string& why, const FilterChain* filters) {
  targets.validate();
  TunedGains tuned;
  tuned.before = loop_margins(points, 1.0, min_coherence, filters);
  bool found = false;
  // From the largest scale down: the first that meets both targets.
  const double steps = std::ceil(2.0 * std::log(targets.max_gain_scale) / std::log(1.01));
  for (double i = 0; i <= steps && !found; ++i) {
    const double scale = targets.max_gain_scale * std::pow(1.01, -i);
    const LoopMargins m = loop_margins(points, scale, min_coherence, filters);
    if (meets_with_allowances(m, targets)) {
      tuned.gain_scale = scale;
      tuned.after = m;
      found = true;
    }
  }
  if (!found) {
    why = "no gain within x/" + format_value(targets.max_gain_scale) + " of the measured one gives a phase margin of " +
          format_value(targets.min_phase_margin_deg + targets.phase_allowance_deg) + " deg and a gain margin of " +
          format_value(targets.min_gain_margin_db + targets.gain_allowance_db) +
          " dB (the targets and their allowances) with both crossovers in the measured band";
    return std::nullopt;
  }
  tuned.kp_n_s_per_m = kp_n_s_per_m * tuned.gain_scale;
  tuned.ki_n_per_m = ki_n_per_m * tuned.gain_scale;
  return tuned;
}

std::vector<FrequencyPoint> position_loop_points(const std::vector<FrequencyPoint>& points,
                                                 const std::vector<LoadRatioPoint>& load_points,
                                                 PositionFeedback closes_on, double period_s,
                                                 double velocity_gain_scale, const FilterChain* filters) {
  std::vector<FrequencyPoint> out;
  if (closes_on == PositionFeedback::kNone) return out;
  out.reserve(points.size());
  std::size_t next_load = 0;
  for (const FrequencyPoint& p : points) {
    std::complex<double> q = 1.0;
    double coherence = p.coherence;
    if (closes_on == PositionFeedback::kLoad) {
      while (next_load < load_points.size() && load_points[next_load].frequency_hz < p.frequency_hz * (1 - 1e-9)) {
        ++next_load;
      }
      if (next_load == load_points.size() || load_points[next_load].frequency_hz > p.frequency_hz * (1 + 1e-9)) {
        continue;
      }
      q = load_points[next_load].ratio;
      coherence = std::min(coherence, load_points[next_load].coherence);
    }
    const std::complex<double> l = velocity_gain_scale * p.open_loop() *
                                   (filters != nullptr ? filters->response(p.frequency_hz) : std::complex<double>(1.0));
    const std::complex<double> z_inv = std::polar(1.0, -kRadiansPerTurn * p.frequency_hz * period_s);
    const std::complex<double> l_x = l / (1.0 + l) * q * period_s / (1.0 - z_inv);
    FrequencyPoint x;
    x.frequency_hz = p.frequency_hz;
    x.plant = p.plant;
    x.sensitivity = 1.0 / (1.0 + l_x);
    x.coherence = coherence;
    out.push_back(x);
  }
  return out;
}

LoopMargins position_loop_margins(const std::vector<FrequencyPoint>& position_points, double gain_per_s,
                                  double min_coherence) {
  LoopMargins m = loop_margins(position_points, gain_per_s, min_coherence);
  if (m.gain_crossover_found) return m;
  for (const FrequencyPoint& p : position_points) {
    if (p.coherence < min_coherence) continue;
    const std::complex<double> l = gain_per_s * p.open_loop();
    if (std::abs(l) < 1.0) {
      const double phase_deg = std::arg(l) * kDegreesPerRadian;
      m.gain_crossover_found = true;
      m.gain_crossover_hz = gain_per_s / kRadiansPerTurn;
      m.phase_margin_deg = 180.0 + phase_deg;
    }
    break;
  }
  return m;
}

std::optional<std::pair<double, LoopMargins>> tune_position_gain(const std::vector<FrequencyPoint>& position_points,
                                                                 const TuningTargets& targets, double min_coherence,
                                                                 std::string& why) {
  targets.validate();
  constexpr double kMostPerS = 1000.0, kLeastPerS = 0.01;
  const double steps = std::ceil(std::log(kMostPerS / kLeastPerS) / std::log(1.01));
  for (double i = 0; i <= steps; ++i) {
    const double gain = kMostPerS * std::pow(1.01, -i);
    const LoopMargins m = position_loop_margins(position_points, gain, min_coherence);
    if (meets_with_allowances(m, targets)) return std::make_pair(gain, m);
  }
  why = "no position gain from " + format_value(kLeastPerS) + " to " + format_value(kMostPerS) +
        " 1/s gives a phase margin of " + format_value(targets.min_phase_margin_deg + targets.phase_allowance_deg) +
        " deg and a gain margin of " + format_value(targets.min_gain_margin_db + targets.gain_allowance_db) +
        " dB with its phase crossover in the measured band";
  return std::nullopt;
}

std::optional<GainChoice> choose_gain_factor(const std::vector<GainTrial>& trials) {
  for (std::size_t f = 0; f < trials.size(); ++f) {
    if (!(trials[f].factor > 0) || (f > 0 && !(trials[f].factor > trials[f - 1].factor))) {
      throw std::invalid_argument("gain trial factors must be positive and ascending, got " +
                                  format_value(trials[f].factor) + " at position " + std::to_string(f + 1));
    }
  }
  const auto cheapest = [&](bool with_step) {
    std::optional<std::size_t> best;
    for (std::size_t f = 0; f < trials.size(); ++f) {
      const bool step = f + 1 < trials.size() && trials[f + 1].passes;
      if (!trials[f].passes || (with_step && !step)) continue;
      if (!best || trials[f].mean_cost_ratio < trials[*best].mean_cost_ratio) best = f;
    }
    return best;
  };
  if (const auto f = cheapest(true)) return GainChoice{trials[*f].factor, true};
  if (const auto f = cheapest(false)) return GainChoice{trials[*f].factor, false};
  return std::nullopt;
}

}  // namespace pmlsm
