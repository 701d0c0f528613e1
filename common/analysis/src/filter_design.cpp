#include "pmlsm/analysis/filter_design.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

/// A coherent line above the search band: its frequency and 20 log10 |G / G_fit|.
struct RatioLine {
  double log_f = 0;
  double db = 0;
};

std::vector<RatioLine> ratio_lines(const std::vector<FrequencyPoint>& points, const TwoMassFit& fit,
                                   double min_coherence, double min_frequency_hz) {
  std::vector<RatioLine> lines;
  for (const FrequencyPoint& p : points) {
    if (p.frequency_hz <= min_frequency_hz || p.coherence < min_coherence) continue;
    const double ratio = std::abs(p.plant / two_mass_response(fit, p.frequency_hz));
    if (!std::isfinite(ratio) || ratio <= 0) continue;
    lines.push_back({std::log(p.frequency_hz), 20.0 * std::log10(ratio)});
  }
  return lines;
}

/// Where the lines from `peak` towards `step` (-1, +1) first fall below `level`, in log f (the
/// stretch's last line when they do not), and the lowest value before a higher line than the peak.
struct Side {
  double crossing_log_f = 0;
  double lowest_db = 0;
};

Side walk(const std::vector<RatioLine>& lines, std::size_t peak, int step, double level) {
  Side side{lines[peak].log_f, lines[peak].db};
  bool crossed = false;
  for (std::size_t i = peak;;) {
    if ((step < 0 && i == 0) || (step > 0 && i + 1 == lines.size())) break;
    const std::size_t next = step < 0 ? i - 1 : i + 1;
    if (lines[next].db > lines[peak].db) break;
    if (!crossed && lines[next].db < level) {
      const double t = (lines[i].db - level) / (lines[i].db - lines[next].db);
      side.crossing_log_f = lines[i].log_f + t * (lines[next].log_f - lines[i].log_f);
      crossed = true;
    }
    side.lowest_db = std::min(side.lowest_db, lines[next].db);
    if (!crossed) side.crossing_log_f = lines[next].log_f;
    i = next;
  }
  return side;
}

/// The gain scale the tuner allows with `chain` in the loop (0: none).
double tunable_scale(const std::vector<FrequencyPoint>& points, const TuningTargets& targets, double min_coherence,
                     const FilterChainParams& chain) {
  const FilterChain filters(chain);
  std::string why;
  const std::optional<TunedGains> tuned = tune_velocity_pi(points, 1.0, 1.0, targets, min_coherence, why, &filters);
  return tuned ? tuned->gain_scale : 0.0;
}

}  // namespace

void FilterDesignParams::validate() const { check_declared_ranges(*this); }

