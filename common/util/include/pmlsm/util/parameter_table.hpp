// Parameter tables: a component declares each parameter once, as a visit of its fields with
// the key its files use, the kind, and the plausible range with the reason (the pattern of
// Drake's Serialize/Archive). Whatever needs the parameters walks that one table: the YAML
// reader (every key known and present), RangeCheck below (the system's check of every range;
// a component's own validate() starts with check_declared_ranges, so its ranges are written
// nowhere else), the generated configuration reference, the mutation tests.
//
// An entry also says who takes it live (Plausible::live_at, choice's live_at): the node that
// accepts a change of it at a tick boundary (`pmlsm param`), or nobody (read at start). A node's
// live parameters are the entries that name it (live_keys, pmlsm/sim/live_parameters.hpp).
//
// A visitor has:
//   real(path, double&, Plausible)                          a finite number
//   integer(path, T&, Plausible)                            a whole number (counts, ids, seeds)
//   flag(path, bool&)
//   choice(path, E&, E (*from_string)(const std::string&), live_at)  one of a set of names
//   vector3(path, Eigen::Vector3d&, Plausible)              three numbers, each in range
//   integer_list(path, std::vector<int>&, Plausible)        whole numbers, each in range
#pragma once

#include <Eigen/Core>
#include <cfloat>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

/// A parameter's plausible range and why: a value outside it is refused with the range and
/// this reason. The ranges are wide (a study may move a value by orders of magnitude) but keep
/// every value one a real motor, drive, bus or filter could have, so that a typo like 1e308 or
/// 1e-320 stops the program instead of turning a state into NaN.
struct Plausible {
  double min;
  double max;
  const char* reason;
  const char* live_at = nullptr;  ///< the node that takes it live, or nullptr: read at start only
};

/// Checks each value of a table against its plausible range; throws std::invalid_argument
/// "<key>: must be in [min, max] (<reason>), got <value>" at the first one outside.
class RangeCheck {
 public:
  void real(const std::string& path, double value, const Plausible& range) const { check(path, value, range); }
  template <typename T>
  void integer(const std::string& path, T value, const Plausible& range) const {
    const double x = static_cast<double>(value);
    if (std::isfinite(x) && x != std::trunc(x)) {
      throw std::invalid_argument(path + ": must be a whole number (" + range.reason + "), got " + format_value(x));
    }
    check(path, x, range);
  }
  void flag(const std::string&, bool) const {}
  template <typename E, typename F>
  void choice(const std::string&, E, F, const char* /*live_at*/ = nullptr) const {}
  void vector3(const std::string& path, const Eigen::Vector3d& value, const Plausible& range) const {
    for (int i = 0; i < 3; ++i) check(path + "[" + std::to_string(i) + "]", value(i), range);
  }
  void integer_list(const std::string& path, const std::vector<int>& value, const Plausible& range) const {
    for (std::size_t i = 0; i < value.size(); ++i) check(path + "[" + std::to_string(i) + "]", value[i], range);
  }

 private:
  static void check(const std::string& path, double value, const Plausible& range) {
    require_finite(path.c_str(), value);
    // A subnormal number (|x| < 2.2e-308, not 0) is no physical quantity; it only
    // overflows whatever divides by it.
    if (value != 0.0 && std::fabs(value) < DBL_MIN) {
      throw std::invalid_argument(path + ": must be 0 or at least 2.2e-308 in size (a subnormal number), got " +
                                  format_value(value));
    }
    if (!(value >= range.min && value <= range.max)) {
      throw std::invalid_argument(path + ": must be in [" + format_value(range.min) + ", " + format_value(range.max) +
                                  "] (" + range.reason + "), got " + format_value(value));
    }
  }
};

namespace table_detail {

// RangeCheck naming each entry by its key inside the Params ("min_decay", "model.load_mass_kg"),
// as the Params' own validate() names what it checks: the declaration is walked at "" and the
// leading '.' of each key dropped.
class OwnRangeCheck {
 public:
  void real(const std::string& path, double value, const Plausible& range) const {
    check_.real(path.substr(1), value, range);
  }
  template <typename T>
  void integer(const std::string& path, T value, const Plausible& range) const {
    check_.integer(path.substr(1), value, range);
  }
  void flag(const std::string&, bool) const {}
  template <typename E, typename F>
  void choice(const std::string&, E, F, const char* /*live_at*/ = nullptr) const {}
  void vector3(const std::string& path, const Eigen::Vector3d& value, const Plausible& range) const {
    check_.vector3(path.substr(1), value, range);
  }
  void integer_list(const std::string& path, const std::vector<int>& value, const Plausible& range) const {
    check_.integer_list(path.substr(1), value, range);
  }

 private:
  RangeCheck check_;
};

template <typename P, typename = void>
struct DeclaresLive : std::false_type {};
template <typename P>
struct DeclaresLive<
    P, std::void_t<decltype(P::declare(std::string(), std::declval<const P&>(), std::declval<OwnRangeCheck&>(),
                                       static_cast<const char*>(nullptr)))>> : std::true_type {};

}  // namespace table_detail

/// A Params' values against its own declaration's ranges: the first step of its validate(), so
/// each range is written once, in declare(), and validate() adds only what a range cannot say
/// (values that must agree with each other, the values the system fills in). A refusal names the
/// key inside the Params ("min_decay: must be in [0.001, 0.999] (...), got 0").
/// @throws std::invalid_argument at the first value outside its range.
template <typename Params>
void check_declared_ranges(const Params& params) {
  table_detail::OwnRangeCheck check;
  if constexpr (table_detail::DeclaresLive<Params>::value) {
    Params::declare(std::string(), params, check, nullptr);
  } else {
    Params::declare(std::string(), params, check);
  }
}

}  // namespace pmlsm
