// Shared by the config tests: the shipped files' texts and YAML edits of them.
#pragma once

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/config/config.hpp"

namespace pmlsm::test {

inline std::string source_path(const std::string& relative) { return std::string(PMLSM_SOURCE_DIR) + "/" + relative; }

inline std::string read_text(const std::string& relative) {
  std::ifstream in(source_path(relative));
  if (!in) throw std::runtime_error("cannot read " + source_path(relative));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The ConfigError message of `load`, or "" with a test failure when it throws none.
template <typename F>
std::string error_of(F&& load) {
  try {
    load();
  } catch (const ConfigError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no ConfigError thrown";
  return "";
}

/// The shipped configs/system.yaml, read once.
inline const std::string& system_text() {
  static const std::string text = read_text("configs/system.yaml");
  return text;
}

/// Sets the node at a dotted key path to a YAML text (adding the last key if
/// new), or removes the key when yaml is empty.
struct Edit {
  std::string path;
  std::optional<std::string> yaml;
};

inline std::string edited(const std::string& text, const std::vector<Edit>& edits) {
  YAML::Node root = YAML::Load(text);
  for (const Edit& e : edits) {
    std::vector<std::string> keys;
    std::stringstream parts(e.path);
    for (std::string k; std::getline(parts, k, '.');) keys.push_back(k);
    YAML::Node parent = root;
    for (std::size_t i = 0; i + 1 < keys.size(); ++i) {
      // A missing parent would silently become an unknown-key test instead.
      if (!parent[keys[i]]) throw std::logic_error("edit path not in file: " + e.path);
      parent.reset(parent[keys[i]]);  // reset, not =: assigning a Node overwrites what it refers to
    }
    if (e.yaml) {
      parent[keys.back()] = YAML::Load(*e.yaml);
    } else if (!parent.remove(keys.back())) {
      throw std::logic_error("edit path not in file: " + e.path);
    }
  }
  YAML::Emitter out;
  out << root;
  return out.c_str();
}

}  // namespace pmlsm::test
