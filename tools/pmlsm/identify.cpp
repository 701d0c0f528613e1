// `pmlsm identify`: commissioning. The load's mass and spring and the bearing friction fitted
// (pmlsm/analysis/identification.hpp) to what the drive measured while the velocity PI alone ran the
// identification scenario, written into a copy of the system file, whose models (the Kalman
// filter's, state feedback's) and the gains scheduled on them every node then takes with
// `--config`:
//   pmlsm record -o commissioning.mcap ...   (while launch/sim.yaml or the rig runs the scenario)
//   pmlsm identify commissioning.mcap -o configs/system_identified.yaml
//   pmlsm identify --simulate --set plant.mechanics.load_mass_kg=2 ...   (the simulated plant, in process)
// From a recording it takes /pmlsm/motor_feedback (encoder position and velocity, the force
// applied), decoded by the file's own schemas, in tick order. A recording with a tick missing
// or repeated, a tick with the drive's force off, or too short a run is refused (exit 2), as is
// a fit whose load mass or spring ended at the edge of the search box (exit 6: the data did not
// pin it; nothing written).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "system_file_options.hpp"
#include "commands.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"
#include "pmlsm/mcap/mcap.hpp"
#include "pmlsm/analysis/identification.hpp"
#include "pmlsm/util/data_files.hpp"
#include "run_validity.hpp"
#include "tool_support.hpp"

