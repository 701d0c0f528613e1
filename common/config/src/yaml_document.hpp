// Reading a YAML text from outside (a config, a weights file, an override value)
// with the checks yaml-cpp does not make: a duplicated key (yaml-cpp keeps the
// first value silently), aliases (a few lines of them expand to billions of nodes:
// "billion laughs"), nesting deeper than any config, more than one document, and
// texts larger than any config.
#pragma once

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <string>

namespace pmlsm {

/// Limits of a config text; far above what configs/ holds (system.yaml: 12 kB, depth 4).
constexpr std::size_t kMaxYamlBytes = 1 << 20;
constexpr int kMaxYamlDepth = 32;

/// The document's root node (Null for an empty text).
/// @throws ConfigError "origin: ..." naming the line and column, and the key of a duplicate.
YAML::Node load_yaml_document(const std::string& text, const std::string& origin);

}  // namespace pmlsm
