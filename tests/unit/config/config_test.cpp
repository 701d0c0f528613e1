// The config loader's rules (pmlsm/config/config.hpp), one table row per rule: each
// bad input must raise a ConfigError whose message names the origin, the full
// key path and the offending value. Bad inputs are the shipped files with
// small YAML edits, so the tests follow the files as they evolve.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "config_edit.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/sweep_file.hpp"

namespace pmlsm {
namespace {

constexpr const char* kOrigin = "test.yaml";
constexpr double kControlPeriod = 1e-3;

using test::Edit;
using test::edited;
using test::error_of;
using test::read_text;
using test::source_path;

using test::system_text;
const std::string& pulse_text() {
  static const std::string kText = read_text("configs/scenarios/pulse.yaml");
  return kText;
}
const std::string& free_vibration_text() {
  static const std::string kText = read_text("configs/scenarios/free_vibration.yaml");
  return kText;
}

std::string system_error(const std::vector<Edit>& edits, const std::vector<ConfigOverride>& overrides = {}) {
  const std::string text = edited(system_text(), edits);
  return error_of([&] { parse_system_params(text, kOrigin, overrides); });
}

std::string scenario_error(const std::vector<Edit>& edits, const std::vector<ConfigOverride>& overrides = {}) {
  const std::string text = edited(pulse_text(), edits);
  return error_of([&] { parse_scenario(text, kOrigin, kControlPeriod, overrides); });
}

/// Checks that the message starts with the origin and contains every part.
void expect_names(const std::string& message, const std::string& origin, const std::vector<std::string>& parts) {
  if (message.empty()) return;  // error_of has reported the missing error
  EXPECT_EQ(message.rfind(origin + ": ", 0), 0u) << "origin not first in: " << message;
  for (const std::string& part : parts) {
    EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
  }
}

struct Case {
  const char* what;
  std::vector<Edit> edits;
  std::vector<std::string> expected;  ///< substrings: key path, value, reason
};

void expect_system_rejects(const std::vector<Case>& cases) {
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    expect_names(system_error(c.edits), kOrigin, c.expected);
  }
}

void expect_scenario_rejects(const std::vector<Case>& cases) {
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    expect_names(scenario_error(c.edits), kOrigin, c.expected);
  }
}

/// "paper ..." or "chosen:" followed by a reason that is not blank.
bool is_valid_source(const std::string& source) {
  if (source.rfind("paper", 0) == 0) return true;
  return source.rfind("chosen:", 0) == 0 && source.find_first_not_of(" \t", 7) != std::string::npos;
}

// ---------------------------------------------------------------- shipped files

TEST(ConfigShipped, SystemAndScenariosLoad) {
  const SystemParams p = load_system_params(source_path("configs/system.yaml"));
  EXPECT_EQ(p.timing.current_steps_per_tick(), 32);
  const Scenario pulse = load_scenario(source_path("configs/scenarios/pulse.yaml"), p.timing.control_period_s);
  EXPECT_EQ(pulse.name, "pulse");
  EXPECT_EQ(pulse.shape, CommandShape::kPulse);
  const Scenario free = load_scenario(source_path("configs/scenarios/free_vibration.yaml"), p.timing.control_period_s);
  EXPECT_EQ(free.name, "free_vibration");
  EXPECT_EQ(free.shape, CommandShape::kZero);
}

