// closed_loop: the whole cascade in one process (no DDS). Runs the scenarios,
// PI only or with a compensator (load-acceleration feedback, the RNN or state feedback), writes
// a CSV trace of each and prints the results table.
#include "pmlsm/util/data_files.hpp"
#include <CLI/CLI.hpp>

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/analysis/compensated_run.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/sim/metrics.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "pmlsm/util/exit_codes.hpp"
#include "results_table.hpp"
#include "trace_csv.hpp"
#include "system_file_options.hpp"

namespace {

struct ClosedLoopOptions {
  std::string config_path = pmlsm::data_file("configs/system.yaml");
  std::vector<std::string> scenario_paths;
  std::vector<std::string> overrides_text;
  std::string out_dir = "out";
  std::string compensator = "none";
  std::string weights_path;
  bool online_learning = false;
  std::string input_shaper;  ///< empty: each scenario's own
};

void add_closed_loop_options(CLI::App& app, ClosedLoopOptions& o) {
  pmlsm::add_system_file_options(app, o.config_path, o.overrides_text);
  app.add_option("-s,--scenario", o.scenario_paths, "Scenario file(s) (YAML)")->required()->check(CLI::ExistingFile);
  app.add_option("-o,--out", o.out_dir, "Folder for the CSV traces");
  app.add_option(
         "--compensator", o.compensator,
         "none (PI only), accel (load-acceleration feedback), rnn (the paper's network), state (state feedback with "
         "inverse-model feedforward): one of " +
             pmlsm::compensator_kind_names())
      ->capture_default_str();
  app.add_option("-w,--weights", o.weights_path, "RNN weights file (with --compensator rnn)")->check(CLI::ExistingFile);
  app.add_flag("--online-learning", o.online_learning, "RNN online learning, eqs. (16)-(19)");
  app.add_option("--input-shaper", o.input_shaper,
                 "Shape every scenario's command: none, zv, zvd or ei, timed to the velocity loop's mode "
                 "(default: each scenario's own input_shaper)");
}

/// --compensator, --weights and --online-learning. @throws ConfigError for a bad kind or weights
/// that do not fit the system.
pmlsm::CompensatorSetup compensator_setup(const ClosedLoopOptions& o, const pmlsm::SystemParams& params) {
  pmlsm::CompensatorSetup setup;
  try {
    setup.kind = pmlsm::compensator_kind_from_string(o.compensator);
  } catch (const std::invalid_argument& e) {
    throw pmlsm::ConfigError(std::string("--compensator: ") + e.what());
  }
  setup.online_learning = o.online_learning;
  if (setup.kind == pmlsm::CompensatorKind::kRnn) {
    if (o.weights_path.empty()) throw pmlsm::ConfigError("--compensator rnn: needs --weights FILE");
    const pmlsm::RnnWeightsFile file = pmlsm::load_rnn_weights(o.weights_path);
    const std::string misfit = pmlsm::rnn_weights_misfit(file, params);
    if (!misfit.empty()) throw pmlsm::ConfigError(o.weights_path + ": " + misfit + " (" + o.config_path + ")");
    setup.rnn_weights = file.weights;
  }
  return setup;
}

/// Runs one scenario, writes its trace and prints its row of the results table; kExitSafeState
/// when the plant diverged (a fault: the run is not valid), kExitVerdictFailed when the load's
/// sensor failed (the run lost the feedback it was asked to run with), else kExitOk.
int run_scenario(const pmlsm::SystemParams& params, const pmlsm::Scenario& scenario,
                 const pmlsm::CompensatorSetup& setup, const std::string& out_dir, const std::string& suffix) {
  const double period = params.timing.control_period_s;
  const std::vector<pmlsm::TickRecord> trace = pmlsm::run_with_compensator(params, scenario, setup);
  const auto m = pmlsm::compute_metrics(trace, scenario, period);
  const std::string csv = out_dir + "/" + scenario.name + suffix + ".csv";
  pmlsm::write_trace_csv(csv, trace);
  // A plant that diverged is a fault, a load sensor that failed a lost feedback: the row is
  // marked, the run is not valid.
  const std::string plant_fault = pmlsm::plant_fault_reason(trace);
  const std::string sensor_fault = pmlsm::load_sensor_failure_reason(trace);
  const std::string fault = plant_fault.empty()    ? sensor_fault
                            : sensor_fault.empty() ? plant_fault
                                                   : plant_fault + "; " + sensor_fault;
  pmlsm::node::print_results_row(scenario.name + suffix, m, fault);
  // The vibration guard's verdict: the compensation ran the whole scenario, or from when it was out.
  const auto trip =
      std::find_if(trace.begin(), trace.end(), [](const pmlsm::TickRecord& r) { return r.guard_tripped; });
  if (trip != trace.end()) {
    std::printf(
        "  vibration guard: compensation faded out from t = %.3f s (the oscillation grew or did not "
        "decay); the rest of the run is PI alone\n",
        trip->time_s);
  }
  if (!fault.empty()) {
    std::fprintf(stderr, "closed_loop: %s: %s: run not valid\n", scenario.name.c_str(), fault.c_str());
    return plant_fault.empty() ? pmlsm::kExitVerdictFailed : pmlsm::kExitSafeState;
  }
  return pmlsm::kExitOk;
}

/// Says, for a scenario that shapes its command, the mode and the impulses the shaper uses.
void print_shaper(const pmlsm::SystemParams& params, const pmlsm::Scenario& scenario) {
  if (scenario.input_shaper == pmlsm::ShaperKind::kNone) return;
  const pmlsm::InputShaperParams shaper = params.input_shaper_params(scenario.input_shaper);
  std::string impulses;
  for (const auto& i : pmlsm::shaper_impulses(shaper)) {
    char text[48];
    std::snprintf(text, sizeof text, "%s%.3f at %.1f ms", impulses.empty() ? "" : ", ", i.amplitude, i.time_s * 1e3);
    impulses += text;
  }
  std::fprintf(stderr, "closed_loop: %s: %s shaper on the loop's mode %.2f Hz, damping %.3f: %s\n",
               scenario.name.c_str(), pmlsm::to_string(scenario.input_shaper), shaper.frequency_hz,
               shaper.damping_ratio, impulses.c_str());
}

/// Every scenario with the chosen compensator; kExitSafeState when a plant diverged, else
/// kExitVerdictFailed when a load sensor failed.
/// @throws ConfigError, std::invalid_argument (parameters refused)
int run_closed_loop(const ClosedLoopOptions& o) {
  std::vector<pmlsm::ConfigOverride> overrides;
  for (const auto& text : o.overrides_text) overrides.push_back(pmlsm::ConfigOverride::parse(text));
  const pmlsm::SystemParams params = pmlsm::load_system_params(o.config_path, overrides);
  std::vector<pmlsm::Scenario> scenarios;
  for (const auto& path : o.scenario_paths) {
    scenarios.push_back(pmlsm::load_scenario(path, params.timing.control_period_s));
  }
  if (!o.input_shaper.empty()) {
    pmlsm::ShaperKind kind = pmlsm::ShaperKind::kNone;
    try {
      kind = pmlsm::shaper_kind_from_string(o.input_shaper);
    } catch (const std::invalid_argument& e) {
      throw pmlsm::ConfigError(std::string("--input-shaper: ") + e.what());
    }
    for (pmlsm::Scenario& scenario : scenarios) {
      scenario.input_shaper = kind;
      if (kind != pmlsm::ShaperKind::kNone) scenario.name += std::string("_") + pmlsm::to_string(kind);
    }
  }
  std::filesystem::create_directories(o.out_dir);
  const pmlsm::CompensatorSetup setup = compensator_setup(o, params);
  const std::string suffix = o.compensator == "none" ? "" : "_" + o.compensator + (o.online_learning ? "_online" : "");

  int exit_code = pmlsm::kExitOk;
  pmlsm::node::print_results_header();
  for (const pmlsm::Scenario& scenario : scenarios) print_shaper(params, scenario);
  for (const pmlsm::Scenario& scenario : scenarios) {
    const int code = run_scenario(params, scenario, setup, o.out_dir, suffix);
    if (code == pmlsm::kExitSafeState || exit_code == pmlsm::kExitOk) exit_code = code;
  }
  pmlsm::node::print_results_footer(o.out_dir);
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "In-process closed loop of the PMLSM two-mass system: plant, current loop, "
      "velocity PI, reference model and Kalman filter, without DDS."};
  ClosedLoopOptions options;
  add_closed_loop_options(app, options);
  CLI11_PARSE(app, argc, argv);

  try {
    return run_closed_loop(options);
  } catch (const pmlsm::ConfigError& e) {
    std::fprintf(stderr, "config error: %s\n", e.what());
    return pmlsm::kExitBadConfig;
  } catch (const std::invalid_argument& e) {
    // A component refused its parameters (from the config or the command line).
    std::fprintf(stderr, "config error: parameters refused: %s\n", e.what());
    return pmlsm::kExitBadConfig;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return pmlsm::kExitError;
  }
}
