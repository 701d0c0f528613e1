#include "pmlsm/control/input_shaper.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

ShaperKind shaper_kind_from_string(const std::string& text) {
  if (text == "none") return ShaperKind::kNone;
  if (text == "zv") return ShaperKind::kZv;
  if (text == "zvd") return ShaperKind::kZvd;
  if (text == "ei") return ShaperKind::kEi;
  throw std::invalid_argument("expected none, zv, zvd or ei, got '" + text + "'");
}

const char* to_string(ShaperKind kind) {
  switch (kind) {
    case ShaperKind::kNone: return "none";
    case ShaperKind::kZv: return "zv";
    case ShaperKind::kZvd: return "zvd";
    case ShaperKind::kEi: return "ei";
  }
  return "?";
}

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMaxSpanS = 10.0;

double damped_period_s(const InputShaperParams& p) {
  return 1.0 / (p.frequency_hz * std::sqrt(1.0 - p.damping_ratio * p.damping_ratio));
}

}  // namespace

void InputShaperParams::validate() const {
  require_in_range("period_s", period_s, 1e-6, 1.0);
  if (kind == ShaperKind::kNone) return;
  require_positive("frequency_hz", frequency_hz);
  require_in_range("damping_ratio", damping_ratio, 0.0, 0.5);
  require_in_range("vibration_tolerance", vibration_tolerance, 1e-6, 0.25);
  const double span_s = damped_period_s(*this) * (kind == ShaperKind::kZv ? 0.5 : 1.0);
  if (span_s > kMaxSpanS) {
    throw std::invalid_argument("frequency_hz: the shaper would delay a move by " + format_value(span_s) +
                                " s (over 10 s), got " + format_value(frequency_hz));
  }
}

std::vector<ShaperImpulse> shaper_impulses(const InputShaperParams& p) {
  p.validate();
  if (p.kind == ShaperKind::kNone) return {{0.0, 1.0}};
  const double td = damped_period_s(p);
  const double k = std::exp(-p.damping_ratio * kPi / std::sqrt(1.0 - p.damping_ratio * p.damping_ratio));
  const double v = p.vibration_tolerance;
  std::vector<ShaperImpulse> out;
  switch (p.kind) {
    case ShaperKind::kZv: out = {{0.0, 1.0}, {0.5 * td, k}}; break;
    case ShaperKind::kZvd: out = {{0.0, 1.0}, {0.5 * td, 2.0 * k}, {td, k * k}}; break;
    case ShaperKind::kEi:
      out = {{0.0, 0.25 * (1.0 + v)}, {0.5 * td, 0.5 * (1.0 - v) * k}, {td, 0.25 * (1.0 + v) * k * k}};
      break;
    case ShaperKind::kNone: break;
  }
  double sum = 0;
  for (const ShaperImpulse& i : out) sum += i.amplitude;
  for (ShaperImpulse& i : out) i.amplitude /= sum;
  return out;
}

double residual_vibration(const std::vector<ShaperImpulse>& impulses, double frequency_hz, double damping_ratio) {
  const double w = 2.0 * kPi * frequency_hz;
  const double wd = w * std::sqrt(1.0 - damping_ratio * damping_ratio);
  const double t_last = impulses.empty() ? 0.0 : impulses.back().time_s;
  double c = 0, s = 0;
  for (const ShaperImpulse& i : impulses) {
    // Relative to the last impulse's time, so the exponentials stay below 1 (no overflow).
    const double decay = std::exp(-damping_ratio * w * (t_last - i.time_s));
    c += i.amplitude * decay * std::cos(wd * i.time_s);
    s += i.amplitude * decay * std::sin(wd * i.time_s);
  }
  return std::sqrt(c * c + s * s);
}

namespace {

// Each impulse at t = (n + f) T split into (1 - f) at tick n and f at tick n + 1.
std::vector<double> tap_weights_of(const std::vector<ShaperImpulse>& impulses, double period_s) {
  std::vector<double> taps(static_cast<std::size_t>(std::floor(impulses.back().time_s / period_s)) + 2, 0.0);
  for (const ShaperImpulse& i : impulses) {
    const double at = i.time_s / period_s;
    const double whole = std::floor(at);
    const double fraction = at - whole;
    const auto n = static_cast<std::size_t>(whole);
    taps[n] += i.amplitude * (1.0 - fraction);
    taps[n + 1] += i.amplitude * fraction;
  }
  while (taps.size() > 1 && taps.back() == 0.0) taps.pop_back();
  return taps;
}

}  // namespace

InputShaper::InputShaper(const InputShaperParams& params) {
  const std::vector<ShaperImpulse> impulses = shaper_impulses(params);
  span_s_ = impulses.back().time_s;
  taps_ = tap_weights_of(impulses, params.period_s);
  history_.assign(taps_.size(), 0.0);
}

void InputShaper::retune(const InputShaperParams& params) {
  const std::vector<ShaperImpulse> impulses = shaper_impulses(params);
  std::vector<double> taps = tap_weights_of(impulses, params.period_s);
  // The past by age (0: the newest), then laid out with the newest at the last index.
  std::vector<double> history(taps.size());
  std::size_t at = newest_;
  double oldest = history_[newest_];
  for (std::size_t age = 0; age < history.size(); ++age) {
    if (age < history_.size()) {
      oldest = history_[at];
      at = at == 0 ? history_.size() - 1 : at - 1;
    }
    history[history.size() - 1 - age] = oldest;
  }
  taps_ = std::move(taps);
  history_ = std::move(history);
  newest_ = history_.size() - 1;
  span_s_ = impulses.back().time_s;
}

void InputShaper::reset(double command) {
  std::fill(history_.begin(), history_.end(), command);
  last_command_ = command;
}

double InputShaper::step(double command) {
  if (std::isfinite(command)) {
    last_command_ = command;
  } else {
    ++rejected_inputs_;
  }
  newest_ = newest_ + 1 == history_.size() ? 0 : newest_ + 1;
  history_[newest_] = last_command_;
  double out = 0;
  std::size_t at = newest_;
  for (const double w : taps_) {
    out += w * history_[at];
    at = at == 0 ? history_.size() - 1 : at - 1;
  }
  return out;
}

}  // namespace pmlsm
