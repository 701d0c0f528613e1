// closed_loop: the whole cascade in one process (no DDS). Runs the scenarios,
// writes a CSV trace of each and prints the results table.
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "pmlsm/closed_loop.hpp"
#include "pmlsm/config.hpp"
#include "pmlsm/metrics.hpp"
#include "results_table.hpp"
#include "trace_csv.hpp"

int main(int argc, char** argv) {
  CLI::App app{"In-process closed loop of the PMLSM two-mass system: plant, current loop, "
               "velocity PI, reference model and Kalman filter, without DDS."};
  std::string config_path = "configs/system.yaml";
  std::vector<std::string> scenario_paths;
  std::vector<std::string> overrides_text;
  std::string out_dir = "out";
  app.add_option("-c,--config", config_path, "System parameters (YAML)")->check(CLI::ExistingFile);
  app.add_option("-s,--scenario", scenario_paths, "Scenario file(s) (YAML)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--set", overrides_text, "Override a system parameter: key.path=value")
      ->take_all();
  app.add_option("-o,--out", out_dir, "Folder for the CSV traces");
  CLI11_PARSE(app, argc, argv);

  try {
    std::vector<pmlsm::ConfigOverride> overrides;
    for (const auto& text : overrides_text) overrides.push_back(pmlsm::ConfigOverride::parse(text));
    const pmlsm::SystemParams params = pmlsm::load_system_params(config_path, overrides);
    const double period = params.timing.control_period_s;
    std::vector<pmlsm::Scenario> scenarios;
    for (const auto& path : scenario_paths) scenarios.push_back(pmlsm::load_scenario(path, period));
    std::filesystem::create_directories(out_dir);

    pmlsm::node::print_results_header();
    for (const pmlsm::Scenario& scenario : scenarios) {
      const auto trace = pmlsm::run_scenario(params, scenario);
      const auto m = pmlsm::compute_metrics(trace, scenario, period);
      const std::string csv = out_dir + "/" + scenario.name + ".csv";
      pmlsm::write_trace_csv(csv, trace);
      pmlsm::node::print_results_row(scenario.name, m);
    }
    pmlsm::node::print_results_footer(out_dir);
  } catch (const pmlsm::ConfigError& e) {
    std::fprintf(stderr, "config error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
