// The options of every program that loads the system file: -c,--config FILE and --set KEY=VALUE,
// declared once. Inline and with <CLI/CLI.hpp>: only the files that declare a command line include
// it, and they parse CLI11 already (a compiled copy would be one more file compiling CLI11).
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace pmlsm {

/// -c,--config FILE (it must exist; its default shown when not empty) and --set KEY=VALUE ...
/// (any number, each a key path of the file and its new value; read by parse_overrides()).
/// `file_help` says what the file is to this program.
inline void add_system_file_options(CLI::App& app, std::string& config_path, std::vector<std::string>& overrides,
                                    const std::string& file_help = "System parameters (YAML)",
                                    const std::string& set_help = "Override a system parameter: key.path=value") {
  app.add_option("-c,--config", config_path, file_help)->check(CLI::ExistingFile)->capture_default_str();
  app.add_option("--set", overrides, set_help)->take_all();
}

}  // namespace pmlsm