namespace pmlsm::tools {
namespace {

struct IdentifyOptions {
  std::string recording;  ///< an MCAP file with /pmlsm/motor_feedback ("" with --simulate)
  bool simulate = false;
  std::string config = data_file("configs/system.yaml");
  std::vector<std::string> set;
  std::string scenario = data_file("configs/scenarios/identification.yaml");
  std::string out;  ///< the system file to write ("": print only)
  double range_ratio = IdentificationParams{}.range_ratio;
  std::uint32_t evaluations = IdentificationParams{}.max_evaluations;
};

constexpr const char* kFeedbackTopic = "/pmlsm/motor_feedback";

/// The drive's samples of a recording, in tick order. @throws UsageError naming what is wrong.
std::vector<IdentificationSample> recorded_samples(const std::string& path) {
  if (!std::filesystem::exists(path)) throw UsageError("no such file: " + path);
  std::map<std::uint16_t, mcap::Schema> schemas;
  std::optional<introspect::MessageSchema> schema;
  std::optional<std::uint16_t> channel;
  std::map<std::uint64_t, IdentificationSample> by_tick;
  std::string problem;
  mcap::ReadCallbacks callbacks;
  callbacks.on_schema = [&](const mcap::Schema& s) { schemas[s.id] = s; };
  callbacks.on_channel = [&](const mcap::Channel& c) {
    if (c.topic != kFeedbackTopic) return;
    const auto found = schemas.find(c.schema_id);
    std::string why;
    if (recorded_channel(c, found != schemas.end() ? &found->second : nullptr, &schema, why) == nullptr) {
      problem = std::string(kFeedbackTopic) + ": " + why;
      return;
    }
    channel = c.id;
  };
  callbacks.on_message = [&](const mcap::Message& m) {
    if (!channel || m.channel_id != *channel || !problem.empty()) return;
    const auto decoded = schema->decode(m.data, m.size);
    const auto number = [&](const char* field) -> std::optional<double> {
      const auto* f = decoded.find(field);
      return f != nullptr ? f->as_double() : std::nullopt;
    };
    const auto tick = number("stamp.tick"), position = number("position_m"), velocity = number("velocity_mps"),
               applied = number("applied_force_n"), status = number("status"), power = number("power_state");
    if (!decoded.ok() || !tick || !position || !velocity || !applied || !status || !power) {
      problem = std::string(kFeedbackTopic) +
                ": a sample without stamp.tick, position_m, velocity_mps, "
                "applied_force_n, status or power_state" +
                (decoded.ok() ? "" : ": " + decoded.error);
      return;
    }
    const auto k = static_cast<std::uint64_t>(*tick);
    if (!node::force_applied({static_cast<std::uint32_t>(*status), static_cast<std::uint8_t>(*power), 0})) {
      problem = "the drive had its force off at tick " + std::to_string(k) +
                " (safe state, fault or not enabled): a commissioning run must have the force on throughout";
      return;
    }
    if (!by_tick.emplace(k, IdentificationSample{*velocity, *position, *applied}).second) {
      problem =
          std::string(kFeedbackTopic) + ": tick " + std::to_string(k) + " twice (two drives, or two runs in one file)";
    }
  };
  try {
    const mcap::ReadReport report = mcap::read(path, callbacks);
    (void)report;
  } catch (const std::runtime_error& e) {
    throw UsageError(path + ": " + e.what());
  }
  if (!problem.empty()) throw UsageError(path + ": " + problem);
  if (by_tick.empty()) throw UsageError(path + ": no " + std::string(kFeedbackTopic) + " samples");
  std::vector<IdentificationSample> samples;
  samples.reserve(by_tick.size());
  std::uint64_t expected = by_tick.begin()->first;
  for (const auto& [tick, sample] : by_tick) {
    if (tick != expected) {
      throw UsageError(path + ": " + kFeedbackTopic + ": ticks " + std::to_string(expected) + " to " +
                       std::to_string(tick - 1) + " missing (the fit needs every tick)");
    }
    samples.push_back(sample);
    ++expected;
  }
  return samples;
}

int run_identify(const IdentifyOptions& o) {
  if (o.simulate == !o.recording.empty()) throw UsageError("give a recording or --simulate (one of them)");
  const SystemParams configured = load_system_params(o.config, parse_overrides(o.set));
  if (!o.out.empty()) require_output_folder("identify: -o", o.out);  // before the run, not after it
  std::vector<IdentificationSample> samples;
  std::string from;
  if (o.simulate) {
    const Scenario scenario = load_scenario(o.scenario, configured.timing.control_period_s);
    std::fprintf(stderr, "identify: PI alone on %s, simulated plant (%s)\n", o.scenario.c_str(), o.config.c_str());
    const auto trace = run_scenario(configured, scenario);
    const std::string fault = plant_fault_reason(trace);
    if (!fault.empty()) throw UsageError("the commissioning run is not valid: " + fault);
    samples = identification_samples(trace);
    from = "a simulated commissioning run (" + std::filesystem::path(o.scenario).filename().string() + ", PI alone)";
  } else {
    samples = recorded_samples(o.recording);
    from = o.recording;
  }
  IdentificationParams params;
  params.range_ratio = o.range_ratio;
  params.max_evaluations = o.evaluations;
  IdentifiedLoad id;
  try {
    id = identify_load(configured, samples, params);
  } catch (const std::invalid_argument& e) {
    throw UsageError(from + ": " + e.what());
  }
  std::printf("identified from %s (%zu samples, %u filter runs):\n", from.c_str(), samples.size(), id.evaluations);
  std::printf("  %-46s %14s %14s%s\n", "parameter", "configured", "identified",
              o.simulate ? "     simulated plant" : "");
  const auto row = [&](const char* key, double was, double now, double truth) {
    std::printf("  %-46s %14.6g %14.6g", key, was, now);
    if (o.simulate) std::printf(" %14.6g (%+.1f %%)", truth, 100.0 * (now / truth - 1.0));
    std::printf("\n");
  };
  row("kalman.model.load_mass_kg", configured.kalman.model.load_mass_kg, id.load_mass_kg,
      configured.plant.mechanics.load_mass_kg);
  row("kalman.model.spring_n_per_m", configured.kalman.model.spring_n_per_m, id.spring_n_per_m,
      configured.plant.mechanics.spring_n_per_m);
  row("kalman.friction_input.coulomb_n", configured.kalman.friction_input.model.coulomb_n, id.coulomb_n,
      configured.plant.friction.coulomb_n);
  row("kalman.friction_input.viscous_n_s_per_m", configured.kalman.friction_input.model.viscous_n_s_per_m,
      id.viscous_n_s_per_m, configured.plant.friction.viscous_n_s_per_m);
  const double configured_mode_hz =
      std::sqrt(configured.kalman.model.spring_n_per_m / configured.kalman.model.load_mass_kg) / (2 * M_PI);
  std::printf("  load mode %.2f Hz (configured model %.2f Hz); innovation rms %.3f mm/s (configured model %.3f mm/s)\n",
              id.load_mode_hz(), configured_mode_hz, 1e3 * id.innovation_rms_mps,
              1e3 * id.configured_innovation_rms_mps);
  const SystemParams identified = with_identified_load(configured, id);
  std::printf(
      "  gain scale %.3f: acceleration feedback K_a %.1f kg, RNN force x %.3f (compensator.design_load_mass_kg %.6g)\n",
      identified.compensator_gain_scale(), identified.accel_feedback_params().gain_kg,
      identified.rnn_compensator_params(false).output_scale, identified.compensator.design_load_mass_kg);
  const bool load_unpinned = id.at_bound.find("kalman.model.") != std::string::npos;
  if (!id.at_bound.empty()) {
    std::printf("  at the edge of the search box (x/%.3g of the configured values): %s\n", o.range_ratio,
                id.at_bound.c_str());
  }
  if (load_unpinned) {
    std::printf(
        "identify: the load is not pinned by this run (a longer or richer run, or a wider --range-ratio); "
        "nothing written\n");
    return kExitVerdictFailed;
  }
  if (o.out.empty()) return kExitOk;
  char source[320];
  std::snprintf(source, sizeof source,
                "chosen: identified by pmlsm identify from %s (innovation rms %.3f mm/s against %.3f mm/s with the "
                "values of %s)",
                from.c_str(), 1e3 * id.innovation_rms_mps, 1e3 * id.configured_innovation_rms_mps, o.config.c_str());
  write_system_file_with(o.config, identified_parameters(id), source, o.out, parse_overrides(o.set));
  std::printf("identify: %s written (%zu values, and %zu set with --set); run the nodes with --config %s\n",
              o.out.c_str(), identified_parameters(id).size(), o.set.size(), o.out.c_str());
  return kExitOk;
}

}  // namespace

void add_identify_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<IdentifyOptions>();
  CLI::App* cmd = app.add_subcommand(
      "identify",
      "Commissioning: the load's mass and spring and the bearing friction fitted to a PI-alone run (a "
      "recording's /pmlsm/motor_feedback, or --simulate), written into a copy of the system file");
  cmd->add_option("recording", o->recording, "MCAP recording of the commissioning run");
  cmd->add_flag("--simulate", o->simulate, "Run the commissioning in process on the configured (simulated) plant");
  add_system_file_options(*cmd, o->config, o->set, "The system file whose models are replaced");
  cmd->add_option("-s,--scenario", o->scenario, "With --simulate: the commissioning scenario")
      ->capture_default_str()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--out", o->out, "The system file to write (default: print only)");
  cmd->add_option("--range-ratio", o->range_ratio, "The search box: configured / ratio to configured x ratio")
      ->capture_default_str();
  cmd->add_option("--evaluations", o->evaluations, "Filter runs the search may spend")->capture_default_str();
  cmd->callback([o, &exit_code] {
    try {
      exit_code = run_identify(*o);
    } catch (const ConfigError& e) {
      throw UsageError(std::string("config error: ") + e.what());
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  });
}

}  // namespace pmlsm::tools
