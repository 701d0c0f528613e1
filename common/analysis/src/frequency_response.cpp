#include "pmlsm/analysis/frequency_response.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kSkIterations = 12;

using Complex = std::complex<double>;

/// The whole periods of n ticks in `samples`, at least settle_periods + 2.
/// @throws std::invalid_argument saying how many there are and how many are needed.
std::size_t whole_periods(std::size_t samples, std::size_t n, std::size_t settle_periods) {
  const std::size_t periods = samples / n;
  if (periods < settle_periods + 2) {
    throw std::invalid_argument("samples: " + std::to_string(samples) + " ticks hold " + std::to_string(periods) +
                                " periods of " + std::to_string(n) + "; need " + std::to_string(settle_periods) +
                                " to settle and 2 to average");
  }
  return periods;
}

/// e^{-j 2 pi m / n}, m = 0 .. n - 1: a period's DFT.
std::vector<Complex> twiddles(std::size_t n) {
  std::vector<Complex> table(n);
  for (std::size_t m = 0; m < n; ++m) table[m] = std::polar(1.0, -2.0 * kPi * static_cast<double>(m) / n);
  return table;
}

}  // namespace

void MultisineParams::validate() const {
  require_in_range("period_s", period_s, 1e-6, 1.0);
  require_in_range("amplitude_n", amplitude_n, 1e-6, 1e5);
  require_positive("min_frequency_hz", min_frequency_hz);
  const double nyquist_hz = 0.5 / period_s;
  if (!(max_frequency_hz > min_frequency_hz && max_frequency_hz < nyquist_hz)) {
    throw std::invalid_argument("max_frequency_hz: must lie above min_frequency_hz (" + format_value(min_frequency_hz) +
                                ") and below the Nyquist frequency " + format_value(nyquist_hz) + ", got " +
                                format_value(max_frequency_hz));
  }
  // A period of at most 100 s, with a line between the band's ends.
  require_in_range("resolution_hz", resolution_hz, 0.01, max_frequency_hz - min_frequency_hz);
  if (dense_max_frequency_hz != 0.0) {
    require_in_range("dense_max_frequency_hz", dense_max_frequency_hz, min_frequency_hz, max_frequency_hz);
    require_in_range("lines_per_decade", lines_per_decade, 1.0, 1000.0);
  }
}

Multisine::Multisine(const MultisineParams& params) : params_(params) {
  params_.validate();
  const auto n = static_cast<std::size_t>(std::llround(1.0 / (params_.resolution_hz * params_.period_s)));
  params_.resolution_hz = 1.0 / (static_cast<double>(n) * params_.period_s);  // whole ticks per period
  const double dense_max_hz =
      params_.dense_max_frequency_hz != 0.0 ? params_.dense_max_frequency_hz : params_.max_frequency_hz;
  const double step = std::pow(10.0, 1.0 / std::max(params_.lines_per_decade, 1.0));
  for (auto k = static_cast<std::size_t>(std::ceil(params_.min_frequency_hz / params_.resolution_hz - 1e-9));
       static_cast<double>(k) * params_.resolution_hz <= params_.max_frequency_hz + 1e-9;) {
    lines_.push_back(k);
    const double f = static_cast<double>(k) * params_.resolution_hz;
    // Log spacing above the dense band: the next line at f 10^(1/lines_per_decade), on the grid.
    k = f < dense_max_hz - 1e-9
            ? k + 1
            : std::max(k + 1, static_cast<std::size_t>(std::llround(f * step / params_.resolution_hz)));
  }
  if (lines_.empty()) throw std::invalid_argument("resolution_hz: no line between min and max frequency");
  // Schroeder phases: phi_i = -pi i (i - 1) / K keep the sum's peak near sqrt(2 K) of a line's.
  table_.assign(n, 0.0);
  const double count = static_cast<double>(lines_.size());
  for (std::size_t i = 0; i < lines_.size(); ++i) {
    const double phase = -kPi * static_cast<double>(i + 1) * static_cast<double>(i) / count;
    for (std::size_t t = 0; t < n; ++t) {
      const double turns = static_cast<double>((lines_[i] * t) % n) / static_cast<double>(n);
      table_[t] += std::cos(2.0 * kPi * turns + phase);
    }
  }
  double peak = 0;
  for (const double x : table_) peak = std::max(peak, std::fabs(x));
  for (double& x : table_) x *= params_.amplitude_n / peak;
}