// The edits below re-emit the file; an unedited re-emission must still load,
// or every rejection could come from the emitter rather than the rule.
// The trainer ships the system file to its workers whole, in TrainingSetup.system_yaml, a
// string<65536> (idl/TrainingSetup.idl): the shipped file must fit, or every remote training is
// refused.
TEST(ConfigShipped, TheSystemFileFitsTheTrainingSetupThatCarriesItToWorkers) {
  std::ifstream in(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml", std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_FALSE(text.empty());
  EXPECT_LE(text.size(), 65536u) << "configs/system.yaml grew past TrainingSetup's bound: shorten its sources";
}

TEST(ConfigShipped, ReemittedFilesLoad) {
  EXPECT_NO_THROW(parse_system_params(edited(system_text(), {}), kOrigin));
  EXPECT_NO_THROW(parse_scenario(edited(pulse_text(), {}), kOrigin, kControlPeriod));
}

TEST(ConfigShipped, EveryLeafHasAPaperOrChosenSource) {
  struct File {
    const char* name;
    const std::string& text;
  };
  for (const File& f :
       {File{"system", system_text()}, File{"pulse", pulse_text()}, File{"free_vibration", free_vibration_text()}}) {
    SCOPED_TRACE(f.name);
    const auto leaves = list_leaf_sources(f.text, f.name);
    EXPECT_GE(leaves.size(), 8u);
    for (const SourcedLeaf& leaf : leaves) {
      if (leaf.key_path == "name") continue;  // a scenario's identifier, not a parameter
      EXPECT_TRUE(is_valid_source(leaf.source)) << leaf.key_path << ": '" << leaf.source << "'";
    }
  }
}

// A source says where a value comes from in a sentence or two and points to docs/ for the rest:
// at most 300 characters, in every shipped file that holds sourced values.
TEST(ConfigShipped, EverySourceIsASentenceOrTwo) {
  std::size_t files = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(source_path("configs"))) {
    if (entry.path().extension() != ".yaml") continue;
    const std::string relative = std::filesystem::relative(entry.path(), source_path("")).string();
    const std::string text = read_text(relative);
    if (text.find("source:") == std::string::npos) continue;
    ++files;
    std::size_t from = 0;
    for (std::size_t at; (at = text.find("source: \"", from)) != std::string::npos; from = at + 1) {
      const std::size_t begin = at + 9;
      const std::size_t end = text.find('"', begin);
      ASSERT_NE(end, std::string::npos) << relative;
      const std::size_t line = 1 + static_cast<std::size_t>(std::count(text.begin(), text.begin() + at, '\n'));
      EXPECT_LE(end - begin, 300u) << relative << ":" << line << ": " << text.substr(begin, 80) << "...";
    }
  }
  EXPECT_GE(files, 20u);
}

TEST(ConfigShipped, ValuesMatchThePaper) {
  const SystemParams p = parse_system_params(system_text(), kOrigin);
  EXPECT_DOUBLE_EQ(p.plant.mechanics.motor_mass_kg, 20.0);  // Table 2
  EXPECT_DOUBLE_EQ(p.plant.mechanics.load_mass_kg, 4.0);
  EXPECT_DOUBLE_EQ(p.plant.mechanics.spring_n_per_m, 13700.0);
  EXPECT_DOUBLE_EQ(p.plant.electrical.motor_constant_n_per_a, 94.0);  // Table 3
  EXPECT_DOUBLE_EQ(p.plant.electrical.resistance_ohm, 4.8);
  EXPECT_DOUBLE_EQ(p.plant.electrical.pole_pitch_m, 0.015);
  EXPECT_DOUBLE_EQ(p.velocity_loop.kp_n_s_per_m, 10000.0);
  EXPECT_DOUBLE_EQ(p.velocity_loop.ki_n_per_m, 0.01);
  EXPECT_DOUBLE_EQ(p.reference_model.natural_frequency_rad_s, 100.0);  // eq. 25
  EXPECT_DOUBLE_EQ(p.reference_model.damping_ratio, 1.732);
  // Q is chosen, not the paper's diag(100, 10, 1) of eq. 35 (see its source in
  // system.yaml and tests/unit/estimation/kalman_test.cpp); R is the paper's.
  EXPECT_DOUBLE_EQ(p.kalman.measurement_noise, 0.01);
  EXPECT_DOUBLE_EQ(p.timing.control_period_s, 1e-3);  // section 4.1
  EXPECT_DOUBLE_EQ(p.timing.current_loop_period_s, 31.25e-6);
  EXPECT_DOUBLE_EQ(p.plant.max_step_s, 1e-5);

  const Scenario pulse = parse_scenario(pulse_text(), kOrigin, kControlPeriod);  // section 4.2
  EXPECT_DOUBLE_EQ(pulse.amplitude_mps, 0.2);
  EXPECT_DOUBLE_EQ(pulse.frequency_hz, 1.0);
  EXPECT_DOUBLE_EQ(pulse.cost_window_s, 1.0);
  const Scenario free = parse_scenario(free_vibration_text(), kOrigin, kControlPeriod);
  EXPECT_DOUBLE_EQ(free.initial_load_displacement_m, 0.02);
  EXPECT_DOUBLE_EQ(free.amplitude_mps, 0.0);
}

// ---------------------------------------------------------------- rejections

