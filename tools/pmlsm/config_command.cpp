// `pmlsm config`: the configuration files' references and checks.
//   pmlsm config reference [--kind system|canopen|ethercat] [-c FILE] [-o PAGE] [--check]   the generated reference
//   pmlsm config check [--kind system|canopen|ethercat] [-c FILE] [--set K=V ...]   every check a program makes on
//   loading it
//   pmlsm config write [-c FILE] --set K=V ... -o OUT [--reason TEXT]   a copy of the system file with these
//   values, each source "chosen: TEXT" (a nudged plant for a rig beside its simulation, a site's file)
// `reference --check` compares PAGE with what it would write and exits 1 when they differ (the
// ctest `config_reference` runs it on docs/configuration-reference.md).
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/ethercat_config.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/parameter_reference.hpp"
#include "pmlsm/util/atomic_file.hpp"
#include "pmlsm/util/data_files.hpp"

namespace pmlsm::tools {
namespace {

struct ConfigCommandOptions {
  std::string kind = "system";  ///< system (configs/system.yaml), canopen or ethercat (configs/<kind>/drive.yaml)
  std::string config;           ///< "": the shipped file of that kind
  std::string out;              ///< the page ("": standard output)
  bool check = false;
  std::vector<std::string> set;
  std::string reason = "set with pmlsm config write";
};

/// The shipped file of the kind, by its place in the source tree.
std::string shipped_file(const ConfigCommandOptions& o) {
  return o.kind == "system" ? "configs/system.yaml" : "configs/" + o.kind + "/drive.yaml";
}

/// The file to read: the option's, else the shipped one wherever it is installed.
std::string file_to_read(const ConfigCommandOptions& o) {
  return o.config.empty() ? data_file(shipped_file(o)) : o.config;
}

/// The file as messages and the page name it: the shipped one by its place in the source tree.
std::string origin_of(const ConfigCommandOptions& o) { return o.config.empty() ? shipped_file(o) : o.config; }

int run_reference(const ConfigCommandOptions& o) {
  const std::string text = read_config_file(file_to_read(o));
  const std::string page = o.kind == "canopen"    ? canopen_parameter_reference(text, origin_of(o))
                           : o.kind == "ethercat" ? ethercat_parameter_reference(text, origin_of(o))
                                                  : system_parameter_reference(text, origin_of(o));
  if (o.check) {
    if (o.out.empty()) throw UsageError("--check needs -o PAGE, the page to compare");
    std::ifstream in(o.out, std::ios::binary);
    std::ostringstream current;
    if (in) current << in.rdbuf();
    if (current.str() == page) {
      std::printf("%s: up to date with %s and the parameter declarations\n", o.out.c_str(), origin_of(o).c_str());
      return kExitOk;
    }
    std::fprintf(stderr,
                 "%s: out of date with %s or the parameter declarations; remake it with\n"
                 "  ./build/bin/pmlsm config reference -o %s\n",
                 o.out.c_str(), origin_of(o).c_str(), o.out.c_str());
    return kExitError;
  }
  if (o.out.empty()) {
    std::fputs(page.c_str(), stdout);
    return kExitOk;
  }
  try {
    write_file_atomically(o.out, page);
  } catch (const std::runtime_error& e) {
    throw UsageError(e.what());
  }
  std::printf("wrote %s\n", o.out.c_str());
  return kExitOk;
}

int run_check(const ConfigCommandOptions& o) {
  const std::string text = read_config_file(file_to_read(o));
  if (o.kind == "canopen") {
    parse_canopen_config(text, origin_of(o), parse_overrides(o.set));
  } else if (o.kind == "ethercat") {
    parse_ethercat_config(text, origin_of(o), parse_overrides(o.set));
  } else {
    parse_system_params(text, origin_of(o), parse_overrides(o.set));
  }
  std::printf("%s: valid (%zu parameters)\n", origin_of(o).c_str(), list_leaf_sources(text, origin_of(o)).size());
  return kExitOk;
}

int run_write(const ConfigCommandOptions& o) {
  if (o.set.empty()) throw UsageError("write: nothing to set (--set key.path=value ...)");
  write_system_file_with(file_to_read(o), parse_overrides(o.set), "chosen: " + o.reason, o.out);
  std::printf("wrote %s: %s with %zu value(s) set\n", o.out.c_str(), origin_of(o).c_str(), o.set.size());
  return kExitOk;
}

}  // namespace

void add_config_command(CLI::App& app, int& exit_code) {
  CLI::App* cmd = app.add_subcommand(
      "config",
      "The system, CANopen and EtherCAT files: their generated references, their checks, a copy with values set");
  cmd->require_subcommand(1);
  auto o = std::make_shared<ConfigCommandOptions>();
  const auto wrap = [&exit_code](const std::shared_ptr<ConfigCommandOptions>& options,
                                 int (*run)(const ConfigCommandOptions&)) {
    return [options, run, &exit_code] {
      try {
        exit_code = run(*options);
      } catch (const ConfigError& e) {
        throw UsageError(std::string("config error: ") + e.what());
      }
    };
  };
  // Which file, for both subcommands.
  const auto add_file_options = [&o](CLI::App& sub) {
    sub.add_option("--kind", o->kind,
                   "Which file: system (configs/system.yaml), canopen (configs/canopen/drive.yaml) or ethercat "
                   "(configs/ethercat/drive.yaml)")
        ->capture_default_str()
        ->check(CLI::IsMember({"system", "canopen", "ethercat"}));
    sub.add_option("-c,--config", o->config, "The file (default: the shipped one of its kind)")
        ->check(CLI::ExistingFile);
  };
  CLI::App* reference = cmd->add_subcommand(
      "reference", "Markdown: every parameter's key, value, unit, accepted range and its reason, and source");
  add_file_options(*reference);
  reference->add_option("-o,--out", o->out, "The page to write (default: standard output)");
  reference->add_flag("--check", o->check, "Compare with the page instead of writing it: exit 1 when it differs");
  reference->callback(wrap(o, &run_reference));
  CLI::App* check = cmd->add_subcommand("check", "Loads the file with every check the programs make");
  add_file_options(*check);
  check->add_option("--set", o->set, "Override a parameter of the file: key.path=value")->take_all();
  check->callback(wrap(o, &run_check));
  CLI::App* write =
      cmd->add_subcommand("write", "A copy of the system file with values set, every check made before it is written");
  write->add_option("-c,--config", o->config, "The system file (default: the shipped one)")->check(CLI::ExistingFile);
  write->add_option("--set", o->set, "The value to set: key.path=value")->take_all()->required();
  write->add_option("-o,--out", o->out, "The file to write")->required();
  write->add_option("--reason", o->reason, "Why, written into each set value's source (\"chosen: REASON\")")
      ->capture_default_str();
  write->callback(wrap(o, &run_write));
}

}  // namespace pmlsm::tools
