// Reading configuration YAML: sourced leaves ({value, source}), overrides (--set key.path=value),
// numbers and whole numbers checked, and Section, a mapping read key by key that reports the
// keys it did not read (unknown keys). Every error names the file and the key path; Section's
// name the line of the value too. Shared by the parsers of common/config.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/config/config.hpp"
#include "yaml_document.hpp"

namespace pmlsm::config_reading {

inline bool is_sourced_leaf(const YAML::Node& node) { return node.IsMap() && node["value"]; }

inline std::string join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

inline std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path + ": cannot open file");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// A file named in a config file: relative names are relative to that file's folder.
inline std::string relative_to(const std::string& origin, const std::string& file) {
  if (file.empty() || file[0] == '/') return file;
  const auto slash = origin.find_last_of('/');
  return (slash == std::string::npos ? std::string(".") : origin.substr(0, slash)) + "/" + file;
}

inline YAML::Node parse_yaml(const std::string& text, const std::string& origin) {
  YAML::Node root = load_yaml_document(text, origin);
  if (!root.IsMap()) throw ConfigError(origin + ": top level must be a mapping of keys");
  return root;
}

// Checks the form of a sourced leaf: exactly value and source, and a source that
// says where the value comes from.
inline void check_sourced_leaf(const YAML::Node& node, const std::string& origin, const std::string& path) {
  for (const auto& kv : node) {
    const auto key = kv.first.as<std::string>();
    if (key != "value" && key != "source") {
      throw ConfigError(origin + ": " + path + "." + key +
                        ": unknown key (a sourced value has only 'value' and 'source')");
    }
  }
  if (!node["source"] || !node["source"].IsScalar()) {
    throw ConfigError(origin + ": " + path + ".source: missing (say 'paper ...' or 'chosen: why')");
  }
  const auto source = node["source"].as<std::string>();
  const bool from_paper = source.rfind("paper", 0) == 0;
  const bool chosen = source.rfind("chosen:", 0) == 0 && source.find_first_not_of(" \t", 7) != std::string::npos;
  if (!from_paper && !chosen) {
    throw ConfigError(origin + ": " + path + ".source: must start with 'paper' or 'chosen: <reason>', got '" + source +
                      "'");
  }
}

// A sourced leaf's source becomes `source`: by default what --set says of its values.
inline void apply_overrides(YAML::Node& root, const std::vector<ConfigOverride>& overrides, const std::string& origin,
                            const std::string& source = "chosen: set on the command line") {
  for (const ConfigOverride& o : overrides) {
    YAML::Node node = root;
    std::string walked;
    std::stringstream parts(o.key_path);
    std::string part;
    std::vector<std::string> keys;
    while (std::getline(parts, part, '.')) keys.push_back(part);
    for (std::size_t i = 0; i < keys.size(); ++i) {
      walked = join(walked, keys[i]);
      if (!node.IsMap() || !node[keys[i]]) {
        throw ConfigError(origin + ": override " + o.key_path + ": no key '" + walked + "' in the file");
      }
      node.reset(node[keys[i]]);
    }
    if (node.IsMap() && !is_sourced_leaf(node)) {
      throw ConfigError(origin + ": override " + o.key_path + ": is a section, not a value");
    }
    YAML::Node value;
    try {
      value = load_yaml_document(o.value, "override " + o.key_path);
    } catch (const ConfigError& e) {
      throw ConfigError(origin + ": override " + o.key_path + ": value '" + o.value + "' is not accepted: " + e.what());
    }
    if (is_sourced_leaf(node)) {
      node["value"] = value;
      node["source"] = source;
    } else {
      node = value;
    }
  }
}

[[noreturn]] inline void fail_at(const std::string& origin, const std::string& path, const std::string& what) {
  throw ConfigError(origin + ": " + path + ": " + what);
}

/// A value as an error message quotes it: a scalar as written, anything else (an empty value:
/// "~", a list, a mapping) in flow style.
inline std::string describe(const YAML::Node& v) {
  if (v.IsScalar()) return v.Scalar();
  YAML::Emitter out;
  out << YAML::Flow << v;
  return out.c_str();
}

inline bool looks_boolean(const YAML::Node& v) {
  bool b = false;
  return YAML::convert<bool>::decode(v, b);
}

// A finite number (not a boolean that would read as 0 or 1).
inline double to_number(const YAML::Node& v, const std::string& origin, const std::string& path) {
  double out = 0;
  if (!v.IsScalar() || !YAML::convert<double>::decode(v, out) || looks_boolean(v)) {
    fail_at(origin, path, "expected a number, got '" + describe(v) + "'");
  }
  if (!std::isfinite(out)) fail_at(origin, path, "must be finite, got " + v.Scalar());
  return out;
}

// Digits only: no sign, no fraction, no exponent, no hexadecimal.
inline std::uint64_t to_whole_number(const YAML::Node& v, const std::string& origin, const std::string& path) {
  std::uint64_t out = 0;
  const std::string text = v.IsScalar() ? v.Scalar() : std::string();
  if (!v.IsScalar() || text.empty() || text.find_first_not_of("0123456789") != std::string::npos ||
      !YAML::convert<std::uint64_t>::decode(v, out)) {
    fail_at(origin, path, "expected a non-negative integer, got '" + describe(v) + "'");
  }
  return out;
}

// The value of a leaf: a sourced leaf's value (its form checked) or the plain scalar or list.
inline YAML::Node leaf_value(const YAML::Node& v, const std::string& origin, const std::string& path) {
  if (is_sourced_leaf(v)) {
    check_sourced_leaf(v, origin, path);
    return v["value"];
  }
  if (v.IsMap()) fail_at(origin, path, "expected a value, got a section '" + describe(v) + "'");
  return v;
}