TEST(ConfigRejects, UnknownKey) {
  expect_system_rejects({
      {"top level", {{"gearbox", "1"}}, {"gearbox: unknown key"}},
      {"nested",
       {{"plant.mechanics.extra_mass_kg", "{value: 1, source: paper}"}},
       {"plant.mechanics.extra_mass_kg: unknown key"}},
      {"nested section", {{"plant.gearbox", "{ratio: 1}"}}, {"plant.gearbox: unknown key"}},
      {"inside a sourced leaf",
       {{"plant.mechanics.load_mass_kg", "{value: 1, source: paper, units: x}"}},
       {"plant.mechanics.load_mass_kg.units: unknown key"}},
  });
  expect_scenario_rejects({
      {"scenario nested", {{"command.phase_rad", "0"}}, {"command.phase_rad: unknown key"}},
  });
}

TEST(ConfigRejects, MissingKey) {
  expect_system_rejects({
      {"leaf", {{"plant.mechanics.load_mass_kg", std::nullopt}}, {"plant.mechanics.load_mass_kg: missing key"}},
      {"section", {{"kalman", std::nullopt}}, {"kalman: missing key"}},
      {"nested section", {{"plant.mechanics", std::nullopt}}, {"plant.mechanics: missing key"}},
  });
  expect_scenario_rejects({
      {"scenario leaf", {{"command.duty_cycle", std::nullopt}}, {"command.duty_cycle: missing key"}},
  });
}

TEST(ConfigRejects, WrongType) {
  const std::string mass = "plant.mechanics.load_mass_kg";
  expect_system_rejects({
      {"string for a number", {{mass + ".value", "abc"}}, {mass + ": expected a number", "'abc'"}},
      {"boolean for a number", {{mass + ".value", "true"}}, {mass + ": expected a number", "'true'"}},
      {"list for a number", {{mass + ".value", "[4]"}}, {mass + ": expected a number", "[4]"}},
      {"map as a sourced value", {{mass + ".value", "{a: 1}"}}, {mass + ": expected a number", "a: 1"}},
      {"map for a value", {{mass, "{a: 1}"}}, {mass + ": expected a value, got a section", "a: 1"}},
      {"value for a section", {{"plant.mechanics", "5"}}, {"plant.mechanics: must be a mapping", "5"}},
      {"list of 2",
       {{"kalman.process_noise_diag.value", "[100, 10]"}},
       {"kalman.process_noise_diag: expected a list of 3 numbers", "[100, 10]"}},
      {"list of 4",
       {{"kalman.process_noise_diag.value", "[100, 10, 1, 1]"}},
       {"kalman.process_noise_diag: expected a list of 3 numbers", "[100, 10, 1, 1]"}},
      {"scalar for a list",
       {{"kalman.process_noise_diag.value", "100"}},
       {"kalman.process_noise_diag: expected a list of 3 numbers", "100"}},
      {"string in a list",
       {{"kalman.process_noise_diag.value", "[100, x, 1]"}},
       {"kalman.process_noise_diag[1]: expected a number", "'x'"}},
      {"negative seed",
       {{"plant.encoder.noise_seed.value", "-1"}},
       {"plant.encoder.noise_seed: expected a non-negative integer", "'-1'"}},
      {"fractional seed",
       {{"plant.encoder.noise_seed.value", "1.5"}},
       {"plant.encoder.noise_seed: expected a non-negative integer", "'1.5'"}},
  });
  expect_scenario_rejects({
      {"scenario string for a number",
       {{"command.amplitude_mps.value", "fast"}},
       {"command.amplitude_mps: expected a number", "'fast'"}},
  });
}

TEST(ConfigRejects, NonFinite) {
  const std::string mass = "plant.mechanics.load_mass_kg";
  const std::string q = "kalman.process_noise_diag";
  expect_system_rejects({
      {"nan", {{mass + ".value", ".nan"}}, {mass + ": must be finite", ".nan"}},
      {"inf", {{mass + ".value", ".inf"}}, {mass + ": must be finite", ".inf"}},
      {"-inf", {{mass + ".value", "-.inf"}}, {mass + ": must be finite", "-.inf"}},
      {"nan in list", {{q + ".value", "[100, .nan, 1]"}}, {q + "[1]: must be finite", ".nan"}},
      {"inf in list", {{q + ".value", "[.inf, 10, 1]"}}, {q + "[0]: must be finite", ".inf"}},
      {"-inf in list", {{q + ".value", "[100, 10, -.inf]"}}, {q + "[2]: must be finite", "-.inf"}},
  });
  expect_scenario_rejects({
      {"scenario nan", {{"duration_s.value", ".nan"}}, {"duration_s: must be finite", ".nan"}},
  });
}

