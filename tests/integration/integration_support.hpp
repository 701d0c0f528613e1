// What the integration tests share: where the programs and the sources are,
// a DDS domain per test, files in and out, and the command lines of the nodes.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace pmlsm::test {

inline std::string bin(const std::string& name) { return std::string(PMLSM_BIN_DIR) + "/" + name; }
inline std::string source(const std::string& rel) { return std::string(PMLSM_SOURCE_DIR) + "/" + rel; }

/// A domain of its own per test, so the tests of one ctest run, which run in
/// parallel, never meet. Offsets: distributed_test.cpp 0..6, compensator_test.cpp
/// 10..14 and 78 (state feedback), training_test.cpp 15..19, 86, 87, tests/interop 20..24, the Foxglove bridge's tests
/// 25..29, tests/tools 30..39, drive_safety_test.cpp 40..44, virtual_rig_test.cpp 45, 46, 48, 49, 70, 71 (CAN
/// ports 62xx), the python CANopen tests 47, 72 and 73, tests/security 50..59, hardening_test.cpp
/// 60..69, external_reference_test.cpp 74..77, agents_test.cpp 80..85, tests/tools' identify 88, 89,
/// drive_safety_test.cpp 90, 91, tests/tools 92..103 and 106, shutdown_test.cpp 104, 105, churn_test.cpp 107,
/// tests/tools 108, container_test.cpp 120..124, 127..130, secure_nodes_test.cpp's containers 125, 126,
/// virtual_rig_test.cpp's container 131. PMLSM_TEST_DOMAIN_BASE moves the whole set (default 100), for two test runs on
/// one machine: 0..101 (the largest offset is 131, and a domain id above 232 is refused by every node, so a test there
/// fails).
inline std::string test_domain(int offset) {
  const char* base = std::getenv("PMLSM_TEST_DOMAIN_BASE");
  return std::to_string((base != nullptr ? std::atoi(base) : 100) + offset);
}

inline std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// configs/scenarios/pulse.yaml made 600 s long, written into `dir`: a run that lasts until it is stopped.
inline std::string long_pulse(const std::filesystem::path& dir) {
  std::string text = read_file(source("configs/scenarios/pulse.yaml"));
  const auto at = text.find("duration_s:");
  text.replace(at, text.find('\n', at) - at, "duration_s: 600.0");
  const std::filesystem::path path = dir / "long.yaml";
  std::ofstream(path) << text;
  return path.string();
}

/// One column of a trace CSV (header row first) by its name; empty when there is no such column.
inline std::vector<double> trace_column(const std::string& csv, const std::string& name) {
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  {
    std::istringstream h(line);
    std::string cell;
    while (std::getline(h, cell, ',')) header.push_back(cell);
  }
  const auto it = std::find(header.begin(), header.end(), name);
  if (it == header.end()) return {};
  const std::size_t column = static_cast<std::size_t>(it - header.begin());
  std::vector<double> values;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string cell;
    for (std::size_t c = 0; c <= column && std::getline(row, cell, ','); ++c) {
    }
    values.push_back(std::strtod(cell.c_str(), nullptr));
  }
  return values;
}

/// An empty folder <tmp>/<prefix>_<pid>_<name>.
inline std::filesystem::path fresh_dir(const std::string& prefix, const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / (prefix + "_" + std::to_string(getpid()) + "_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// A control-loop node on the shipped config and profiles.
inline std::vector<std::string> node_args(const std::string& exe, const std::string& domain,
                                          const std::string& scenario, std::vector<std::string> extra = {}) {
  std::vector<std::string> a{bin(exe),
                             "--domain",
                             domain,
                             "--config",
                             source("configs/system.yaml"),
                             "--scenario",
                             scenario,
                             "--profiles",
                             source("configs/dds/profiles.xml")};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

/// One component of a container: `--component NAME TYPE` and node_args()'s arguments after the program.
inline std::vector<std::string> component_args(const std::string& name, const std::string& type,
                                               const std::string& domain, const std::string& scenario,
                                               std::vector<std::string> extra = {}) {
  std::vector<std::string> args = node_args(type, domain, scenario, std::move(extra));
  args.erase(args.begin());
  args.insert(args.begin(), {"--component", name, type});
  return args;
}

/// The container `name` with these components (component_args()).
inline std::vector<std::string> container_args(const std::string& name,
                                               const std::vector<std::vector<std::string>>& components) {
  std::vector<std::string> argv{bin("container"), "--name", name};
  for (const auto& c : components) argv.insert(argv.end(), c.begin(), c.end());
  return argv;
}

/// de_trainer on the shipped configs, one local thread, no progress bar.
inline std::vector<std::string> trainer_args(const std::string& domain, std::vector<std::string> extra = {}) {
  std::vector<std::string> a{bin("de_trainer"),
                             "--domain",
                             domain,
                             "--config",
                             source("configs/system.yaml"),
                             "--training",
                             source("configs/training.yaml"),
                             "--profiles",
                             source("configs/dds/profiles.xml"),
                             "--no-progress",
                             "--threads",
                             "1"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

}  // namespace pmlsm::test
