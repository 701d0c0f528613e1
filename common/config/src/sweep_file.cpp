#include "pmlsm/config/sweep_file.hpp"

#include <stdexcept>
#include <utility>

#include "config_reading.hpp"

namespace pmlsm {

using namespace config_reading;

namespace {

VerdictParams read_verdict(Section verdict) {
  VerdictParams out;
  out.tail_s = verdict.number("tail_s");
  out.tail_windows = verdict.unsigned_integer("tail_windows");
  out.limit_cycle_amplitude_m = verdict.number("limit_cycle_amplitude_m");
  out.min_decay_rate_per_s = verdict.number("min_decay_rate_per_s");
  out.max_saturated_tail_share = verdict.number("max_saturated_tail_share");
  out.max_free_vibration_settling_s = verdict.number("max_free_vibration_settling_s");
  out.rest_command_band_mps = verdict.number("rest_command_band_mps");
  out.min_rest_s = verdict.number("min_rest_s");
  out.max_rest_stretch_peak_m = verdict.number("max_rest_stretch_peak_m");
  out.max_rest_compensation_rms_n = verdict.number("max_rest_compensation_rms_n");
  out.max_forced_ratio_to_pi = verdict.number("max_forced_ratio_to_pi");
  verdict.finish();
  return out;
}

}  // namespace

SweepFile parse_sweep_file(const std::string& yaml_text, const std::string& origin, const SystemParams& nominal,
                           const std::vector<ConfigOverride>& overrides) {
  YAML::Node root = parse_yaml(yaml_text, origin);
  apply_overrides(root, overrides, origin);
  Section top(root, origin, "");
  SweepFile out;
  SweepSpec& spec = out.spec;

  Section plants = top.child("plants");
  spec.sampling.grid_points = plants.unsigned_integer("grid_points");
  spec.sampling.centre = plants.flag("centre");
  spec.sampling.random = plants.unsigned_integer("random");
  spec.sampling.seed = plants.unsigned_integer("seed");
  std::vector<Section> parameters = plants.sections("parameters");
  for (std::size_t i = 0; i < parameters.size(); ++i) {
    Section& p = parameters[i];
    SweepRange range;
    range.key_path = p.text("key");
    range.min = p.number("min");
    range.max = p.number("max");
    const std::string source = p.text("source");
    p.finish();
    // Each range checked here, so that the message names its line.
    try {
      range.validate(nominal);
    } catch (const std::invalid_argument& e) {
      throw ConfigError(origin + ": plants.parameters[" + std::to_string(i) + "]: " + e.what() + p.line());
    }
    if (source.rfind("paper", 0) != 0 && source.rfind("chosen:", 0) != 0) {
      throw ConfigError(origin + ": plants.parameters[" + std::to_string(i) +
                        "].source: must start with 'paper' or 'chosen: <reason>', got '" + source + "'" + p.line());
    }
    spec.ranges.push_back(range);
  }
  plants.finish();

  for (const std::string& name : top.texts("compensators")) {
    try {
      spec.compensators.push_back(compensator_kind_from_string(name));
    } catch (const std::invalid_argument& e) {
      throw ConfigError(origin + ": compensators: " + e.what());
    }
  }
  out.weights_path = relative_to(origin, top.text("rnn_weights"));
  for (const std::string& file : top.texts("scenarios")) {
    out.scenario_files.push_back(relative_to(origin, file));
    spec.scenarios.push_back(load_scenario(out.scenario_files.back(), nominal.timing.control_period_s));
  }

  spec.verdict = read_verdict(top.child("verdict"));
  ModelsSection models = read_models_section(top, origin, nominal.timing.control_period_s);
  spec.identify_models = models.identify;
  out.identification_scenario_file = models.identification_scenario_file;
  spec.identification_scenario = std::move(models.identification_scenario);
  top.finish();
  validate_in(origin, [&] { spec.validate(nominal); });
  return out;
}

VerdictParams load_sweep_verdict(const std::string& path) {
  const std::string text = read_file(path);
  YAML::Node root = parse_yaml(text, path);
  Section top(root, path, "");
  VerdictParams verdict = read_verdict(top.child("verdict"));
  validate_in(path, [&] { verdict.validate(); });
  return verdict;
}

SweepFile load_sweep_file(const std::string& path, const SystemParams& nominal,
                          const std::vector<ConfigOverride>& overrides) {
  return parse_sweep_file(read_file(path), path, nominal, overrides);
}

}  // namespace pmlsm