TEST(ConfigRejects, OutOfRange) {
  expect_system_rejects({
      {"negative load mass",
       {{"plant.mechanics.load_mass_kg.value", "-4"}},
       {"plant.mechanics.load_mass_kg: must be in [", "got -4"}},
      {"negative motor mass",
       {{"plant.mechanics.motor_mass_kg.value", "-20"}},
       {"plant.mechanics.motor_mass_kg: must be in [", "got -20"}},
      {"zero resistance",
       {{"plant.electrical.resistance_ohm.value", "0"}},
       {"plant.electrical.resistance_ohm: must be in [", "got 0"}},
      {"zero damping ratio",
       {{"reference_model.damping_ratio.value", "0"}},
       {"reference_model.damping_ratio: must be in [", "got 0"}},
      {"negative damping ratio",
       {{"reference_model.damping_ratio.value", "-1.5"}},
       {"reference_model.damping_ratio: must be in [", "got -1.5"}},
      // L_md^2 = L_ad L_D exactly (0.02^2 both sides): the boundary is excluded.
      {"L_md^2 = L_ad L_D",
       {{"plant.electrical.mutual_d_inductance_h.value", "0.02"},
        {"plant.electrical.damper_d_inductance_h.value", "0.02"}},
       {"plant.electrical.mutual_d_inductance_h: must satisfy L_md^2 < L_ad L_D", "got 0.02"}},
      {"L_md^2 > L_ad L_D",
       {{"plant.electrical.mutual_d_inductance_h.value", "0.5"}},
       {"plant.electrical.mutual_d_inductance_h: must satisfy L_md^2 < L_ad L_D", "got 0.5"}},
      // 1 ms / 0.25 ms would divide; 1 ms / 0.4 ms = 2.5 does not.
      {"current period not dividing",
       {{"timing.current_loop_period_s.value", "0.0004"}},
       {"timing.current_loop_period_s: must divide control_period_s", "got 0.0004"}},
      {"current period above control period",
       {{"timing.current_loop_period_s.value", "0.002"}},
       {"timing.current_loop_period_s: must be in", "got 0.002"}},
  });
  expect_scenario_rejects({
      {"duty cycle above 1",
       {{"command.duty_cycle.value", "1.5"}},
       {"command.duty_cycle: must be in [0, 1]", "got 1.5"}},
      {"unknown shape", {{"command.shape.value", "square"}}, {"command.shape", "'square'", "zero, step, pulse, sine"}},
  });
}

TEST(ConfigRejects, SourcedLeafWithoutValidSource) {
  const std::string mass = "plant.mechanics.load_mass_kg";
  expect_system_rejects({
      {"no source", {{mass, "{value: 4}"}}, {mass + ".source: missing"}},
      {"source is a list", {{mass, "{value: 4, source: [paper]}"}}, {mass + ".source: missing"}},
      {"neither paper nor chosen",
       {{mass + ".source", "Table 2"}},
       {mass + ".source: must start with 'paper' or 'chosen: <reason>'", "'Table 2'"}},
      {"empty source", {{mass + ".source", "''"}}, {mass + ".source: must start with", "''"}},
      {"chosen without reason", {{mass + ".source", "'chosen:'"}}, {mass + ".source: must start with", "'chosen:'"}},
      {"chosen with a blank reason",
       {{mass + ".source", "'chosen:     '"}},
       {mass + ".source: must start with", "'chosen:     '"}},
  });
  // list_leaf_sources applies the same check.
  const std::string text = edited(system_text(), {{mass + ".source", "Table 2"}});
  expect_names(error_of([&] { list_leaf_sources(text, kOrigin); }), kOrigin, {mass + ".source", "'Table 2'"});
}

TEST(ConfigRejects, MalformedYamlAndNonMappingTopLevel) {
  const std::vector<std::pair<std::string, std::string>> texts = {
      {"parse error", "timing: {control_period_s: [1\n"},
      {"parse error, bad indent", "timing:\n  a: 1\n b: 2\n"},
      {"list", "- 1\n- 2\n"},
      {"scalar", "42\n"},
      {"empty", ""},
  };
  for (const auto& entry : texts) {
    const std::string& what = entry.first;
    const std::string& text = entry.second;
    SCOPED_TRACE(what);
    const std::string expected = what.rfind("parse error", 0) == 0 ? "YAML parse error" : "top level must be a mapping";
    expect_names(error_of([&] { parse_system_params(text, kOrigin); }), kOrigin, {expected});
    expect_names(error_of([&] { parse_scenario(text, kOrigin, kControlPeriod); }), kOrigin, {expected});
    expect_names(error_of([&] { list_leaf_sources(text, kOrigin); }), kOrigin, {expected});
  }
  // The parse error says where.
  expect_names(error_of([&] { parse_system_params(texts[1].second, kOrigin); }), kOrigin, {"line 3"});
}

