// YAML configuration: the system parameters (configs/system.yaml) and the
// scenarios (configs/scenarios/*.yaml).
//
// A parameter is either a plain scalar or a sourced leaf
//   key: {value: 20.0, source: "paper Table 2"}
// whose source starts with "paper" (a value the paper gives) or "chosen:"
// followed by the reason (a value the paper leaves open). Every key must be
// known and present, every number finite and in range; each error names the
// file, the key path and the value. The values are validated by the same
// validate() functions the components' constructors use.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/analysis/rnn_training.hpp"
#include "pmlsm/sim/scenario.hpp"
#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// "a.b.c=value": replaces the value at that key path before the file is read
/// (for sourced leaves, their value). An unknown path is an error.
struct ConfigOverride {
  std::string key_path;
  std::string value;
  /// @throws ConfigError when the text has no '=' or an empty key.
  static ConfigOverride parse(const std::string& text);
};

/// Every text of a command line's --set list, parsed. @throws ConfigError as ConfigOverride::parse.
std::vector<ConfigOverride> parse_overrides(const std::vector<std::string>& texts);

/// The text of a configuration file, for tools that read it themselves (`pmlsm config`).
/// @throws ConfigError "<path>: cannot open file".
std::string read_config_file(const std::string& path);

/// @throws ConfigError naming the file, key path and value of the first problem.
SystemParams load_system_params(const std::string& path, const std::vector<ConfigOverride>& overrides = {});

/// Writes out_path: the system file in_path with every (key path, value) of `values` set and its
/// source replaced by `source` ("chosen: <reason>"), the rest as it was (comments are not kept:
/// a header line names in_path). `command_line`, the --set overrides the writing command ran
/// with, is set first, its source saying so: the copy describes the system that was measured (a
/// simulated plant changed with --set stays that plant). The text is loaded back with every check
/// of load_system_params before it is written, atomically. Returns what it wrote.
/// @throws ConfigError naming the file and the key of the first problem.
std::string write_system_file_with(const std::string& in_path,
                                   const std::vector<std::pair<std::string, double>>& values, const std::string& source,
                                   const std::string& out_path, const std::vector<ConfigOverride>& command_line = {});
/// The same with each value as its text (a choice's name, a number as written).
std::string write_system_file_with(const std::string& in_path, const std::vector<ConfigOverride>& values,
                                   const std::string& source, const std::string& out_path,
                                   const std::vector<ConfigOverride>& command_line = {});
SystemParams parse_system_params(const std::string& yaml_text, const std::string& origin,
                                 const std::vector<ConfigOverride>& overrides = {});

/// @throws ConfigError naming the file, key path and value of the first problem.
Scenario load_scenario(const std::string& path, double control_period_s,
                       const std::vector<ConfigOverride>& overrides = {});
Scenario parse_scenario(const std::string& yaml_text, const std::string& origin, double control_period_s,
                        const std::vector<ConfigOverride>& overrides = {});

/// configs/training.yaml (the weight search); scenario files are relative to it.
/// @throws ConfigError naming the file, key path and value of the first problem.
TrainingParams load_training_params(const std::string& path, double control_period_s,
                                    const std::vector<ConfigOverride>& overrides = {});
TrainingParams parse_training_params(const std::string& yaml_text, const std::string& origin, double control_period_s,
                                     const std::vector<ConfigOverride>& overrides = {});

/// Every leaf of a YAML document with its key path and its source ("" when the
/// leaf is a plain scalar): lets tests and tools check that each value says where
/// it comes from. @throws ConfigError on a parse error.
struct SourcedLeaf {
  std::string key_path;
  std::string source;
  std::string value;  ///< the value as the file writes it (a list in flow form)
};
std::vector<SourcedLeaf> list_leaf_sources(const std::string& yaml_text, const std::string& origin);

}  // namespace pmlsm
