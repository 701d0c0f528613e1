#include "pmlsm/control/biquad.hpp"

#include <cmath>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

constexpr double kTwoPiRad = 6.28318530717958647692;

/// A continuous second-order section n(s) / d(s), coefficients highest power first.
struct Analog {
  double n2 = 0, n1 = 0, n0 = 1, d2 = 0, d1 = 0, d0 = 1;
  double prewarp_rad_s = 0;
};

Analog analog_of(const BiquadParams& p) {
  const double w = kTwoPiRad * p.frequency_hz, w2 = kTwoPiRad * p.second_frequency_hz;
  Analog a;
  switch (p.kind) {
    case FilterKind::kNone: break;
    case FilterKind::kNotch: a = {1.0, 2.0 * p.damping * w, w * w, 1.0, 2.0 * p.second_damping * w, w * w, w}; break;
    case FilterKind::kLowPass: a = {0.0, 0.0, w * w, 1.0, 2.0 * p.damping * w, w * w, w}; break;
    case FilterKind::kLeadLag: a = {0.0, 1.0 / w, 1.0, 0.0, 1.0 / w2, 1.0, std::sqrt(w * w2)}; break;
    case FilterKind::kGeneral:
      a = {1.0 / (w * w), 2.0 * p.damping / w, 1.0, 1.0 / (w2 * w2), 2.0 * p.second_damping / w2,
           1.0,           std::sqrt(w * w2)};
      break;
  }
  return a;
}

void require_frequency(const char* name, double value, double period_s) {
  require_in_range(name, value, 1e-3, 0.45 / period_s);
}

}  // namespace

FilterKind filter_kind_from_string(const std::string& name) {
  if (name == "none") return FilterKind::kNone;
  if (name == "notch") return FilterKind::kNotch;
  if (name == "low_pass") return FilterKind::kLowPass;
  if (name == "lead_lag") return FilterKind::kLeadLag;
  if (name == "general") return FilterKind::kGeneral;
  throw std::invalid_argument("must be one of none, notch, low_pass, lead_lag, general, got '" + name + "'");
}

const char* to_string(FilterKind kind) {
  switch (kind) {
    case FilterKind::kNone: return "none";
    case FilterKind::kNotch: return "notch";
    case FilterKind::kLowPass: return "low_pass";
    case FilterKind::kLeadLag: return "lead_lag";
    case FilterKind::kGeneral: return "general";
  }
  return "?";
}

void BiquadParams::validate() const {
  require_in_range("period_s", period_s, 1e-6, 1.0);
  switch (kind) {
    case FilterKind::kNone: return;
    case FilterKind::kNotch:
      require_frequency("frequency_hz", frequency_hz, period_s);
      require_in_range("second_damping", second_damping, 1e-3, 10.0);
      require_in_range("damping", damping, 0.0, second_damping);
      return;
    case FilterKind::kLowPass:
      require_frequency("frequency_hz", frequency_hz, period_s);
      require_in_range("damping", damping, 1e-2, 10.0);
      return;
    case FilterKind::kLeadLag:
      require_frequency("frequency_hz", frequency_hz, period_s);
      require_frequency("second_frequency_hz", second_frequency_hz, period_s);
      return;
    case FilterKind::kGeneral:
      require_frequency("frequency_hz", frequency_hz, period_s);
      require_frequency("second_frequency_hz", second_frequency_hz, period_s);
      require_in_range("damping", damping, 0.0, 10.0);
      require_in_range("second_damping", second_damping, 1e-3, 10.0);
      return;
  }
}

BiquadCoefficients biquad_coefficients(const BiquadParams& params) {
  params.validate();
  if (params.kind == FilterKind::kNone) return {};
  const Analog a = analog_of(params);
  const double k = a.prewarp_rad_s / std::tan(a.prewarp_rad_s * params.period_s / 2.0);
  const double k2 = k * k;
  const double a0 = a.d2 * k2 + a.d1 * k + a.d0;
  BiquadCoefficients c;
  c.b0 = (a.n2 * k2 + a.n1 * k + a.n0) / a0;
  c.b1 = 2.0 * (a.n0 - a.n2 * k2) / a0;
  c.b2 = (a.n2 * k2 - a.n1 * k + a.n0) / a0;
  c.a1 = 2.0 * (a.d0 - a.d2 * k2) / a0;
  c.a2 = (a.d2 * k2 - a.d1 * k + a.d0) / a0;
  return c;
}

std::complex<double> biquad_response(const BiquadCoefficients& c, double frequency_hz, double period_s) {
  const std::complex<double> z1 = std::polar(1.0, -kTwoPiRad * frequency_hz * period_s);  // z^-1
  return (c.b0 + z1 * (c.b1 + z1 * c.b2)) / (1.0 + z1 * (c.a1 + z1 * c.a2));
}

Biquad::Biquad(const BiquadParams& params) : c_(biquad_coefficients(params)) {}

double Biquad::step(double x) {
  if (!std::isfinite(x)) {
    ++rejected_;
    return last_;
  }
  const double y = c_.b0 * x + s1_;
  s1_ = c_.b1 * x - c_.a1 * y + s2_;
  s2_ = c_.b2 * x - c_.a2 * y;
  last_ = y;
  return y;
}

void FilterChainParams::validate() const {
  for (std::size_t i = 0; i < slots.size(); ++i) {
    try {
      slots[i].validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("slot " + std::to_string(i + 1) + ": " + e.what());
    }
  }
}

namespace {

/// The slots in use first, then kind none ones.
std::array<Biquad, kFilterSlots> in_use_first(const FilterChainParams& p) {
  p.validate();
  std::array<BiquadParams, kFilterSlots> used;
  used.fill(BiquadParams{FilterKind::kNone, 0, 0, 0, 0, p.slots[0].period_s});
  std::size_t count = 0;
  for (const BiquadParams& slot : p.slots) {
    if (slot.kind != FilterKind::kNone) used[count++] = slot;
  }
  return {Biquad(used[0]), Biquad(used[1]), Biquad(used[2]), Biquad(used[3])};
}

}  // namespace

FilterChain::FilterChain(const FilterChainParams& params)
    : params_(params), filters_(in_use_first(params)), period_s_(params.slots[0].period_s) {
  for (const BiquadParams& slot : params.slots) count_ += slot.kind != FilterKind::kNone ? 1 : 0;
}

double FilterChain::step(double x) {
  if (!std::isfinite(x)) {
    ++rejected_;
    return last_;
  }
  for (std::size_t i = 0; i < count_; ++i) x = filters_[i].step(x);
  last_ = x;
  return x;
}

std::complex<double> FilterChain::response(double frequency_hz) const {
  std::complex<double> h = 1.0;
  for (std::size_t i = 0; i < count_; ++i) h *= biquad_response(filters_[i].coefficients(), frequency_hz, period_s_);
  return h;
}

}  // namespace pmlsm
