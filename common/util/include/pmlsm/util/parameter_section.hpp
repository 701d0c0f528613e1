// A parameter section: the table of a component declared outside SystemParams (in a library above
// it, as the commissioning's, or in its own folder, compensators/<name>/), joined to the system's
// table at run time instead of being written into SystemParams. The
// component's Params declares its entries once, as every component does (declare(at, self, v,
// live_at), pmlsm/util/parameter_table.hpp), with its defaults as the struct's initial values:
// the system file may set any entry under the section's key path and need not name the section
// at all. Whatever walks the system's table (the YAML reader, the range checks, the configuration
// reference, `pmlsm param`, the mutation tests) walks the sections' entries too, through
// SectionVisitor, a visitor behind virtual calls.
//
// A section's values are kept by key path as numbers (a flag as 0 or 1, a whole number exactly:
// the ranges keep them below 2^53); the component reads its typed Params from them
// (section_params).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

/// Key path -> value of every entry of every section.
using SectionValues = std::map<std::string, double>;

/// The visitor kinds a section's entries may have: real, whole number and flag.
class SectionVisitor {
 public:
  virtual ~SectionVisitor() = default;
  virtual void real(const std::string& path, double& value, const Plausible& range) = 0;
  virtual void integer(const std::string& path, std::int64_t& value, const Plausible& range) = 0;
  virtual void flag(const std::string& path, bool& value) = 0;
};

/// Any table visitor (the templates that walk visit_parameters) behind SectionVisitor.
template <typename Visitor>
class SectionVisitorOf final : public SectionVisitor {
 public:
  explicit SectionVisitorOf(Visitor& v) : v_(v) {}
  void real(const std::string& path, double& value, const Plausible& range) override { v_.real(path, value, range); }
  void integer(const std::string& path, std::int64_t& value, const Plausible& range) override {
    v_.integer(path, value, range);
  }
  void flag(const std::string& path, bool& value) override { v_.flag(path, value); }

 private:
  Visitor& v_;
};

/// One registered section: where it sits in the system file, which node takes its live entries,
/// and its table over SectionValues.
struct ParameterSection {
  const char* at;           ///< its key path, "compensator.spring_force_feedback"
  const char* live_at;      ///< the node taking the entries its Params declares live
  const char* declared_in;  ///< the file of its declaration, from the source tree's root
  /// Walks its entries with `v` on the Params held in `values` (entries absent there: the
  /// declared defaults), and keeps what `v` wrote.
  void (*visit)(const ParameterSection& section, SectionValues& values, SectionVisitor& v);
  /// The Params' own validate() on the values (the ranges are the table's, checked before).
  /// @throws std::invalid_argument naming the entry.
  void (*validate)(const ParameterSection& section, const SectionValues& values);
};

/// True for a Params with validate() (the checks that combine values; the ranges are the table's).
template <typename T, typename = void>
struct HasValidate : std::false_type {};
template <typename T>
struct HasValidate<T, std::void_t<decltype(std::declval<const T&>().validate())>> : std::true_type {};
/// True for a Params whose values the system completes (a period, a pole pitch, not in its
/// section): its validate_entries() checks what the file's values alone can be checked for, and
/// is what reading the file runs; its validate() runs where the system completes it.
template <typename T, typename = void>
struct HasValidateEntries : std::false_type {};
template <typename T>
struct HasValidateEntries<T, std::void_t<decltype(std::declval<const T&>().validate_entries())>> : std::true_type {};

/// Params::declare with the node taking its live entries, or without for a Params with none.
template <typename Params, typename Self, typename Visitor>
void declare_section(const std::string& at, Self& p, Visitor& v, const char* live_at) {
  if constexpr (table_detail::DeclaresLive<Params>::value) {
    Params::declare(at, p, v, live_at);
  } else {
    Params::declare(at, p, v);
  }
}

