#include "pmlsm/sim/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

constexpr double kTwoPi = 6.28318530717958647692;
constexpr CommandShape kShapes[] = {CommandShape::kZero,   CommandShape::kStep,    CommandShape::kPulse,
                                    CommandShape::kSine,   CommandShape::kRamp,    CommandShape::kTrapezoid,
                                    CommandShape::kSCurve, CommandShape::kChirp,   CommandShape::kMultiSine,
                                    CommandShape::kCsv,    CommandShape::kExternal};
constexpr double kMaxSpeedMps = kMaxCommandSpeedMps;
// Far above this motor (force limit / moving mass: some 100 m/s^2), so a typo is caught
// without second-guessing a rig.
constexpr double kMaxAccelMps2 = 1000.0;
constexpr double kMaxJerkMps3 = 1e6;
constexpr std::size_t kMaxComponents = 64;

// The move of ramp, trapezoid and s_curve: zero until start_s, the rise, hold_s at the
// amplitude, the fall (ramp: none, it holds to the end), zero. Hold and rest return
// exactly amplitude and 0, so the settling metric finds them as constant segments.
double move_mps(const Scenario& s, double t) {
  const double tau = t - s.start_s;
  if (tau < 0.0) return 0.0;
  const double jerk = s.shape == CommandShape::kSCurve ? s.jerk_mps3 : std::numeric_limits<double>::infinity();
  const VelocityTransition rise{s.amplitude_mps, s.accel_mps2, jerk};
  const double rise_s = rise.duration_s();
  if (tau < rise_s) return rise.velocity_mps(tau);
  if (s.shape == CommandShape::kRamp || tau < rise_s + s.hold_s) return s.amplitude_mps;
  const double fall_tau = tau - rise_s - s.hold_s;
  if (fall_tau < rise_s) return s.amplitude_mps - rise.velocity_mps(fall_tau);
  return 0.0;
}

// Linear chirp: f(t) = f0 + (f1 - f0) t / Ts, phase 2 pi (f0 t + (f1 - f0) t^2 / (2 Ts)); after Ts
// the sine goes on at f1 from the phase reached.
double chirp_phase_rad(const Scenario& s, double t) {
  const double f0 = s.frequency_hz;
  const double f1 = s.end_frequency_hz;
  const double ts = s.sweep_s;
  if (t <= ts) return kTwoPi * (f0 * t + 0.5 * (f1 - f0) * t * t / ts);
  return kTwoPi * (0.5 * (f0 + f1) * ts + f1 * (t - ts));
}

double profile_mps(const std::vector<ProfilePoint>& profile, double t) {
  if (profile.empty()) return 0.0;
  if (t <= profile.front().time_s) return profile.front().velocity_mps;
  if (t >= profile.back().time_s) return profile.back().velocity_mps;
  const auto next = std::upper_bound(profile.begin(), profile.end(), t,
                                     [](double time, const ProfilePoint& p) { return time < p.time_s; });
  const ProfilePoint& b = *next;
  const ProfilePoint& a = *(next - 1);
  const double w = (t - a.time_s) / (b.time_s - a.time_s);
  return a.velocity_mps + w * (b.velocity_mps - a.velocity_mps);
}

}  // namespace

const char* to_string(CommandShape shape) {
  switch (shape) {
    case CommandShape::kZero: return "zero";
    case CommandShape::kStep: return "step";
    case CommandShape::kPulse: return "pulse";
    case CommandShape::kSine: return "sine";
    case CommandShape::kRamp: return "ramp";
    case CommandShape::kTrapezoid: return "trapezoid";
    case CommandShape::kSCurve: return "s_curve";
    case CommandShape::kChirp: return "chirp";
    case CommandShape::kMultiSine: return "multi_sine";
    case CommandShape::kCsv: return "csv";
    case CommandShape::kExternal: return "external";
  }
  return "?";
}

CommandShape command_shape_from_string(const std::string& name) {
  std::string known;
  for (CommandShape s : kShapes) {
    if (name == to_string(s)) return s;
    known += known.empty() ? to_string(s) : std::string(", ") + to_string(s);
  }
  throw std::invalid_argument("must be one of " + known + ", got '" + name + "'");
}

double VelocityTransition::duration_s() const {
  const double dv = std::abs(delta_mps);
  if (dv == 0.0) return 0.0;
  if (std::isinf(jerk_mps3)) return dv / accel_mps2;
  // Peak acceleration: the limit, or sqrt(dv j) when the change is too small to reach it.
  const double a_peak = std::min(accel_mps2, std::sqrt(dv * jerk_mps3));
  return dv / a_peak + a_peak / jerk_mps3;
}

