#include "pmlsm/analysis/identification.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "pmlsm/estimation/kalman_filter.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

constexpr const char* kLoadMassKey = "kalman.model.load_mass_kg";
constexpr const char* kSpringKey = "kalman.model.spring_n_per_m";
constexpr const char* kCoulombKey = "kalman.friction_input.coulomb_n";
constexpr const char* kViscousKey = "kalman.friction_input.viscous_n_s_per_m";
// Samples beyond the skipped start a fit needs: half a second at 1 ms, a few periods of the
// slowest load mode of interest.
constexpr std::size_t kMinJudgedSamples = 500;

/// One identified coordinate, searched as z = ln(value) in [lo, hi].
struct Coordinate {
  const char* key;
  double lo = 0, hi = 0;
};

class PredictionError {
 public:
  PredictionError(const SystemParams& configured, const std::vector<IdentificationSample>& samples, std::uint32_t skip)
      : configured_(configured), samples_(samples), skip_(skip) {}

  /// J / n for a parameter set with the given coordinate values (ln); +inf when the filter
  /// cannot be built or its innovations leave the numbers.
  double mean_square(const std::vector<Coordinate>& coords, const double* z) const {
    SystemParams p = configured_;
    for (std::size_t i = 0; i < coords.size(); ++i) real_parameter(p, coords[i].key) = std::exp(z[i]);
    return mean_square(p);
  }

  double mean_square(const SystemParams& p) const {
    try {
      // A model is judged by the innovations of the measurement update alone: the standstill hold
      // would skip them whenever the filter holds a swing, so J would jump with the model.
      KalmanParams filter_params = p.kalman_params();
      filter_params.standstill_hold.enabled = false;
      KalmanFilter filter(filter_params);
      double sum = 0;
      for (std::size_t k = 0; k < samples_.size(); ++k) {
        const IdentificationSample& s = samples_[k];
        const KalmanEstimate e = filter.step({s.motor_velocity_measured_mps, s.applied_force_n, s.encoder_position_m});
        if (k >= skip_) sum += e.innovation_mps * e.innovation_mps;
      }
      const double mean = sum / static_cast<double>(samples_.size() - skip_);
      return std::isfinite(mean) ? mean : std::numeric_limits<double>::infinity();
    } catch (const std::invalid_argument&) {
      return std::numeric_limits<double>::infinity();
    }
  }

 private:
  const SystemParams& configured_;
  const std::vector<IdentificationSample>& samples_;
  std::uint32_t skip_;
};

using Point = std::array<double, 4>;

/// Puts the first n vertices of a simplex in order of value, best first.
void sort_simplex_best_first(std::array<Point, 5>& v, std::array<double, 5>& fv, std::size_t n) {
  std::array<std::size_t, 5> order{0, 1, 2, 3, 4};
  // A stable insertion sort, as std::sort is on 5 elements (the same order on ties), written
  // out because GCC 12 cannot see that n <= 5 through std::sort (-Warray-bounds).
  for (std::size_t i = 1; i < n && i < order.size(); ++i) {
    const std::size_t key = order[i];
    std::size_t j = i;
    for (; j > 0 && fv[key] < fv[order[j - 1]]; --j) order[j] = order[j - 1];
    order[j] = key;
  }
  std::array<Point, 5> sv{};
  std::array<double, 5> sf{};
  for (std::size_t i = 0; i < n; ++i) {
    sv[i] = v[order[i]];
    sf[i] = fv[order[i]];
  }
  v = sv;
  fv = sf;
}