std::vector<ResonancePeak> resonance_peaks(const std::vector<FrequencyPoint>& points, const TwoMassFit& fit,
                                           double min_coherence, double period_s, const FilterDesignParams& params) {
  params.validate();
  require_in_range("period_s", period_s, 1e-6, 1.0);
  const std::vector<RatioLine> lines = ratio_lines(points, fit, min_coherence, params.min_frequency_hz);
  std::vector<ResonancePeak> peaks;
  // A peak needs a line either side: one at the band's edge cannot be told from a slope.
  for (std::size_t i = 1; i + 1 < lines.size(); ++i) {
    const RatioLine &a = lines[i - 1], &b = lines[i], &c = lines[i + 1];
    if (!(b.db > a.db && b.db >= c.db)) continue;
    // The parabola through the three lines (in log f, at their mean spacing h): its vertex.
    const double h = 0.5 * (c.log_f - a.log_f), curvature = a.db - 2.0 * b.db + c.db;
    const double offset = curvature < 0 ? std::clamp(0.5 * (a.db - c.db) / curvature, -0.5, 0.5) : 0.0;
    const double top_db = b.db - 0.25 * (a.db - c.db) * offset;
    const double half_power_db = top_db - 10.0 * std::log10(2.0);
    const Side left = walk(lines, i, -1, half_power_db), right = walk(lines, i, +1, half_power_db);
    const double height_db = top_db - std::max(left.lowest_db, right.lowest_db);
    const double centre_hz = std::exp(b.log_f + offset * h);
    if (height_db < params.min_peak_db || centre_hz >= 0.45 / period_s) continue;  // no notch above 0.45 f_s
    ResonancePeak peak;
    peak.frequency_hz = centre_hz;
    peak.height_db = height_db;
    // At least the lines' spacing: a mode narrower than it is not resolved, and its peak is lower
    // than measured; the wider notch is the safe side.
    peak.width_hz =
        std::max(std::exp(right.crossing_log_f) - std::exp(left.crossing_log_f), std::exp(c.log_f) - std::exp(b.log_f));
    const double zeros_damping = std::clamp(peak.width_hz / (2.0 * peak.frequency_hz), 1e-3, 1.0);
    peak.notch.kind = FilterKind::kNotch;
    peak.notch.frequency_hz = peak.frequency_hz;
    peak.notch.damping = zeros_damping;
    peak.notch.second_damping = std::min(zeros_damping * std::pow(10.0, height_db / 20.0), 10.0);
    peak.notch.period_s = period_s;
    peaks.push_back(peak);
  }
  std::sort(peaks.begin(), peaks.end(),
            [](const ResonancePeak& x, const ResonancePeak& y) { return x.height_db > y.height_db; });
  return peaks;
}

FilterDesign design_notches(const std::vector<FrequencyPoint>& points, const TwoMassFit& fit,
                            const FilterChainParams& configured, const TuningTargets& targets, double min_coherence,
                            double period_s, const FilterDesignParams& params) {
  targets.validate();
  FilterDesign design;
  design.chain = configured;
  design.peaks = resonance_peaks(points, fit, min_coherence, period_s, params);
  double scale = tunable_scale(points, targets, min_coherence, design.chain);
  for (ResonancePeak& peak : design.peaks) {
    const auto free_slot = std::find_if(design.chain.slots.begin(), design.chain.slots.end(),
                                        [](const BiquadParams& s) { return s.kind == FilterKind::kNone; });
    peak.gain_scale_before = scale;
    peak.slot_free = free_slot != design.chain.slots.end();
    if (!peak.slot_free) continue;
    // The notch as found is the peak's inverse at the lines; the mode between them and the
    // phase the notch costs below it are not in that: centre, width (its poles' damping) and
    // depth are searched around it, each trial judged by the gain the tuner then allows.
    const BiquadParams found = peak.notch;
    FilterChainParams best_chain = design.chain;
    for (const double shift : {1.0, 0.97, 1.03}) {
      for (const double widen : {1.0, 0.5, 2.0, 4.0}) {
        for (const double deepen_db : {0.0, -6.0, 6.0}) {
          const double depth_db = peak.height_db + deepen_db;
          if (depth_db <= 0.0) continue;  // no notch left (a low peak made shallower)
          BiquadParams notch = found;
          notch.frequency_hz = found.frequency_hz * shift;
          if (notch.frequency_hz >= 0.45 / period_s) continue;
          notch.second_damping = std::min(found.second_damping * widen, 10.0);
          notch.damping = notch.second_damping * std::pow(10.0, -depth_db / 20.0);
          FilterChainParams trial = design.chain;
          trial.slots[static_cast<std::size_t>(free_slot - design.chain.slots.begin())] = notch;
          const double with = tunable_scale(points, targets, min_coherence, trial);
          if (with > peak.gain_scale_with) {
            peak.gain_scale_with = with;
            peak.notch = notch;
            best_chain = trial;
          }
        }
      }
    }
    peak.placed = scale == 0.0 ? peak.gain_scale_with > 0.0 : peak.gain_scale_with >= scale * params.min_gain_increase;
    if (!peak.placed) continue;
    design.chain = best_chain;
    scale = peak.gain_scale_with;
    ++design.placed;
  }
  return design;
}

}  // namespace pmlsm