namespace section_detail {

/// A whole number as the Params' own type holds it; one it cannot hold (-4 for a count) is
/// refused, not wrapped.
/// @throws std::invalid_argument naming the entry.
template <typename T>
T held_as(const std::string& path, double x) {
  // 2^digits is one past the largest and, unlike a 64-bit max, exact as a double.
  const double past_max = std::ldexp(1.0, std::numeric_limits<T>::digits);
  if (!(x >= static_cast<double>(std::numeric_limits<T>::lowest()) && x < past_max)) {
    throw std::invalid_argument(path + ": expected a whole number in [" +
                                std::to_string(std::numeric_limits<T>::lowest()) + ", " +
                                std::to_string(std::numeric_limits<T>::max()) + "], got " + format_value(x));
  }
  return static_cast<T>(x);
}

// Moves a Params' entries into and out of SectionValues by walking its declaration.
class Load {
 public:
  explicit Load(const SectionValues& values) : values_(values) {}
  void real(const std::string& path, double& value, const Plausible&) const {
    if (const auto it = values_.find(path); it != values_.end()) value = it->second;
  }
  template <typename T>
  void integer(const std::string& path, T& value, const Plausible&) const {
    if (const auto it = values_.find(path); it != values_.end()) value = held_as<T>(path, it->second);
  }
  void flag(const std::string& path, bool& value) const {
    if (const auto it = values_.find(path); it != values_.end()) value = it->second != 0.0;
  }

 private:
  const SectionValues& values_;
};

class Store {
 public:
  explicit Store(SectionValues& values) : values_(values) {}
  void real(const std::string& path, double value, const Plausible&) { values_[path] = value; }
  template <typename T>
  void integer(const std::string& path, T value, const Plausible&) {
    values_[path] = static_cast<double>(value);
  }
  void flag(const std::string& path, bool value) { values_[path] = value ? 1.0 : 0.0; }

 private:
  SectionValues& values_;
};

// Whole numbers reach a SectionVisitor as std::int64_t, whatever the Params' own type.
class Erase {
 public:
  explicit Erase(SectionVisitor& v) : v_(v) {}
  void real(const std::string& path, double& value, const Plausible& range) { v_.real(path, value, range); }
  template <typename T>
  void integer(const std::string& path, T& value, const Plausible& range) {
    auto whole = static_cast<std::int64_t>(value);
    v_.integer(path, whole, range);
    value = held_as<T>(path, static_cast<double>(whole));
  }
  void flag(const std::string& path, bool& value) { v_.flag(path, value); }

 private:
  SectionVisitor& v_;
};

}  // namespace section_detail

/// The typed Params of the section at `at`: its defaults, with what `values` holds over them.
template <typename Params>
Params section_params(const SectionValues& values, const std::string& at) {
  Params p;
  section_detail::Load load(values);
  declare_section<Params>(at, p, load, nullptr);
  return p;
}

/// The section of a Params type (declare(at, self, v, live_at) over real, integer and flag
/// entries; validate() when it has one), registered under `at` with its live entries taken by
/// `live_at`, declared in the file `declared_in`.
template <typename Params>
ParameterSection parameter_section(const char* at, const char* live_at, const char* declared_in) {
  return ParameterSection{at, live_at, declared_in,
                          [](const ParameterSection& section, SectionValues& values, SectionVisitor& v) {
                            Params p = section_params<Params>(values, section.at);
                            section_detail::Erase erase(v);
                            declare_section<Params>(section.at, p, erase, section.live_at);
                            section_detail::Store store(values);
                            declare_section<Params>(section.at, static_cast<const Params&>(p), store, nullptr);
                          },
                          [](const ParameterSection& section, const SectionValues& values) {
                            if constexpr (HasValidateEntries<Params>::value) {
                              section_params<Params>(values, section.at).validate_entries();
                            } else if constexpr (HasValidate<Params>::value) {
                              section_params<Params>(values, section.at).validate();
                            }
                          }};
}

/// This build's sections: generated into the build tree (cmake/PmlsmCompensators.cmake, library
/// pmlsm_parameter_sections) from the libraries' pmlsm_parameter_section() calls (the
/// commissioning's, common/CMakeLists.txt) and the compensators' registration lines, in their
/// folders' order.
/// Every reader of a system file reads them (parse_system_params).
const std::vector<ParameterSection>& registered_parameter_sections();

}  // namespace pmlsm