/// Nelder-Mead on the first `dims` coordinates, every vertex clamped into [lo, hi]; stops after
/// `budget` evaluations. Returns the best vertex and its value.
template <typename F>
std::pair<Point, double> nelder_mead(F&& f, std::size_t dims, const Point& start, const Point& step, const Point& lo,
                                     const Point& hi, std::uint32_t budget, std::uint32_t& used) {
  const auto clamp = [&](Point x) {
    for (std::size_t i = 0; i < dims; ++i) x[i] = std::clamp(x[i], lo[i], hi[i]);
    return x;
  };
  const auto eval = [&](const Point& x) {
    ++used;
    return f(x);
  };
  std::array<Point, 5> v{};
  std::array<double, 5> fv{};
  v[0] = clamp(start);
  fv[0] = eval(v[0]);
  for (std::size_t i = 0; i < dims; ++i) {
    v[i + 1] = v[0];
    // Step inward when the start sits on the upper edge.
    v[i + 1][i] = v[0][i] + step[i] <= hi[i] ? v[0][i] + step[i] : v[0][i] - step[i];
    v[i + 1] = clamp(v[i + 1]);
    fv[i + 1] = eval(v[i + 1]);
  }
  const std::size_t n = dims + 1;
  std::uint32_t spent = static_cast<std::uint32_t>(n);
  while (spent + n + 2 <= budget) {
    sort_simplex_best_first(v, fv, n);
    Point centroid{};
    for (std::size_t i = 0; i + 1 < n; ++i)
      for (std::size_t d = 0; d < dims; ++d) centroid[d] += v[i][d] / static_cast<double>(dims);
    const auto along = [&](double t) {
      Point x = centroid;
      for (std::size_t d = 0; d < dims; ++d) x[d] = centroid[d] + t * (v[n - 1][d] - centroid[d]);
      return clamp(x);
    };
    const Point reflected = along(-1.0);
    const double fr = eval(reflected);
    ++spent;
    if (fr < fv[0]) {
      const Point expanded = along(-2.0);
      const double fe = eval(expanded);
      ++spent;
      if (fe < fr) {
        v[n - 1] = expanded;
        fv[n - 1] = fe;
      } else {
        v[n - 1] = reflected;
        fv[n - 1] = fr;
      }
    } else if (fr < fv[n - 2]) {
      v[n - 1] = reflected;
      fv[n - 1] = fr;
    } else {
      const Point contracted = fr < fv[n - 1] ? along(-0.5) : along(0.5);
      const double fc = eval(contracted);
      ++spent;
      if (fc < std::min(fr, fv[n - 1])) {
        v[n - 1] = contracted;
        fv[n - 1] = fc;
      } else {
        for (std::size_t i = 1; i < n; ++i) {
          for (std::size_t d = 0; d < dims; ++d) v[i][d] = v[0][d] + 0.5 * (v[i][d] - v[0][d]);
          fv[i] = eval(v[i]);
          ++spent;
        }
      }
    }
  }
  std::size_t best = 0;
  for (std::size_t i = 1; i < n; ++i)
    if (fv[i] < fv[best]) best = i;
  return {v[best], fv[best]};
}

/// The search space: log-coordinates of the fitted parameters, each within range_ratio of the
/// configured value and inside its plausible range.
struct SearchBox {
  std::vector<Coordinate> coords;
  Point lo{}, hi{}, start{}, step{};
  double span = 0;  ///< log(range_ratio)
};

SearchBox search_box(const SystemParams& configured, const IdentificationParams& params) {
  SearchBox box;
  // The load always, the friction when the filter models it (and has some to scale).
  std::vector<const char*> keys{kLoadMassKey, kSpringKey};
  if (configured.kalman.friction_input.enabled) {
    if (configured.kalman.friction_input.model.coulomb_n > 0) keys.push_back(kCoulombKey);
    if (configured.kalman.friction_input.model.viscous_n_s_per_m > 0) keys.push_back(kViscousKey);
  }
  box.span = std::log(params.range_ratio);
  for (const char* key : keys) {
    SystemParams probe = configured;
    Plausible range{0, 0, ""};
    const double value = real_parameter(probe, key, &range);
    Coordinate c{key, std::log(value) - box.span, std::log(value) + box.span};
    if (range.min > 0) c.lo = std::max(c.lo, std::log(range.min));
    c.hi = std::min(c.hi, std::log(range.max));
    const std::size_t i = box.coords.size();
    box.lo[i] = c.lo;
    box.hi[i] = c.hi;
    box.start[i] = std::clamp(std::log(value), c.lo, c.hi);
    box.step[i] = 0.25 * box.span;
    box.coords.push_back(c);
  }
  return box;
}