// ---------------------------------------------------------------- overrides and files

TEST(ConfigOverrides, ParsesKeyPathAndValue) {
  const ConfigOverride o = ConfigOverride::parse("a.b=1");
  EXPECT_EQ(o.key_path, "a.b");
  EXPECT_EQ(o.value, "1");
  EXPECT_EQ(ConfigOverride::parse("a=x=y").value, "x=y");  // split at the first '='
}

TEST(ConfigOverrides, RejectsTextWithoutKeyOrEquals) {
  for (const std::string text : {"a.b", "=1", ""}) {
    SCOPED_TRACE(text);
    const std::string message = error_of([&] { ConfigOverride::parse(text); });
    EXPECT_NE(message.find("'" + text + "'"), std::string::npos) << message;
  }
}

TEST(ConfigOverrides, ChangesTheValue) {
  const auto p = parse_system_params(system_text(), kOrigin,
                                     {ConfigOverride::parse("plant.mechanics.load_mass_kg=5"),
                                      ConfigOverride::parse("kalman.process_noise_diag=[1, 2, 3]")});
  EXPECT_DOUBLE_EQ(p.plant.mechanics.load_mass_kg, 5.0);
  EXPECT_DOUBLE_EQ(p.kalman.process_noise_diag(2), 3.0);
  const auto s =
      parse_scenario(pulse_text(), kOrigin, kControlPeriod, {ConfigOverride::parse("command.amplitude_mps=0.5")});
  EXPECT_DOUBLE_EQ(s.amplitude_mps, 0.5);
}

TEST(ConfigOverrides, RejectsUnknownPathOrSection) {
  expect_names(system_error({}, {ConfigOverride::parse("plant.mechanics.nonexistent_key=1")}), kOrigin,
               {"plant.mechanics.nonexistent_key"});
  expect_names(system_error({}, {ConfigOverride::parse("nonexistent.load_mass_kg=1")}), kOrigin,
               {"nonexistent.load_mass_kg"});
  expect_names(system_error({}, {ConfigOverride::parse("plant.mechanics=1")}), kOrigin, {"plant.mechanics", "section"});
}

TEST(ConfigOverrides, RejectsBadValueWithKeyPath) {
  expect_names(system_error({}, {ConfigOverride::parse("plant.mechanics.load_mass_kg=-4")}), kOrigin,
               {"plant.mechanics.load_mass_kg: must be in [", "got -4"});
  expect_names(system_error({}, {ConfigOverride::parse("plant.mechanics.load_mass_kg=abc")}), kOrigin,
               {"plant.mechanics.load_mass_kg: expected a number", "'abc'"});
  expect_names(scenario_error({}, {ConfigOverride::parse("command.duty_cycle=1.5")}), kOrigin,
               {"command.duty_cycle", "got 1.5"});
  // A value that is not YAML at all (an unclosed list) must still be a ConfigError.
  expect_names(system_error({}, {ConfigOverride::parse("plant.mechanics.load_mass_kg=[1")}), kOrigin,
               {"plant.mechanics.load_mass_kg", "[1"});
}

TEST(ConfigFiles, ErrorsNameTheFilePath) {
  const std::string missing = source_path("configs/no_such_file.yaml");
  expect_names(error_of([&] { load_system_params(missing); }), missing, {"cannot open"});
  expect_names(error_of([&] { load_scenario(missing, kControlPeriod); }), missing, {"cannot open"});
  // A rule broken in a real file is reported against its path.
  const std::string shipped = source_path("configs/system.yaml");
  expect_names(
      error_of([&] { load_system_params(shipped, {ConfigOverride::parse("plant.mechanics.load_mass_kg=-4")}); }),
      shipped, {"plant.mechanics.load_mass_kg", "-4"});
}