std::vector<FrequencyPoint> estimate_frequency_response(const Multisine& excitation,
                                                        const std::vector<double>& excitation_n,
                                                        const std::vector<double>& force_n,
                                                        const std::vector<double>& velocity_mps,
                                                        std::size_t settle_periods) {
  const std::size_t n = excitation.ticks_per_period();
  if (excitation_n.size() != force_n.size() || force_n.size() != velocity_mps.size()) {
    throw std::invalid_argument("samples: excitation, force and velocity differ in length (" +
                                std::to_string(excitation_n.size()) + ", " + std::to_string(force_n.size()) + ", " +
                                std::to_string(velocity_mps.size()) + ")");
  }
  const std::size_t periods = whole_periods(excitation_n.size(), n, settle_periods);
  for (std::size_t i = 0; i < force_n.size(); ++i) {
    if (!std::isfinite(excitation_n[i]) || !std::isfinite(force_n[i]) || !std::isfinite(velocity_mps[i])) {
      throw std::invalid_argument("samples: a non-finite value at tick " + std::to_string(i));
    }
  }
  const std::vector<Complex> twiddle = twiddles(n);
  std::vector<FrequencyPoint> out;
  for (const std::size_t k : excitation.lines()) {
    Complex sum_r, sum_f, sum_v, cross_vr;
    double power_v = 0, power_r = 0;
    for (std::size_t p = settle_periods; p < periods; ++p) {
      Complex r, f, v;
      const std::size_t start = p * n;
      for (std::size_t t = 0; t < n; ++t) {
        const Complex w = twiddle[(k * t) % n];
        r += excitation_n[start + t] * w;
        f += force_n[start + t] * w;
        v += velocity_mps[start + t] * w;
      }
      sum_r += r;
      sum_f += f;
      sum_v += v;
      cross_vr += v * std::conj(r);
      power_v += std::norm(v);
      power_r += std::norm(r);
    }
    FrequencyPoint point;
    point.frequency_hz = static_cast<double>(k) * excitation.resolution_hz();
    point.plant = sum_v / sum_f;
    point.sensitivity = sum_f / sum_r;
    point.coherence = power_v > 0 && power_r > 0 ? std::norm(cross_vr) / (power_v * power_r) : 0.0;
    out.push_back(point);
  }
  return out;
}

std::vector<LoadRatioPoint> estimate_load_ratio(const Multisine& excitation, const std::vector<double>& velocity_mps,
                                                const std::vector<double>& load_velocity_mps,
                                                std::size_t settle_periods) {
  const std::size_t n = excitation.ticks_per_period();
  if (velocity_mps.size() != load_velocity_mps.size()) {
    throw std::invalid_argument("samples: the motor's and the load's velocity differ in length (" +
                                std::to_string(velocity_mps.size()) + ", " + std::to_string(load_velocity_mps.size()) +
                                ")");
  }
  const std::size_t periods = whole_periods(velocity_mps.size(), n, settle_periods);
  for (std::size_t i = 0; i < velocity_mps.size(); ++i) {
    if (!std::isfinite(velocity_mps[i]) || !std::isfinite(load_velocity_mps[i])) {
      throw std::invalid_argument("samples: a non-finite value at tick " + std::to_string(i));
    }
  }
  const std::vector<Complex> twiddle = twiddles(n);
  std::vector<LoadRatioPoint> out;
  for (const std::size_t k : excitation.lines()) {
    Complex sum_m, sum_l, cross;
    double power_m = 0, power_l = 0;
    for (std::size_t p = settle_periods; p < periods; ++p) {
      Complex vm, vl;
      const std::size_t start = p * n;
      for (std::size_t t = 0; t < n; ++t) {
        const Complex w = twiddle[(k * t) % n];
        vm += velocity_mps[start + t] * w;
        vl += load_velocity_mps[start + t] * w;
      }
      sum_m += vm;
      sum_l += vl;
      cross += vl * std::conj(vm);
      power_m += std::norm(vm);
      power_l += std::norm(vl);
    }
    LoadRatioPoint point;
    point.frequency_hz = static_cast<double>(k) * excitation.resolution_hz();
    point.ratio = sum_l / sum_m;
    point.coherence = power_m > 0 && power_l > 0 ? std::norm(cross) / (power_m * power_l) : 0.0;
    out.push_back(point);
  }
  return out;
}