void check_identification_samples(const std::vector<IdentificationSample>& samples,
                                  const IdentificationParams& params) {
  if (samples.size() < params.skip_samples + kMinJudgedSamples) {
    throw std::invalid_argument("samples: need at least " + std::to_string(params.skip_samples + kMinJudgedSamples) +
                                " (" + std::to_string(params.skip_samples) + " skipped + " +
                                std::to_string(kMinJudgedSamples) + "), got " + std::to_string(samples.size()));
  }
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const IdentificationSample& s = samples[i];
    if (std::isfinite(s.motor_velocity_measured_mps) && std::isfinite(s.encoder_position_m) &&
        std::isfinite(s.applied_force_n)) {
      continue;
    }
    const std::string at = "samples[" + std::to_string(i) + "].";
    require_finite((at + "motor_velocity_measured_mps").c_str(), s.motor_velocity_measured_mps);
    require_finite((at + "encoder_position_m").c_str(), s.encoder_position_m);
    require_finite((at + "applied_force_n").c_str(), s.applied_force_n);
  }
}

constexpr std::size_t kLoadDims = 2;  ///< load mass and spring come first in a SearchBox

/// The friction coordinates fitted on the configured load (the box's start), a tenth of the
/// budget spent: a wrong Coulomb force dominates the innovations wherever the motor turns, and
/// hides the load's valley (a plant with 30 N against the model's 20 N showed no minimum near its
/// load at all). Returns the start with the fitted friction.
template <typename F>
Point fit_friction_first(F&& f, const SearchBox& box, std::uint32_t budget, std::uint32_t& evaluations) {
  Point friction = box.start;
  const std::size_t dims = box.coords.size();
  if (dims <= kLoadDims) return friction;
  const std::size_t friction_dims = dims - kLoadDims;
  Point f_start{}, f_step{}, f_lo{}, f_hi{};
  for (std::size_t i = 0; i < friction_dims; ++i) {
    f_start[i] = box.start[kLoadDims + i];
    f_step[i] = box.step[kLoadDims + i];
    f_lo[i] = box.lo[kLoadDims + i];
    f_hi[i] = box.hi[kLoadDims + i];
  }
  const auto f_friction = [&](const Point& x) {
    Point z = box.start;
    for (std::size_t i = 0; i < friction_dims; ++i) z[kLoadDims + i] = x[i];
    return f(z);
  };
  std::uint32_t used = 0;
  const Point fitted = nelder_mead(f_friction, friction_dims, f_start, f_step, f_lo, f_hi, budget, used).first;
  evaluations += used;
  for (std::size_t i = 0; i < friction_dims; ++i) friction[kLoadDims + i] = fitted[i];
  return friction;
}

struct Candidate {
  Point z;
  double value;
};

/// A 5 x 5 grid over load mass and spring (half a span apart) with the given friction, best first:
/// where the valleys are.
template <typename F>
std::vector<Candidate> load_grid_best_first(F&& f, const SearchBox& box, const Point& friction,
                                            std::uint32_t& evaluations) {
  std::vector<Candidate> grid;
  for (int a = -2; a <= 2; ++a) {
    for (int b = -2; b <= 2; ++b) {
      Point z = friction;
      z[0] = std::clamp(box.start[0] + 0.5 * a * box.span, box.lo[0], box.hi[0]);
      z[1] = std::clamp(box.start[1] + 0.5 * b * box.span, box.lo[1], box.hi[1]);
      grid.push_back({z, f(z)});
      ++evaluations;
    }
  }
  std::sort(grid.begin(), grid.end(), [](const Candidate& x, const Candidate& y) { return x.value < y.value; });
  return grid;
}

}  // namespace

void IdentificationParams::validate() const {
  require_finite("range_ratio", range_ratio);
  if (!(range_ratio > 1.0 && range_ratio <= 100.0)) {
    throw std::invalid_argument("range_ratio: must be in (1, 100], got " + format_value(range_ratio));
  }
  if (max_evaluations < 100 || max_evaluations > 1000000) {
    throw std::invalid_argument("max_evaluations: must be 100 to 1000000, got " + std::to_string(max_evaluations));
  }
}

