// Parameter checks shared by every component's constructor.
//
// Each check throws std::invalid_argument naming the parameter and the
// offending value, so that the config loader can prefix the key path and the
// user sees e.g. "plant.mechanics.load_mass_kg: must be > 0, got -4".
#pragma once

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace pmlsm {

/// Formats a double with enough digits to round-trip, for error messages.
inline std::string format_value(double value) {
  std::ostringstream out;
  out.precision(17);
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
    throw std::invalid_argument(std::string(name) + ": must be in [" + format_value(lo) + ", " +
                                format_value(hi) + "], got " + format_value(value));
  }
}

/// True when every argument is finite; used by step() functions to reject inputs.
template <typename... T>
constexpr bool all_finite(T... values) {
  return (std::isfinite(values) && ...);
}

}  // namespace pmlsm