// `pmlsm identify` writes its values into a copy of the system file: that copy loads with every
// check, holds the values to the last bit with the given source, and nothing else changed.
// Every kind of file the config library reads (each through its shared reader) names the file,
// the key path, the line and the value of a value of the wrong kind. The edit replaces one value
// in place, so the line is the shipped file's.
TEST(ConfigFiles, EveryFileKindNamesTheFileKeyLineAndValueOfABadValue) {
  const SystemParams nominal = parse_system_params(system_text(), kOrigin);
  struct Kind {
    const char* file;
    std::string shipped;  ///< the value as the file writes it
    std::string key;      ///< the key path the error must name
    std::function<void(const std::string& text, const std::string& origin)> parse;
  };
  const std::vector<Kind> kinds = {
      {"configs/system.yaml", "load_mass_kg: {value: 4.0,", "plant.mechanics.load_mass_kg",
       [](const std::string& text, const std::string& origin) { parse_system_params(text, origin); }},
      {"configs/scenarios/pulse.yaml", "duty_cycle: {value: 0.5,", "command.duty_cycle",
       [](const std::string& text, const std::string& origin) { parse_scenario(text, origin, kControlPeriod); }},
      {"configs/training.yaml", "mutation_factor: {value: 0.8,", "mutation_factor",
       [](const std::string& text, const std::string& origin) { parse_training_params(text, origin, kControlPeriod); }},
      {"configs/sweeps/plant_family.yaml", "random: {value: 50,", "plants.random",
       [&nominal](const std::string& text, const std::string& origin) { parse_sweep_file(text, origin, nominal); }},
      {"configs/canopen/drive.yaml", "heartbeat_ms: {value: 100,", "drive.heartbeat_ms",
       [](const std::string& text, const std::string& origin) { parse_canopen_config(text, origin); }},
  };
  for (const Kind& kind : kinds) {
    SCOPED_TRACE(kind.file);
    std::string text = read_text(kind.file);
    const std::size_t at = text.find(kind.shipped);
    ASSERT_NE(at, std::string::npos) << kind.shipped;
    const std::size_t line = 1 + static_cast<std::size_t>(std::count(text.begin(), text.begin() + at, '\n'));
    const std::size_t value_at = text.find("value: ", at) + 7;
    text.replace(value_at, text.find(',', value_at) - value_at, "abc");
    // The real path: files named inside (a training file's scenarios) are found beside it.
    const std::string origin = source_path(kind.file);
    expect_names(error_of([&] { kind.parse(text, origin); }), origin,
                 {kind.key + ":", "'abc'", "line " + std::to_string(line)});
  }
}

TEST(ConfigFiles, AWrittenCopyHoldsTheValuesAndTheirSource) {
  const std::string shipped = source_path("configs/system.yaml");
  const std::string out = ::testing::TempDir() + "/system_written.yaml";
  const double mass = 2.2124853533629811;
  write_system_file_with(shipped, {{"kalman.model.load_mass_kg", mass}, {"kalman.friction_input.coulomb_n", 12.5}},
                         "chosen: identified (test)", out);
  const SystemParams before = load_system_params(shipped), after = load_system_params(out);
  EXPECT_EQ(after.kalman.model.load_mass_kg, mass);
  EXPECT_EQ(after.kalman.friction_input.model.coulomb_n, 12.5);
  EXPECT_EQ(after.plant.mechanics.load_mass_kg, before.plant.mechanics.load_mass_kg);
  EXPECT_EQ(after.compensator.acceleration_feedback.gain_kg, before.compensator.acceleration_feedback.gain_kg);
  const YAML::Node written = YAML::LoadFile(out);
  EXPECT_EQ(written["kalman"]["model"]["load_mass_kg"]["source"].as<std::string>(), "chosen: identified (test)");
  EXPECT_EQ(written["kalman"]["model"]["spring_n_per_m"]["source"].as<std::string>().rfind("paper", 0), 0u);
  // Refused, naming the problem, with nothing written.
  const std::string refused = ::testing::TempDir() + "/system_refused.yaml";
  expect_names(error_of([&] {
                 write_system_file_with(shipped, {{"kalman.model.mass", 2.0}}, "chosen: x", refused);
               }),
               shipped, {"kalman.model.mass"});
  expect_names(error_of([&] {
                 write_system_file_with(shipped, {{"kalman.model.load_mass_kg", -2.0}}, "chosen: x", refused);
               }),
               refused, {"kalman.model.load_mass_kg", "-2"});
  expect_names(error_of([&] { write_system_file_with(shipped, std::vector<ConfigOverride>{}, "identified", refused); }),
               refused, {"'chosen: <reason>'"});
  EXPECT_FALSE(std::ifstream(refused).good());
}