LoadSideFit fit_load_side(const std::vector<LoadRatioPoint>& load, const std::vector<FrequencyPoint>& motor,
                          double min_coherence, double max_frequency_hz) {
  if (load.size() != motor.size()) {
    throw std::invalid_argument("load side: " + std::to_string(load.size()) + " lines against the motor's " +
                                std::to_string(motor.size()));
  }
  std::vector<std::size_t> used;
  for (std::size_t i = 0; i < load.size(); ++i) {
    if (load[i].frequency_hz <= max_frequency_hz && load[i].coherence >= min_coherence &&
        motor[i].coherence >= min_coherence && std::isfinite(std::abs(load[i].ratio))) {
      used.push_back(i);
    }
  }
  if (used.size() < 4) {
    throw std::invalid_argument("load side: " + std::to_string(used.size()) + " lines of coherence " +
                                format_value(min_coherence) + " or more up to " + format_value(max_frequency_hz) +
                                " Hz, need 4");
  }
  // Rows (real and imaginary parts) of  -Q n1 s - Q n0 + u1 s + u0 = Q s^2,  over |s|^2.
  Eigen::MatrixXd a(2 * used.size(), 4);
  Eigen::VectorXd b(2 * used.size());
  for (std::size_t r = 0; r < used.size(); ++r) {
    const LoadRatioPoint& p = load[used[r]];
    const Complex s(0.0, 2.0 * kPi * p.frequency_hz);
    const double weight = 1.0 / std::norm(s);
    const Complex row[4] = {-p.ratio * s, -p.ratio, s, Complex(1.0, 0.0)};
    const Complex rhs = p.ratio * s * s;
    for (int c = 0; c < 4; ++c) {
      a(static_cast<Eigen::Index>(2 * r), c) = weight * row[c].real();
      a(static_cast<Eigen::Index>(2 * r + 1), c) = weight * row[c].imag();
    }
    b(static_cast<Eigen::Index>(2 * r)) = weight * rhs.real();
    b(static_cast<Eigen::Index>(2 * r + 1)) = weight * rhs.imag();
  }
  const Eigen::Vector4d x = a.colPivHouseholderQr().solve(b);
  const double n1 = x(0), n0 = x(1), u0 = x(3);
  // An undamped load (c = 0, the paper's) fits 2 z w about 0, either side: only the corner must exist.
  if (!(n0 > 0) || !std::isfinite(n1) || !std::isfinite(u0)) {
    throw std::invalid_argument("load side: not a second-order corner (w^2 = " + format_value(n0) +
                                ", 2 z w = " + format_value(n1) + ")");
  }
  LoadSideFit fit;
  const double w = std::sqrt(n0);
  fit.anti_resonance_hz = w / (2.0 * kPi);
  fit.anti_resonance_damping = n1 / (2.0 * w);
  fit.gain = u0 / n0;
  double sum = 0;
  for (const std::size_t i : used) {
    const Complex s(0.0, 2.0 * kPi * load[i].frequency_hz);
    const Complex model = fit.gain * (n1 * s + n0) / (s * s + n1 * s + n0);
    sum += std::norm(std::log(load[i].ratio / model));
  }
  fit.rms_log_error = std::sqrt(sum / static_cast<double>(used.size()));
  fit.lines_used = used.size();
  return fit;
}

std::string load_sensor_disagreement(const LoadSideFit& fit, double tolerance) {
  if (std::fabs(fit.gain - 1.0) <= tolerance) return "";
  char text[240];
  std::snprintf(text, sizeof text,
                "the load's sensor reads %.3f times the load's motion against the motor's encoder (fitted over %zu "
                "lines): %s",
                fit.gain, fit.lines_used,
                fit.gain < 0 ? "its sign is reversed" : "its scale is off (its resolution or the drive's increments)");
  return text;
}

double anti_resonance_hz(double load_mass_kg, double spring_n_per_m) {
  return std::sqrt(spring_n_per_m / load_mass_kg) / (2.0 * kPi);
}

double resonance_hz(double motor_mass_kg, double load_mass_kg, double spring_n_per_m) {
  return std::sqrt(spring_n_per_m * (1.0 / load_mass_kg + 1.0 / motor_mass_kg)) / (2.0 * kPi);
}

std::complex<double> two_mass_response(const TwoMassFit& m, double frequency_hz) {
  const Complex s(0.0, 2.0 * kPi * frequency_hz);
  const Complex coupling = m.load_mass_kg * s * (m.spring_damping_n_s_per_m * s + m.spring_n_per_m) /
                           (m.load_mass_kg * s * s + m.spring_damping_n_s_per_m * s + m.spring_n_per_m);
  return 1.0 / (m.motor_mass_kg * s + m.motor_viscous_n_s_per_m + coupling);
}

namespace {

/// x = [n1, n0, d3, d2, d1, d0] of G = (s^2 + n1 s + n0) / (d3 s^3 + d2 s^2 + d1 s + d0), weighted
/// least squares of N - G D = 0 with the given weights per point (columns scaled to unit norm).
Eigen::Matrix<double, 6, 1> rational_fit(const std::vector<const FrequencyPoint*>& points,
                                         const std::vector<double>& weights) {
  const auto rows = static_cast<Eigen::Index>(2 * points.size());
  Eigen::MatrixXd a(rows, 6);
  Eigen::VectorXd b(rows);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Complex s(0.0, 2.0 * kPi * points[i]->frequency_hz);
    const Complex g = points[i]->plant;
    const Complex row[6] = {s, 1.0, -g * s * s * s, -g * s * s, -g * s, -g};
    const Complex rhs = -s * s;
    const auto re = static_cast<Eigen::Index>(2 * i);
    for (Eigen::Index c = 0; c < 6; ++c) {
      a(re, c) = weights[i] * row[c].real();
      a(re + 1, c) = weights[i] * row[c].imag();
    }
    b(re) = weights[i] * rhs.real();
    b(re + 1) = weights[i] * rhs.imag();
  }
  const Eigen::VectorXd scale = a.colwise().norm().transpose().cwiseMax(1e-300);
  const Eigen::MatrixXd scaled = a * scale.cwiseInverse().asDiagonal();
  const Eigen::VectorXd y = scaled.colPivHouseholderQr().solve(b);
  return y.cwiseQuotient(scale);
}