double IdentifiedLoad::load_mode_hz() const { return std::sqrt(spring_n_per_m / load_mass_kg) / (2.0 * M_PI); }

IdentifiedLoad identify_load(const SystemParams& configured, const std::vector<IdentificationSample>& samples,
                             const IdentificationParams& params) {
  params.validate();
  configured.validate();
  check_identification_samples(samples, params);
  const SearchBox box = search_box(configured, params);
  const std::size_t dims = box.coords.size();
  const std::vector<Coordinate>& coords = box.coords;
  const Point& lo = box.lo;
  const Point& hi = box.hi;

  const PredictionError error(configured, samples, params.skip_samples);
  IdentifiedLoad out;
  const auto f = [&](const Point& z) { return error.mean_square(coords, z.data()); };
  out.configured_innovation_rms_mps = std::sqrt(error.mean_square(configured));
  const Point friction = fit_friction_first(f, box, params.max_evaluations / 10, out.evaluations);
  const std::vector<Candidate> grid = load_grid_best_first(f, box, friction, out.evaluations);

  // Nelder-Mead from the three best grid points, the budget shared.
  constexpr std::size_t kStarts = 3;
  const std::uint32_t per_start = (params.max_evaluations - out.evaluations) / kStarts;
  Candidate best = grid.front();
  for (std::size_t s = 0; s < kStarts; ++s) {
    std::uint32_t used = 0;
    const auto [z, value] = nelder_mead(f, dims, grid[s].z, box.step, lo, hi, per_start, used);
    out.evaluations += used;
    if (value < best.value) best = {z, value};
  }

  SystemParams identified = configured;
  for (std::size_t i = 0; i < dims; ++i) real_parameter(identified, coords[i].key) = std::exp(best.z[i]);
  out.load_mass_kg = identified.kalman.model.load_mass_kg;
  out.spring_n_per_m = identified.kalman.model.spring_n_per_m;
  out.coulomb_n = identified.kalman.friction_input.model.coulomb_n;
  out.viscous_n_s_per_m = identified.kalman.friction_input.model.viscous_n_s_per_m;
  out.innovation_rms_mps = std::sqrt(best.value);
  for (std::size_t i = 0; i < dims; ++i) {
    const double margin = 0.01 * (hi[i] - lo[i]);
    if (best.z[i] - lo[i] < margin || hi[i] - best.z[i] < margin) {
      out.at_bound += (out.at_bound.empty() ? "" : ", ") + std::string(coords[i].key);
    }
  }
  return out;
}

std::vector<std::pair<std::string, double>> identified_parameters(const IdentifiedLoad& load) {
  return {{kLoadMassKey, load.load_mass_kg},
          {kSpringKey, load.spring_n_per_m},
          {kCoulombKey, load.coulomb_n},
          {kViscousKey, load.viscous_n_s_per_m},
          {"compensator.state_feedback.model.load_mass_kg", load.load_mass_kg},
          {"compensator.state_feedback.model.spring_n_per_m", load.spring_n_per_m},
          {"compensator.state_feedback.friction_feedforward.coulomb_n", load.coulomb_n},
          {"compensator.state_feedback.friction_feedforward.viscous_n_s_per_m", load.viscous_n_s_per_m}};
}

SystemParams with_identified_load(const SystemParams& configured, const IdentifiedLoad& load) {
  SystemParams p = configured;
  for (const auto& [key, value] : identified_parameters(load)) real_parameter(p, key) = value;
  p.validate();
  return p;
}

std::vector<IdentificationSample> identification_samples(const std::vector<TickRecord>& trace) {
  std::vector<IdentificationSample> samples;
  samples.reserve(trace.size());
  for (const TickRecord& r : trace)
    samples.push_back({r.motor_velocity_measured_mps, r.encoder_position_m, r.applied_force_n});
  return samples;
}

IdentifiedLoad commission_load(const SystemParams& on_plant, const Scenario& identification,
                               const IdentificationParams& params) {
  return identify_load(on_plant, identification_samples(run_scenario(on_plant, identification)), params);
}

}  // namespace pmlsm