double VelocityTransition::velocity_mps(double tau) const {
  const double dv = std::abs(delta_mps);
  const double sign = delta_mps < 0.0 ? -1.0 : 1.0;
  const double total = duration_s();
  if (tau <= 0.0) return 0.0;
  if (tau >= total) return delta_mps;
  if (std::isinf(jerk_mps3)) return sign * accel_mps2 * tau;
  // Jerk up for tj, constant acceleration a_peak for ta, jerk down for tj (symmetric).
  const double a_peak = std::min(accel_mps2, std::sqrt(dv * jerk_mps3));
  const double tj = a_peak / jerk_mps3;
  if (tau < tj) return sign * 0.5 * jerk_mps3 * tau * tau;
  if (tau < total - tj) return sign * (0.5 * a_peak * tj + a_peak * (tau - tj));
  const double left = total - tau;
  return sign * (dv - 0.5 * jerk_mps3 * left * left);
}

void Scenario::validate(double control_period_s) const {
  require_in_range("duration_s", duration_s, control_period_s, 3600.0);
  require_in_range("command.amplitude_mps", amplitude_mps, -kMaxSpeedMps, kMaxSpeedMps);
  const double nyquist_hz = 0.5 / control_period_s;
  switch (shape) {
    case CommandShape::kZero:
    case CommandShape::kStep: require_non_negative("command.frequency_hz", frequency_hz); break;
    case CommandShape::kPulse:
    case CommandShape::kSine: require_in_range("command.frequency_hz", frequency_hz, 1e-3, nyquist_hz); break;
    case CommandShape::kSCurve: require_in_range("command.jerk_mps3", jerk_mps3, 1e-6, kMaxJerkMps3); [[fallthrough]];
    case CommandShape::kTrapezoid: require_in_range("command.hold_s", hold_s, 0.0, 3600.0); [[fallthrough]];
    case CommandShape::kRamp:
      require_in_range("command.start_s", start_s, 0.0, duration_s);
      require_in_range("command.accel_mps2", accel_mps2, 1e-6, kMaxAccelMps2);
      break;
    case CommandShape::kChirp:
      require_in_range("command.start_frequency_hz", frequency_hz, 1e-3, nyquist_hz);
      require_in_range("command.end_frequency_hz", end_frequency_hz, 1e-3, nyquist_hz);
      require_in_range("command.sweep_s", sweep_s, control_period_s, 3600.0);
      break;
    case CommandShape::kMultiSine: {
      if (components.empty() || components.size() > kMaxComponents) {
        throw std::invalid_argument("command.components: must hold 1 to " + std::to_string(kMaxComponents) +
                                    " terms, got " + std::to_string(components.size()));
      }
      double peak = 0.0;
      for (std::size_t i = 0; i < components.size(); ++i) {
        const std::string at = "command.components[" + std::to_string(i) + "].";
        require_in_range((at + "amplitude_mps").c_str(), components[i].amplitude_mps, -kMaxSpeedMps, kMaxSpeedMps);
        require_in_range((at + "frequency_hz").c_str(), components[i].frequency_hz, 1e-3, nyquist_hz);
        require_in_range((at + "phase_rad").c_str(), components[i].phase_rad, -kTwoPi, kTwoPi);
        peak += std::abs(components[i].amplitude_mps);
      }
      require_in_range("command.components: sum of |amplitude_mps|", peak, 0.0, kMaxSpeedMps);
      break;
    }
    case CommandShape::kCsv:
      require_in_range("command.max_gap_s", max_gap_s, control_period_s, 3600.0);
      if (profile.size() < 2) {
        throw std::invalid_argument("command.file: a profile needs at least 2 rows, got " +
                                    std::to_string(profile.size()) + " (" + profile_file + ")");
      }
      break;
    case CommandShape::kExternal:
      require_in_range("command.timeout_s", timeout_s, control_period_s, 60.0);
      require_in_range("command.max_speed_mps", max_speed_mps, 1e-6, kMaxSpeedMps);
      require_in_range("command.accel_mps2", accel_mps2, 1e-6, kMaxAccelMps2);
      break;
  }
  require_in_range("command.duty_cycle", duty_cycle, 0.0, 1.0);
  require_in_range("initial_load_displacement_m", initial_load_displacement_m, -0.1, 0.1);
  require_in_range("cost_window_s", cost_window_s, control_period_s, duration_s);
  require_in_range("settling_band", settling_band, 1e-6, 0.5);
}

double Scenario::command_mps(double t) const {
  switch (shape) {
    case CommandShape::kZero: return 0.0;
    case CommandShape::kStep: return amplitude_mps;
    case CommandShape::kPulse: {
      const double phase = t * frequency_hz - std::floor(t * frequency_hz);
      return phase < duty_cycle ? amplitude_mps : 0.0;
    }
    case CommandShape::kSine: return amplitude_mps * std::sin(kTwoPi * frequency_hz * t);
    case CommandShape::kRamp:
    case CommandShape::kTrapezoid:
    case CommandShape::kSCurve: return move_mps(*this, t);
    case CommandShape::kChirp: return amplitude_mps * std::sin(chirp_phase_rad(*this, t));
    case CommandShape::kMultiSine: {
      double sum = 0.0;
      for (const SineComponent& c : components) {
        sum += c.amplitude_mps * std::sin(kTwoPi * c.frequency_hz * t + c.phase_rad);
      }
      return sum;
    }
    case CommandShape::kCsv: return profile_mps(profile, t);
    case CommandShape::kExternal: return 0.0;
  }
  return 0.0;
}