// " (line N)" of a node read from a file, "" for one without a place in the file: a value
// given with --set is parsed on its own, so it sits at line 1, column 1, where a file's
// values never do (the file's top level is a mapping whose first key is there).
inline std::string line_of(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null() || (mark.line == 0 && mark.column == 0)) return "";
  return " (line " + std::to_string(mark.line + 1) + ")";
}

// Runs read(); a ConfigError it throws gets the line of node appended.
template <typename Read>
auto with_line_of(const YAML::Node& node, Read&& read) -> decltype(read()) {
  try {
    return read();
  } catch (const ConfigError& e) {
    throw ConfigError(std::string(e.what()) + line_of(node));
  }
}

// A mapping being read: hands out values by key, remembers which keys were
// read, and reports the ones that were not (unknown keys) in finish().
class Section {
 public:
  Section(YAML::Node node, std::string origin, std::string path)
      : node_(std::move(node)), origin_(std::move(origin)), path_(std::move(path)) {
    if (!node_.IsMap()) {
      fail_at(origin_, path_, "must be a mapping of keys, got '" + describe(node_) + "'" + line_of(node_));
    }
  }

  /// The line of the section in its file (" (line N)"), for errors found after reading.
  std::string line() const { return line_of(node_); }

  Section child(const std::string& key) { return Section(required(key), origin_, join(path_, key)); }

  double number(const std::string& key) {
    const YAML::Node at = required(key);
    return with_line_of(at, [&] { return to_number(value(key), origin_, join(path_, key)); });
  }

  std::uint64_t unsigned_integer(const std::string& key) {
    const YAML::Node at = required(key);
    return with_line_of(at, [&] { return to_whole_number(value(key), origin_, join(path_, key)); });
  }

  std::string text(const std::string& key) {
    const YAML::Node at = required(key);
    return with_line_of(at, [&] {
      const YAML::Node v = value(key);
      if (!v.IsScalar()) fail_at(origin_, join(path_, key), "expected a string, got '" + describe(v) + "'");
      return v.Scalar();
    });
  }

  bool has(const std::string& key) const { return static_cast<bool>(node_[key]); }

  bool flag(const std::string& key) {
    const YAML::Node at = required(key);
    return with_line_of(at, [&] {
      const YAML::Node v = value(key);
      bool out = false;
      if (!v.IsScalar() || !YAML::convert<bool>::decode(v, out)) {
        fail_at(origin_, join(path_, key), "expected true or false, got '" + describe(v) + "'");
      }
      return out;
    });
  }

  /// A list of scalars as written (texts), e.g. mapping: ["0x6040:0:16", ...].
  std::vector<std::string> texts(const std::string& key) {
    const YAML::Node v = required(key);
    std::vector<std::string> out;
    if (!v.IsSequence()) {
      throw ConfigError(origin_ + ": " + join(path_, key) + ": expected a list of values" + line_of(v));
    }
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!v[i].IsScalar()) {
        throw ConfigError(origin_ + ": " + join(path_, key) + "[" + std::to_string(i) + "]: expected a value" +
                          line_of(v[i]));
      }
      out.push_back(v[i].Scalar());
    }
    return out;
  }

  /// A list of sub-sections (mappings), e.g. scenarios: [{file: ..., weight: ...}].
  std::vector<Section> sections(const std::string& key) {
    const YAML::Node v = required(key);
    if (!v.IsSequence() || v.size() == 0) {
      fail_at(origin_, join(path_, key), "expected a non-empty list, got '" + describe(v) + "'" + line_of(v));
    }
    std::vector<Section> out;
    for (std::size_t i = 0; i < v.size(); ++i) {
      out.emplace_back(v[i], origin_, join(path_, key) + "[" + std::to_string(i) + "]");
    }
    return out;
  }

  void finish() const {
    for (const auto& kv : node_) {
      const auto key = kv.first.as<std::string>();
      if (used_.count(key) == 0) fail_at(origin_, join(path_, key), "unknown key" + line_of(kv.first));
    }
  }

 private:
  YAML::Node required(const std::string& key) {
    const YAML::Node v = node_[key];
    if (!v) fail_at(origin_, join(path_, key), "missing key" + line_of(node_));
    used_.insert(key);
    return v;
  }

  YAML::Node value(const std::string& key) { return leaf_value(required(key), origin_, join(path_, key)); }

  YAML::Node node_;
  std::string origin_;
  std::string path_;
  std::set<std::string> used_;
};

// Runs a section's validate(), turning its std::invalid_argument into a
// ConfigError with the file name and the section's key path in front.
template <typename F>
inline void validate_in(const std::string& origin, F&& check) {
  try {
    check();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(origin + ": " + e.what());
  }
}

/// The optional `models:` section of sweep and training files: whether every plant is
/// commissioned first, and the run that commissions it (named relative to the file). Without the
/// section: the configured models on every plant.
struct ModelsSection {
  bool identify = false;
  std::string identification_scenario_file;  ///< "" without one
  Scenario identification_scenario;
};

inline ModelsSection read_models_section(Section& top, const std::string& origin, double control_period_s) {
  ModelsSection out;
  if (!top.has("models")) return out;
  Section models = top.child("models");
  out.identify = models.flag("identified");
  if (out.identify || models.has("identification_scenario")) {
    out.identification_scenario_file = relative_to(origin, models.text("identification_scenario"));
    out.identification_scenario = load_scenario(out.identification_scenario_file, control_period_s);
  }
  models.finish();
  return out;
}

}  // namespace pmlsm::config_reading