// The command that writes a copy (identify, commission) ran on the file with its --set: those go
// into the copy too, under their own source, so a simulated plant changed with --set stays the
// plant the copy's models were measured on. A written value wins over a --set of the same key.
TEST(ConfigFiles, AWrittenCopyKeepsTheCommandLinesSetValues) {
  const std::string shipped = source_path("configs/system.yaml");
  const std::string out = ::testing::TempDir() + "/system_written_set.yaml";
  write_system_file_with(
      shipped, {{"kalman.model.load_mass_kg", 7.5}}, "chosen: identified (test)", out,
      {ConfigOverride::parse("plant.mechanics.load_mass_kg=8"), ConfigOverride::parse("kalman.model.load_mass_kg=3")});
  const SystemParams after = load_system_params(out);
  EXPECT_EQ(after.plant.mechanics.load_mass_kg, 8.0);
  EXPECT_EQ(after.kalman.model.load_mass_kg, 7.5);
  const YAML::Node written = YAML::LoadFile(out);
  EXPECT_NE(written["plant"]["mechanics"]["load_mass_kg"]["source"].as<std::string>().find("--set"), std::string::npos);
  EXPECT_EQ(written["kalman"]["model"]["load_mass_kg"]["source"].as<std::string>(), "chosen: identified (test)");
  // A --set that names no key is refused, nothing written.
  const std::string refused = ::testing::TempDir() + "/system_refused_set.yaml";
  expect_names(error_of([&] {
                 write_system_file_with(shipped, {{"kalman.model.load_mass_kg", 7.5}}, "chosen: x", refused,
                                        {ConfigOverride::parse("plant.mass=8")});
               }),
               shipped, {"plant.mass"});
  EXPECT_FALSE(std::ifstream(refused).good());
}

// ------------------------------------------- the Kalman filter's disturbance inputs

TEST(ConfigKalmanInputs, ShippedValuesAreThePlantsAndLoad) {
  const SystemParams p = parse_system_params(system_text(), kOrigin);
  // The identified models a rig would have: here the simulated plant's (10), (11).
  EXPECT_DOUBLE_EQ(p.kalman.friction_input.model.coulomb_n, p.plant.friction.coulomb_n);
  EXPECT_DOUBLE_EQ(p.kalman.friction_input.model.viscous_n_s_per_m, p.plant.friction.viscous_n_s_per_m);
  EXPECT_GT(p.kalman.friction_input.model.regularisation_velocity_mps, 0.0);
  EXPECT_DOUBLE_EQ(p.kalman.ripple_input.model.scale_n, p.plant.ripple.scale_n);
  EXPECT_DOUBLE_EQ(p.kalman.ripple_input.model.amplitude_1, p.plant.ripple.amplitude_1);
  EXPECT_DOUBLE_EQ(p.kalman.ripple_input.model.amplitude_2, p.plant.ripple.amplitude_2);
  EXPECT_DOUBLE_EQ(p.kalman.ripple_input.model.spatial_freq_1_rad_per_m, p.plant.ripple.spatial_freq_1_rad_per_m);
  EXPECT_DOUBLE_EQ(p.kalman.ripple_input.model.spatial_freq_2_rad_per_m, p.plant.ripple.spatial_freq_2_rad_per_m);
  // And they reach the filter.
  const KalmanParams kp = p.kalman_params();
  EXPECT_EQ(kp.friction_input.enabled, p.kalman.friction_input.enabled);
  EXPECT_EQ(kp.ripple_input.enabled, p.kalman.ripple_input.enabled);
  EXPECT_DOUBLE_EQ(kp.friction_input.model.coulomb_n, p.kalman.friction_input.model.coulomb_n);
  EXPECT_DOUBLE_EQ(kp.ripple_input.model.scale_n, p.kalman.ripple_input.model.scale_n);
}

