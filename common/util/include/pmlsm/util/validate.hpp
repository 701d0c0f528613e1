// Parameter checks shared by every component's constructor.
//
// Each check throws std::invalid_argument naming the parameter and the
// offending value, so that the config loader can prefix the key path and the
// user sees e.g. "plant.mechanics.load_mass_kg: must be > 0, got -4".
#pragma once

#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>

namespace pmlsm {

/// Formats a double in the fewest of 15 or 17 significant digits that read
/// back to the same value, for error messages ("0.0004", not "0.00040000000000000002").
inline std::string format_value(double value) {
  for (int digits : {15, 17}) {
    std::ostringstream out;
    out.precision(digits);
    out << value;
    if (digits == 17 || std::strtod(out.str().c_str(), nullptr) == value) return out.str();
  }
  return {};
}

/// `value` in hexadecimal with at least `digits` digits, upper case: "0x0016" for (0x16, 4).
inline std::string format_hex(std::uint32_t value, int digits) {
  std::ostringstream out;
  out << "0x" << std::uppercase << std::hex;
  out.width(digits);
  out.fill('0');
  out << value;
  return out.str();
}

inline void require_finite(const char* name, double value) {
  if (!std::isfinite(value)) {
    throw std::invalid_argument(std::string(name) + ": must be finite, got " + format_value(value));
  }
}

inline void require_positive(const char* name, double value) {
  require_finite(name, value);
  if (!(value > 0.0)) {
    throw std::invalid_argument(std::string(name) + ": must be > 0, got " + format_value(value));
  }
}

inline void require_non_negative(const char* name, double value) {
  require_finite(name, value);
  if (!(value >= 0.0)) {
    throw std::invalid_argument(std::string(name) + ": must be >= 0, got " + format_value(value));
  }
}

inline void require_in_range(const char* name, double value, double lo, double hi) {
  require_finite(name, value);
  if (!(value >= lo && value <= hi)) {
    throw std::invalid_argument(std::string(name) + ": must be in [" + format_value(lo) + ", " + format_value(hi) +
                                "], got " + format_value(value));
  }
}

/// An evaluation window of at least two control periods (one period holds no oscillation).
inline void require_window(const char* name, double window_s, double control_period_s) {
  require_positive(name, window_s);
  if (window_s < 2.0 * control_period_s) {
    throw std::invalid_argument(std::string(name) + ": must be at least two periods (" +
                                format_value(2.0 * control_period_s) + " s), got " + format_value(window_s));
  }
}

/// Runs a sub-section's checks and puts the section's name in front of the
/// parameter name of any error: "mechanics." + "load_mass_kg: ...".
template <typename F>
void validate_section(const char* section, F&& check) {
  try {
    check();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string(section) + "." + e.what());
  }
}

/// True when every argument is finite; used by step() functions to reject inputs.
template <typename... T>
constexpr bool all_finite(T... values) {
  return (std::isfinite(values) && ...);
}

}  // namespace pmlsm