bool Scenario::has_constant_segments() const {
  switch (shape) {
    case CommandShape::kStep:
    case CommandShape::kPulse:
    case CommandShape::kRamp:
    case CommandShape::kTrapezoid:
    case CommandShape::kSCurve:
    case CommandShape::kCsv: return true;
    default: return false;
  }
}

double Scenario::command_scale_mps() const {
  if (shape == CommandShape::kMultiSine) {
    double sum = 0.0;
    for (const SineComponent& c : components) sum += std::abs(c.amplitude_mps);
    return sum;
  }
  if (shape == CommandShape::kExternal) return max_speed_mps;
  if (shape == CommandShape::kCsv) {
    double peak = 0.0;
    for (const ProfilePoint& p : profile) peak = std::max(peak, std::abs(p.velocity_mps));
    return peak;
  }
  return std::abs(amplitude_mps);
}

namespace {

std::string trimmed(const std::string& text) {
  const auto first = text.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  const auto last = text.find_last_not_of(" \t");
  return text.substr(first, last - first + 1);
}

[[noreturn]] void reject_row(const std::string& origin, std::size_t line, const std::string& what,
                             const std::string& value) {
  throw std::invalid_argument(origin + ":" + std::to_string(line) + ": " + what + ", got '" + value + "'");
}

double cell_number(const std::string& cell, const std::string& origin, std::size_t line, const char* column) {
  const std::string text = trimmed(cell);
  if (text.empty()) reject_row(origin, line, std::string(column) + ": empty cell (a gap in the profile)", cell);
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0') reject_row(origin, line, std::string(column) + ": not a number", text);
  if (!std::isfinite(value)) reject_row(origin, line, std::string(column) + ": must be finite", text);
  return value;
}

}  // namespace

std::vector<ProfilePoint> parse_velocity_profile(const std::string& text, const std::string& origin, double max_gap_s,
                                                 double max_speed_mps) {
  std::vector<ProfilePoint> rows;
  std::size_t line = 0;
  std::size_t pos = 0;
  bool header_seen = false;
  while (pos < text.size()) {
    const auto newline = text.find('\n', pos);
    std::string row = text.substr(pos, newline == std::string::npos ? std::string::npos : newline - pos);
    pos = newline == std::string::npos ? text.size() : newline + 1;
    ++line;
    if (!row.empty() && row.back() == '\r') row.pop_back();
    if (!header_seen) {
      if (trimmed(row) != "time_s,velocity_mps") {
        reject_row(origin, line, "the first line must be the header 'time_s,velocity_mps'", row);
      }
      header_seen = true;
      continue;
    }
    if (trimmed(row).empty()) reject_row(origin, line, "empty line (a gap in the profile)", row);
    const auto comma = row.find(',');
    if (comma == std::string::npos || row.find(',', comma + 1) != std::string::npos) {
      reject_row(origin, line, "expected 2 columns: time_s,velocity_mps", row);
    }
    ProfilePoint p;
    p.time_s = cell_number(row.substr(0, comma), origin, line, "time_s");
    p.velocity_mps = cell_number(row.substr(comma + 1), origin, line, "velocity_mps");
    if (p.time_s < 0.0) reject_row(origin, line, "time_s: must be >= 0", format_value(p.time_s));
    if (std::abs(p.velocity_mps) > max_speed_mps) {
      reject_row(origin, line,
                 "velocity_mps: must be in [-" + format_value(max_speed_mps) + ", " + format_value(max_speed_mps) + "]",
                 format_value(p.velocity_mps));
    }
    if (!rows.empty()) {
      const double step = p.time_s - rows.back().time_s;
      if (!(step > 0.0)) {
        reject_row(origin, line, "time_s: must increase (previous row: " + format_value(rows.back().time_s) + ")",
                   format_value(p.time_s));
      }
      if (step > max_gap_s) {
        reject_row(origin, line,
                   "time_s: a gap of " + format_value(step) + " s after " + format_value(rows.back().time_s) +
                       " s, above max_gap_s " + format_value(max_gap_s),
                   format_value(p.time_s));
      }
    }
    rows.push_back(p);
  }
  if (!header_seen) reject_row(origin, 1, "empty file: expected the header 'time_s,velocity_mps'", "");
  if (rows.size() < 2) {
    reject_row(origin, line, "a profile needs at least 2 rows", std::to_string(rows.size()) + " rows");
  }
  return rows;
}

}  // namespace pmlsm