TEST(ConfigKalmanModel, IsTheFiltersOwnSoAPlantOverrideLeavesItNominal) {
  const std::string path = std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml";
  const SystemParams nominal = load_system_params(path);
  EXPECT_DOUBLE_EQ(nominal.kalman.model.load_mass_kg, nominal.plant.mechanics.load_mass_kg);
  EXPECT_DOUBLE_EQ(nominal.kalman.model.motor_mass_kg, nominal.plant.mechanics.motor_mass_kg);
  EXPECT_DOUBLE_EQ(nominal.kalman.model.spring_n_per_m, nominal.plant.mechanics.spring_n_per_m);
  // A heavier load and a stiffer coupling in the plant: the filter keeps the nominal model.
  const SystemParams mismatched =
      load_system_params(path, {ConfigOverride::parse("plant.mechanics.load_mass_kg=2"),
                                ConfigOverride::parse("plant.mechanics.spring_n_per_m=27400")});
  EXPECT_DOUBLE_EQ(mismatched.plant.mechanics.load_mass_kg, 2.0);
  EXPECT_DOUBLE_EQ(mismatched.kalman_params().model.load_mass_kg, 4.0);
  EXPECT_DOUBLE_EQ(mismatched.kalman_params().model.spring_n_per_m, 13700.0);
  // And the model alone.
  const SystemParams model = load_system_params(path, {ConfigOverride::parse("kalman.model.load_mass_kg=8")});
  EXPECT_DOUBLE_EQ(model.kalman_params().model.load_mass_kg, 8.0);
  EXPECT_DOUBLE_EQ(model.plant.mechanics.load_mass_kg, 4.0);
}

TEST(ConfigKalmanInputs, OverridesSwitchThemOnAndOff) {
  for (const char* value : {"true", "false"}) {
    SCOPED_TRACE(value);
    const bool on = std::string(value) == "true";
    const auto p =
        parse_system_params(system_text(), kOrigin,
                            {ConfigOverride::parse(std::string("kalman.friction_input.enabled=") + value),
                             ConfigOverride::parse(std::string("kalman.ripple_input.enabled=") + value),
                             ConfigOverride::parse("kalman.friction_input.regularisation_velocity_mps=0.005")});
    EXPECT_EQ(p.kalman.friction_input.enabled, on);
    EXPECT_EQ(p.kalman.ripple_input.enabled, on);
    EXPECT_DOUBLE_EQ(p.kalman.friction_input.model.regularisation_velocity_mps, 0.005);
  }
}

TEST(ConfigKalmanInputs, BadValuesAreRejectedWithKeyPathAndValue) {
  const std::string f = "kalman.friction_input";
  const std::string r = "kalman.ripple_input";
  expect_system_rejects({
      {"negative coulomb", {{f + ".coulomb_n.value", "-20"}}, {f + ".coulomb_n: must be in [", "got -20"}},
      {"negative viscous",
       {{f + ".viscous_n_s_per_m.value", "-30"}},
       {f + ".viscous_n_s_per_m: must be in [", "got -30"}},
      {"zero smoothing",
       {{f + ".regularisation_velocity_mps.value", "0"}},
       {f + ".regularisation_velocity_mps: must be in [", "got 0"}},
      {"nan coulomb", {{f + ".coulomb_n.value", ".nan"}}, {f + ".coulomb_n: must be finite", ".nan"}},
      {"inf smoothing",
       {{f + ".regularisation_velocity_mps.value", ".inf"}},
       {f + ".regularisation_velocity_mps: must be finite", ".inf"}},
      {"negative ripple scale", {{r + ".scale_n.value", "-10"}}, {r + ".scale_n: must be in [", "got -10"}},
      {"negative ripple frequency",
       {{r + ".spatial_freq_2_rad_per_m.value", "-1"}},
       {r + ".spatial_freq_2_rad_per_m: must be in [", "got -1"}},
      {"number for a flag", {{f + ".enabled.value", "2"}}, {f + ".enabled: expected true or false", "'2'"}},
      {"word for a flag", {{r + ".enabled.value", "maybe"}}, {r + ".enabled: expected true or false", "'maybe'"}},
      {"unknown key", {{f + ".static_n", "{value: 25, source: paper}"}}, {f + ".static_n: unknown key"}},
      {"unknown ripple key", {{r + ".phase_rad", "{value: 0, source: paper}"}}, {r + ".phase_rad: unknown key"}},
      {"missing section", {{f, std::nullopt}}, {f + ": missing key"}},
      {"missing flag", {{r + ".enabled", std::nullopt}}, {r + ".enabled: missing key"}},
  });
  // On the command line too.
  expect_names(system_error({}, {ConfigOverride::parse(f + ".coulomb_n=-1")}), kOrigin,
               {f + ".coulomb_n: must be in [", "got -1"});
}

}  // namespace
}  // namespace pmlsm