Complex denominator(const Eigen::Matrix<double, 6, 1>& x, double frequency_hz) {
  const Complex s(0.0, 2.0 * kPi * frequency_hz);
  return ((x(2) * s + x(3)) * s + x(4)) * s + x(5);
}

[[noreturn]] void not_physical(const std::string& what, double value) {
  throw std::invalid_argument("fit: not a two-mass system: " + what + " " + format_value(value));
}

}  // namespace

TwoMassFit fit_two_mass(const std::vector<FrequencyPoint>& points, double min_coherence, double max_frequency_hz) {
  std::vector<const FrequencyPoint*> used;
  for (const FrequencyPoint& p : points) {
    if (p.coherence >= min_coherence && p.frequency_hz <= max_frequency_hz && std::isfinite(p.plant.real()) &&
        std::isfinite(p.plant.imag()) && std::abs(p.plant) > 0) {
      used.push_back(&p);
    }
  }
  if (used.size() < 6) {
    throw std::invalid_argument("fit: " + std::to_string(used.size()) +
                                " lines with coherence >= " + format_value(min_coherence) + ", 6 needed");
  }
  // Relative error weighting: e / (D G) = G_model / G - 1. Start from D G ~ s^2 (high frequency).
  std::vector<double> weights(used.size());
  for (std::size_t i = 0; i < used.size(); ++i) {
    const double w = 2.0 * kPi * used[i]->frequency_hz;
    weights[i] = 1.0 / (w * w);
  }
  Eigen::Matrix<double, 6, 1> x = rational_fit(used, weights);
  for (int iteration = 0; iteration < kSkIterations; ++iteration) {
    for (std::size_t i = 0; i < used.size(); ++i) {
      weights[i] = 1.0 / std::max(std::abs(denominator(x, used[i]->frequency_hz) * used[i]->plant), 1e-300);
    }
    x = rational_fit(used, weights);
  }
  const double n1 = x(0), n0 = x(1), d3 = x(2), d1 = x(4), d0 = x(5);
  if (!(n0 > 0)) not_physical("anti-resonance^2 (n0)", n0);
  if (!(d3 > 0)) not_physical("motor mass", d3);
  TwoMassFit fit;
  fit.motor_mass_kg = d3;
  fit.motor_viscous_n_s_per_m = d0 / n0;
  fit.load_mass_kg = (d1 - fit.motor_viscous_n_s_per_m * n1) / n0 - d3;
  if (!(fit.load_mass_kg > 0)) not_physical("load mass", fit.load_mass_kg);
  fit.spring_n_per_m = n0 * fit.load_mass_kg;
  fit.spring_damping_n_s_per_m = n1 * fit.load_mass_kg;
  fit.anti_resonance_hz = std::sqrt(n0) / (2.0 * kPi);
  fit.anti_resonance_damping = n1 / (2.0 * std::sqrt(n0));
  // The resonance: the oscillatory pair among the denominator's three roots.
  Eigen::Matrix3d companion = Eigen::Matrix3d::Zero();
  companion(0, 0) = -x(3) / d3;
  companion(0, 1) = -d1 / d3;
  companion(0, 2) = -d0 / d3;
  companion(1, 0) = 1.0;
  companion(2, 1) = 1.0;
  const Eigen::EigenSolver<Eigen::Matrix3d> roots(companion, false);
  for (Eigen::Index i = 0; i < 3; ++i) {
    const Complex root = roots.eigenvalues()(i);
    if (root.imag() > 0) {
      fit.resonance_hz = std::abs(root) / (2.0 * kPi);
      fit.resonance_damping = -root.real() / std::abs(root);
    }
  }
  if (!(fit.resonance_hz > 0)) not_physical("resonance [Hz]", fit.resonance_hz);
  double sum = 0;
  for (const FrequencyPoint* p : used) sum += std::norm(std::log(two_mass_response(fit, p->frequency_hz) / p->plant));
  fit.rms_log_error = std::sqrt(sum / static_cast<double>(used.size()));
  fit.lines_used = used.size();
  return fit;
}

}  // namespace pmlsm
