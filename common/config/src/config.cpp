#include "pmlsm/config/config.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/ethercat_config.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "pmlsm/util/atomic_file.hpp"
#include "pmlsm/util/validate.hpp"
#include "config_reading.hpp"
#include "pmlsm/config/sweep_file.hpp"
#include "yaml_document.hpp"

namespace pmlsm {

using namespace config_reading;

ConfigOverride ConfigOverride::parse(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ConfigError("override '" + text + "': expected key.path=value");
  }
  return ConfigOverride{text.substr(0, eq), text.substr(eq + 1)};
}

std::vector<ConfigOverride> parse_overrides(const std::vector<std::string>& texts) {
  std::vector<ConfigOverride> out;
  for (const std::string& t : texts) out.push_back(ConfigOverride::parse(t));
  return out;
}

namespace {

// Reads a file by its parameter table (pmlsm/util/parameter_table.hpp: visit_parameters of
// SystemParams for configs/system.yaml, visit_rig_parameters for configs/canopen/drive.yaml): each
// entry's key path must be present with a value of its kind; every key the table does not name is
// unknown. The ranges are checked afterwards by the params' validate(), through validate() here,
// which adds the line of the key an error names.
class TableReader {
 public:
  TableReader(YAML::Node root, std::string origin) : root_(std::move(root)), origin_(std::move(origin)) {}

  void real(const std::string& path, double& out, const Plausible&) { out = number(leaf(path), path); }

  template <typename T>
  void integer(const std::string& path, T& out, const Plausible& range) {
    const std::uint64_t x = whole_number(leaf(path), path);
    if (static_cast<double>(x) > range.max) out_of_range(path, static_cast<double>(x), range);
    out = static_cast<T>(x);
  }

  void flag(const std::string& path, bool& out) {
    const YAML::Node v = leaf(path);
    if (!v.IsScalar() || !YAML::convert<bool>::decode(v, out)) {
      fail(path, "expected true or false, got '" + describe(v) + "'");
    }
  }

  template <typename E>
  void choice(const std::string& path, E& out, E (*from_string)(const std::string&),
              const char* /*live_at*/ = nullptr) {
    const YAML::Node v = leaf(path);
    if (!v.IsScalar()) fail(path, "expected a name, got '" + describe(v) + "'");
    try {
      out = from_string(v.Scalar());
    } catch (const std::invalid_argument& e) {
      fail(path, e.what());
    }
  }

  void vector3(const std::string& path, Eigen::Vector3d& out, const Plausible&) {
    const YAML::Node v = leaf(path);
    if (!v.IsSequence() || v.size() != 3) {
      fail(path, "expected a list of 3 numbers, got '" + describe(v) + "'");
    }
    for (std::size_t i = 0; i < 3; ++i) {
      out(static_cast<Eigen::Index>(i)) = number(v[i], path + "[" + std::to_string(i) + "]");
    }
  }

  void integer_list(const std::string& path, std::vector<int>& out, const Plausible& range) {
    const YAML::Node v = leaf(path);
    if (!v.IsSequence() || v.size() == 0) {
      fail(path, "expected a list of integers, got '" + describe(v) + "'");
    }
    out.clear();
    for (std::size_t i = 0; i < v.size(); ++i) {
      const std::string at = path + "[" + std::to_string(i) + "]";
      const std::uint64_t x = whole_number(v[i], at);
      if (static_cast<double>(x) > range.max) out_of_range(at, static_cast<double>(x), range);
      out.push_back(static_cast<int>(x));
    }
  }

  /// Every key of the file that no table entry named is unknown.
  void finish() const { check_known(root_, ""); }

  /// Runs the checks of what was read (a validate()): an error names the file, and the line of the
  /// key it starts with ("plant.mechanics.load_mass_kg: must be ...").
  template <typename Check>
  void validate(Check&& check) const {
    validate_in(origin_, [&] {
      try {
        check();
      } catch (const std::invalid_argument& e) {
        const std::string what = e.what();
        throw std::invalid_argument(what + line_of_key(what.substr(0, what.find(':'))));
      }
    });
  }

 private:
  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    fail_at(origin_, path, what + line_of_key(path));
  }

  [[noreturn]] void out_of_range(const std::string& path, double value, const Plausible& range) const {
    fail(path, "must be in [" + format_value(range.min) + ", " + format_value(range.max) + "] (" + range.reason +
                   "), got " + format_value(value));
  }

  double number(const YAML::Node& v, const std::string& path) const {
    return with_line_of(v, [&] { return to_number(v, origin_, path); });
  }

  std::uint64_t whole_number(const YAML::Node& v, const std::string& path) const {
    return with_line_of(v, [&] { return to_whole_number(v, origin_, path); });
  }

  std::string line_of_key(const std::string& path) const {
    const auto found = lines_.find(path);
    return found != lines_.end() ? found->second : std::string();
  }

  // The value at a key path; every section on the way must be a mapping and
  // every key present. Marks the path and its sections as known.
  YAML::Node leaf(const std::string& path) {
    YAML::Node node = root_;
    std::string walked;
    std::stringstream parts(path);
    for (std::string key; std::getline(parts, key, '.');) {
      if (!node.IsMap() || is_sourced_leaf(node)) {
        fail(walked, "must be a mapping of keys, got '" + describe(node) + "'");
      }
      const YAML::Node child = static_cast<const YAML::Node&>(node)[key];
      if (!child) fail_at(origin_, join(walked, key), "missing key" + line_of(node));
      walked = join(walked, key);
      known_.insert(walked);
      node.reset(child);
    }
    lines_[path] = line_of(node);
    return with_line_of(node, [&] { return leaf_value(node, origin_, path); });
  }

  void check_known(const YAML::Node& node, const std::string& path) const {
    if (!node.IsMap() || is_sourced_leaf(node)) return;
    for (const auto& kv : node) {
      const std::string key = join(path, kv.first.as<std::string>());
      if (known_.count(key) == 0) fail_at(origin_, key, "unknown key" + line_of(kv.first));
      check_known(kv.second, key);
    }
  }

  YAML::Node root_;
  std::string origin_;
  std::set<std::string> known_;
  std::map<std::string, std::string> lines_;  ///< key path -> " (line N)" of the keys read
};

// Writes a section's declared defaults into the document for every entry it does not name, so a
// system file (and --set) may leave a section out or name only some of its entries; what the file
// holds in a section's place that is not a mapping is left to TableReader to refuse.
class SectionDefaults final : public SectionVisitor {
 public:
  explicit SectionDefaults(YAML::Node root) : root_(std::move(root)) {}
  void real(const std::string& path, double& value, const Plausible&) override { fill(path, format_value(value)); }
  void integer(const std::string& path, std::int64_t& value, const Plausible&) override {
    fill(path, std::to_string(value));
  }
  void flag(const std::string& path, bool& value) override { fill(path, value ? "true" : "false"); }

 private:
  void fill(const std::string& path, const std::string& text) {
    YAML::Node node = root_;
    std::stringstream parts(path);
    std::vector<std::string> keys;
    for (std::string key; std::getline(parts, key, '.');) keys.push_back(key);
    for (std::size_t i = 0; i + 1 < keys.size(); ++i) {
      if (!node.IsMap() && !node.IsNull()) return;
      if (!node[keys[i]]) node[keys[i]] = YAML::Node(YAML::NodeType::Map);
      node.reset(node[keys[i]]);
    }
    if (!node.IsMap() || node[keys.back()]) return;
    node[keys.back()] = text;
  }

  YAML::Node root_;
};

}  // namespace

SystemParams parse_system_params(const std::string& yaml_text, const std::string& origin,
                                 const std::vector<ConfigOverride>& overrides) {
  YAML::Node root = parse_yaml(yaml_text, origin);
  SystemParams p;
  p.sections = registered_parameter_sections();
  if (root.IsMap()) {
    SectionDefaults defaults(root);
    for (const ParameterSection& section : p.sections) section.visit(section, p.section_values, defaults);
    p.section_values.clear();
  }
  apply_overrides(root, overrides, origin);
  TableReader reader(root, origin);
  visit_parameters(p, reader);
  reader.finish();
  reader.validate([&] { p.validate(); });
  return p;
}

std::string read_config_file(const std::string& path) { return read_file(path); }

SystemParams load_system_params(const std::string& path, const std::vector<ConfigOverride>& overrides) {
  return parse_system_params(read_file(path), path, overrides);
}

std::string write_system_file_with(const std::string& in_path,
                                   const std::vector<std::pair<std::string, double>>& values, const std::string& source,
                                   const std::string& out_path, const std::vector<ConfigOverride>& command_line) {
  std::vector<ConfigOverride> texts;
  texts.reserve(values.size());
  for (const auto& [key, value] : values) texts.push_back({key, format_value(value)});
  return write_system_file_with(in_path, texts, source, out_path, command_line);
}

std::string write_system_file_with(const std::string& in_path, const std::vector<ConfigOverride>& values,
                                   const std::string& source, const std::string& out_path,
                                   const std::vector<ConfigOverride>& command_line) {
  if (source.rfind("chosen:", 0) != 0 || source.find_first_not_of(" \t", 7) == std::string::npos) {
    throw ConfigError(out_path + ": the source of the written values must be 'chosen: <reason>', got '" + source + "'");
  }
  YAML::Node root = parse_yaml(read_file(in_path), in_path);
  apply_overrides(root, command_line, in_path, "chosen: set on the command line that wrote this file (--set)");
  apply_overrides(root, values, in_path, source);
  YAML::Emitter out;
  out.SetIndent(2);
  out << root;
  if (!out.good()) throw ConfigError(out_path + ": cannot render: " + out.GetLastError());
  const std::string text =
      "# Written from " + in_path + " with " + std::to_string(values.size() + command_line.size()) +
      " values replaced (their source says by what); the comments are in that file.\n" + out.c_str() + "\n";
  parse_system_params(text, out_path);  // every check, before anything is replaced
  try {
    write_file_atomically(out_path, text);
  } catch (const AtomicWriteError& e) {
    throw ConfigError(out_path + ": not written: " + e.what());
  }
  return text;
}

namespace {

// A value named from a fixed list (a shape, an objective): the list's error, prefixed by the key.
template <typename E>
E named_choice(const std::string& origin, const char* key, const std::string& text,
               E (*from_string)(const std::string&)) {
  E out{};
  validate_in(origin, [&] {
    try {
      out = from_string(text);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string(key) + ": " + e.what());
    }
  });
  return out;
}

// The keys of `command:` after its shape: each shape has its own, all required (a key of another
// shape is unknown when the section is finished).
void read_command_keys(Section& cmd, Scenario& s, const std::string& origin, double control_period_s) {
  switch (s.shape) {
    case CommandShape::kZero:
    case CommandShape::kStep:
    case CommandShape::kPulse:
    case CommandShape::kSine:
      s.amplitude_mps = cmd.number("amplitude_mps");
      s.frequency_hz = cmd.number("frequency_hz");
      s.duty_cycle = cmd.number("duty_cycle");
      break;
    case CommandShape::kSCurve: s.jerk_mps3 = cmd.number("jerk_mps3"); [[fallthrough]];
    case CommandShape::kTrapezoid: s.hold_s = cmd.number("hold_s"); [[fallthrough]];
    case CommandShape::kRamp:
      s.amplitude_mps = cmd.number("amplitude_mps");
      s.accel_mps2 = cmd.number("accel_mps2");
      s.start_s = cmd.number("start_s");
      break;
    case CommandShape::kChirp:
      s.amplitude_mps = cmd.number("amplitude_mps");
      s.frequency_hz = cmd.number("start_frequency_hz");
      s.end_frequency_hz = cmd.number("end_frequency_hz");
      s.sweep_s = cmd.number("sweep_s");
      break;
    case CommandShape::kMultiSine:
      for (Section& term : cmd.sections("components")) {
        SineComponent c;
        c.amplitude_mps = term.number("amplitude_mps");
        c.frequency_hz = term.number("frequency_hz");
        c.phase_rad = term.number("phase_rad");
        term.finish();
        s.components.push_back(c);
      }
      break;
    case CommandShape::kCsv: {
      // Read and checked once, here: the control loop only interpolates.
      s.max_gap_s = cmd.number("max_gap_s");
      const std::string file = cmd.text("file");
      s.profile_file = relative_to(origin, file);
      validate_in(origin, [&] { require_in_range("command.max_gap_s", s.max_gap_s, control_period_s, 3600.0); });
      std::string text;
      try {
        text = read_file(s.profile_file);
      } catch (const ConfigError& e) {
        fail_at(origin, "command.file", e.what());
      }
      try {
        s.profile = parse_velocity_profile(text, s.profile_file, s.max_gap_s, kMaxCommandSpeedMps);
      } catch (const std::invalid_argument& e) {
        fail_at(origin, "command.file", e.what());
      }
      break;
    }
    case CommandShape::kExternal:
      s.timeout_s = cmd.number("timeout_s");
      s.max_speed_mps = cmd.number("max_speed_mps");
      s.accel_mps2 = cmd.number("accel_mps2");
      break;
  }
}

}  // namespace

Scenario parse_scenario(const std::string& yaml_text, const std::string& origin, double control_period_s,
                        const std::vector<ConfigOverride>& overrides) {
  YAML::Node root = parse_yaml(yaml_text, origin);
  apply_overrides(root, overrides, origin);
  Section top(root, origin, "");
  Scenario s;
  s.name = top.text("name");
  if (s.name.empty() || s.name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") !=
                            std::string::npos) {
    throw ConfigError(origin + ": name: must be letters, digits, '_' or '-' (it names output files), got '" + s.name +
                      "'");
  }
  s.duration_s = top.number("duration_s");
  Section cmd = top.child("command");
  s.shape = named_choice(origin, "command.shape", cmd.text("shape"), command_shape_from_string);
  read_command_keys(cmd, s, origin, control_period_s);
  cmd.finish();
  // Optional: without it the reference model (25) shapes the command, as in the paper.
  if (top.has("reference_model")) s.use_reference_model = top.flag("reference_model");
  // Optional: without it the command is not shaped.
  if (top.has("input_shaper")) {
    s.input_shaper = named_choice(origin, "input_shaper", top.text("input_shaper"), shaper_kind_from_string);
  }
  s.initial_load_displacement_m = top.number("initial_load_displacement_m");
  s.cost_window_s = top.number("cost_window_s");
  s.settling_band = top.number("settling_band");
  top.finish();
  validate_in(origin, [&] { s.validate(control_period_s); });
  return s;
}

Scenario load_scenario(const std::string& path, double control_period_s, const std::vector<ConfigOverride>& overrides) {
  return parse_scenario(read_file(path), path, control_period_s, overrides);
}

namespace {

// `plants:` of a training file; commission_key names the first that says whether it is commissioned.
std::vector<PlantVariant> read_plant_variants(Section& top, const std::string& origin, std::string& commission_key) {
  std::vector<PlantVariant> out;
  std::vector<Section> plants = top.sections("plants");
  for (std::size_t i = 0; i < plants.size(); ++i) {
    Section& item = plants[i];
    const std::string at = "plants[" + std::to_string(i) + "]";
    PlantVariant variant;
    variant.name = item.text("name");
    for (const std::string& text : item.texts("set")) {
      const ConfigOverride o = ConfigOverride::parse(text);
      const double value = to_number(load_yaml_document(o.value, origin), origin, at + ".set " + o.key_path);
      variant.values.emplace_back(o.key_path, value);
    }
    variant.weight = item.number("weight");
    if (item.has("commission")) {
      variant.commission = item.flag("commission");
      if (commission_key.empty()) commission_key = at + ".commission";
    }
    item.finish();
    out.push_back(variant);
  }
  return out;
}

}  // namespace

TrainingParams parse_training_params(const std::string& yaml_text, const std::string& origin, double control_period_s,
                                     const std::vector<ConfigOverride>& overrides) {
  YAML::Node root = parse_yaml(yaml_text, origin);
  apply_overrides(root, overrides, origin);
  Section top(root, origin, "");
  TrainingParams t;
  t.optimiser = top.text("optimiser");
  t.search.population_size = top.unsigned_integer("population_size");
  t.search.mutation_factor = top.number("mutation_factor");
  t.search.crossover_rate = top.number("crossover_rate");
  t.search.init_lower = top.number("init_lower");
  t.search.init_upper = top.number("init_upper");
  t.search.seed = top.unsigned_integer("seed");
  // Optional (the paper draws every member): a member that applies acceleration feedback.
  if (top.has("start")) t.start = named_choice(origin, "start", top.text("start"), training_start_from_string);
  t.max_evaluations = top.unsigned_integer("max_evaluations");
  t.target_cost = top.number("target_cost");
  t.cost_velocity = named_choice(origin, "cost_velocity", top.text("cost_velocity"), cost_velocity_from_string);
  // Scenario files are named relative to the training file.
  for (Section& item : top.sections("scenarios")) {
    const std::string file = item.text("file");
    TrainingScenario ts;
    ts.weight = item.number("weight");
    item.finish();
    ts.file = relative_to(origin, file);
    ts.scenario = load_scenario(ts.file, control_period_s);
    t.scenarios.push_back(ts);
  }
  // The plants each weight set is scored on: "key.path=value" moves of the configured plant.
  std::string commission_key;  // the first plant that says whether it is commissioned
  t.plants = read_plant_variants(top, origin, commission_key);
  t.plant_objective = named_choice(origin, "plant_objective", top.text("plant_objective"), plant_objective_from_string);
  // Optional: each run judged whole by a sweep file's verdict (named relative to the training
  // file), the thresholds the sweep reports with. Without it the paper's objective, the cost
  // window alone.
  if (top.has("verdict_from_sweep")) {
    t.judge_runs = true;
    t.verdict = load_sweep_verdict(relative_to(origin, top.text("verdict_from_sweep")));
  }
  // Optional, as a sweep file's: every plant commissioned first (commissioned_plants).
  ModelsSection models = read_models_section(top, origin, control_period_s);
  t.identify_models = models.identify;
  if (!t.identify_models && !commission_key.empty()) {
    validate_in(origin, [&] {
      throw std::invalid_argument(commission_key + ": only with models.identified: true (no plant is commissioned)");
    });
  }
  t.identification_scenario_file = models.identification_scenario_file;
  t.identification_scenario = std::move(models.identification_scenario);
  top.finish();
  validate_in(origin, [&] { t.validate(control_period_s); });
  return t;
}

TrainingParams load_training_params(const std::string& path, double control_period_s,
                                    const std::vector<ConfigOverride>& overrides) {
  return parse_training_params(read_file(path), path, control_period_s, overrides);
}

namespace {
void collect_leaves(const YAML::Node& node, const std::string& path, const std::string& origin,
                    std::vector<SourcedLeaf>& out) {
  if (is_sourced_leaf(node)) {
    check_sourced_leaf(node, origin, path);
    out.push_back({path, node["source"].as<std::string>(), describe(node["value"])});
  } else if (node.IsMap()) {
    for (const auto& kv : node) collect_leaves(kv.second, join(path, kv.first.as<std::string>()), origin, out);
  } else if (node.IsSequence() && node.size() > 0 && node[0].IsMap()) {
    // A list of sections (a multi-sine's terms): each item's leaves, as path[i].key.
    for (std::size_t i = 0; i < node.size(); ++i) {
      collect_leaves(node[i], path + "[" + std::to_string(i) + "]", origin, out);
    }
  } else {
    out.push_back({path, "", describe(node)});
  }
}
}  // namespace

std::vector<SourcedLeaf> list_leaf_sources(const std::string& yaml_text, const std::string& origin) {
  std::vector<SourcedLeaf> out;
  collect_leaves(parse_yaml(yaml_text, origin), "", origin, out);
  return out;
}

void CanopenRigConfig::validate() const {
  RangeCheck check;
  visit_rig_parameters(*this, check);
  master.check_relations();
}

CanopenRigConfig parse_canopen_config(const std::string& yaml_text, const std::string& origin,
                                      const std::vector<ConfigOverride>& overrides) {
  YAML::Node root = parse_yaml(yaml_text, origin);
  apply_overrides(root, overrides, origin);
  CanopenRigConfig c;
  TableReader reader(root, origin);
  visit_rig_parameters(c, reader);
  reader.finish();
  reader.validate([&] { c.validate(); });
  return c;
}

CanopenRigConfig load_canopen_config(const std::string& path, const std::vector<ConfigOverride>& overrides) {
  return parse_canopen_config(read_file(path), path, overrides);
}

namespace {
// "0x2001", "8193": an unsigned number in C's notation, within [0, max].
std::uint64_t c_number(const std::string& text, const std::string& origin, const std::string& path, std::uint64_t max) {
  std::size_t used = 0;
  unsigned long long v = 0;
  try {
    if (!text.empty() && text[0] != '-' && text[0] != '+') v = std::stoull(text, &used, 0);
  } catch (const std::exception&) {
    used = 0;
  }
  if (text.empty() || used != text.size() || v > max) {
    throw ConfigError(origin + ": " + path + ": expected a number in [0, " + std::to_string(max) +
                      "] (decimal or 0x hexadecimal), got '" + text + "'");
  }
  return v;
}

std::int64_t c_signed(const std::string& text, const std::string& origin, const std::string& path) {
  std::size_t used = 0;
  long long v = 0;
  try {
    v = std::stoll(text, &used, 0);
  } catch (const std::exception&) {
    used = 0;
  }
  if (text.empty() || used != text.size()) {
    throw ConfigError(origin + ": " + path + ": expected an integer, got '" + text + "'");
  }
  return v;
}
}  // namespace

namespace {

canopen::DataType dictionary_data_type(const std::string& type, const std::string& origin, const std::string& path) {
  static const std::pair<const char*, canopen::DataType> kTypes[] = {
      {"u8", canopen::DataType::kU8}, {"u16", canopen::DataType::kU16}, {"u32", canopen::DataType::kU32},
      {"i8", canopen::DataType::kI8}, {"i16", canopen::DataType::kI16}, {"i32", canopen::DataType::kI32}};
  for (const auto& [name, t] : kTypes) {
    if (type == name) return t;
  }
  throw ConfigError(origin + ": " + path + ".type: one of u8, u16, u32, i8, i16, i32, got '" + type + "'");
}

canopen::Access dictionary_access(const std::string& access, const std::string& origin, const std::string& path) {
  if (access == "ro") return canopen::Access::kRo;
  if (access == "rw") return canopen::Access::kRw;
  if (access == "wo") return canopen::Access::kWo;
  if (access == "const") return canopen::Access::kConst;
  throw ConfigError(origin + ": " + path + ".access: one of ro, rw, wo, const, got '" + access + "'");
}

// One manufacturer-specific object of `objects:`, not yet listed in `d`.
DictionaryObject read_dictionary_object(Section& o, const DeviceDictionary& d, const std::string& origin,
                                        const std::string& path) {
  DictionaryObject obj;
  obj.index = static_cast<std::uint16_t>(c_number(o.text("index"), origin, path + ".index", 0xFFFF));
  if (obj.index < 0x2000 || obj.index > 0x5FFF) {
    throw ConfigError(origin + ": " + path + ".index: a manufacturer-specific object lies in 0x2000-0x5FFF, got " +
                      o.text("index"));
  }
  obj.subindex = static_cast<std::uint8_t>(c_number(o.text("subindex"), origin, path + ".subindex", 0xFF));
  obj.name = o.text("name");
  if (obj.name.empty()) throw ConfigError(origin + ": " + path + ".name: must not be empty");
  obj.type = dictionary_data_type(o.text("type"), origin, path);
  obj.access = dictionary_access(o.text("access"), origin, path);
  const std::string mappable = o.text("pdo_mappable");
  if (mappable != "true" && mappable != "false") {
    throw ConfigError(origin + ": " + path + ".pdo_mappable: true or false, got '" + mappable + "'");
  }
  obj.pdo_mappable = mappable == "true";
  obj.value = c_signed(o.text("value"), origin, path + ".value");
  o.finish();
  for (const DictionaryObject& other : d.objects) {
    if (other.index == obj.index && other.subindex == obj.subindex) {
      throw ConfigError(origin + ": " + path + ": object " + o.text("index") + " sub " + std::to_string(obj.subindex) +
                        " is listed twice");
    }
  }
  return obj;
}

// "0xIIII:SS:BITS": the object a PDO entry maps and its width.
canopen::PdoMapEntry read_pdo_map_entry(const std::string& text, const std::string& origin,
                                        const std::string& item_path) {
  const auto first = text.find(':');
  const auto second = first == std::string::npos ? std::string::npos : text.find(':', first + 1);
  if (second == std::string::npos) {
    throw ConfigError(origin + ": " + item_path + ": expected \"0xIIII:SS:BITS\", got '" + text + "'");
  }
  canopen::PdoMapEntry e;
  e.index = static_cast<std::uint16_t>(c_number(text.substr(0, first), origin, item_path, 0xFFFF));
  e.subindex = static_cast<std::uint8_t>(c_number(text.substr(first + 1, second - first - 1), origin, item_path, 0xFF));
  e.bit_length = static_cast<std::uint8_t>(c_number(text.substr(second + 1), origin, item_path, 0xFF));
  if (e.bit_length != 8 && e.bit_length != 16 && e.bit_length != 32) {
    throw ConfigError(origin + ": " + item_path + ": the bit length must be 8, 16 or 32, got '" + text + "'");
  }
  return e;
}

// One default PDO of `pdos:`, its channel not yet listed in `d`.
PdoDefault read_pdo_default(Section& p, const DeviceDictionary& d, const std::string& origin, const std::string& path) {
  PdoDefault pdo;
  pdo.channel = p.text("channel");
  if (pdo.channel != "rpdo1" && pdo.channel != "tpdo1" && pdo.channel != "tpdo2" && pdo.channel != "tpdo3") {
    throw ConfigError(origin + ": " + path + ".channel: one of rpdo1, tpdo1, tpdo2, tpdo3, got '" + pdo.channel + "'");
  }
  for (const PdoDefault& other : d.pdos) {
    if (other.channel == pdo.channel) {
      throw ConfigError(origin + ": " + path + ".channel: " + pdo.channel + " is listed twice");
    }
  }
  const std::string cob_text = p.text("cob_id");
  std::string cob = cob_text;
  const std::string node_prefix = "$NODEID+";
  pdo.node_relative = cob.rfind(node_prefix, 0) == 0;
  if (pdo.node_relative) cob = cob.substr(node_prefix.size());
  // Bit 31 (CiA 301: the PDO not valid) may be set; the id itself is 11 bits.
  const auto value = static_cast<std::uint32_t>(c_number(cob, origin, path + ".cob_id", 0xFFFFFFFF));
  pdo.valid = (value & canopen::kPdoCobIdInvalid) == 0;
  pdo.cob_id = value & ~canopen::kPdoCobIdInvalid;
  if (pdo.cob_id > 0x7FF) {
    throw ConfigError(origin + ": " + path + ".cob_id: an 11-bit id (bit 31 may mark the PDO not valid), got '" +
                      cob_text + "'");
  }
  pdo.transmission_type =
      static_cast<std::uint8_t>(c_number(p.text("transmission_type"), origin, path + ".transmission_type", 0xFF));
  const std::vector<std::string> mapping = p.texts("mapping");
  if (mapping.empty() || mapping.size() > 8) {
    throw ConfigError(origin + ": " + path + ".mapping: a list of 1 to 8 entries \"0xIIII:SS:BITS\"");
  }
  for (std::size_t k = 0; k < mapping.size(); ++k) {
    pdo.mapping.push_back(read_pdo_map_entry(mapping[k], origin, path + ".mapping[" + std::to_string(k) + "]"));
  }
  p.finish();
  return pdo;
}

// The rig file's pdo section (pdo.outputs, pdo.inputs): lists of "0xIIII:SS:BITS" the master maps,
// read apart from the parameter table (they are entries, not numbers).
std::vector<canopen::PdoMapEntry> read_pdo_list(const YAML::Node& section, const char* key, const std::string& origin) {
  const std::string path = std::string("pdo.") + key;
  const YAML::Node leaf = section[key];
  if (!leaf) fail_at(origin, path, "missing key");
  const YAML::Node v = leaf_value(leaf, origin, path);
  if (!v.IsSequence() || v.size() == 0) {
    fail_at(origin, path, "expected a list of \"0xIIII:SS:BITS\", got '" + describe(v) + "'");
  }
  std::vector<canopen::PdoMapEntry> entries;
  for (std::size_t k = 0; k < v.size(); ++k) {
    const std::string item = path + "[" + std::to_string(k) + "]";
    if (!v[k].IsScalar()) fail_at(origin, item, "expected \"0xIIII:SS:BITS\", got '" + describe(v[k]) + "'");
    entries.push_back(read_pdo_map_entry(v[k].Scalar(), origin, item));
  }
  return entries;
}

}  // namespace

DeviceDictionary parse_device_dictionary(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root = parse_yaml(yaml_text, origin);
  Section top(root, origin, "");
  DeviceDictionary d;
  Section identity = top.child("identity");
  const auto u32 = [&](const char* key) {
    return static_cast<std::uint32_t>(
        c_number(identity.text(key), origin, std::string("identity.") + key, 0xFFFFFFFFULL));
  };
  d.vendor_id = u32("vendor_id");
  d.product_code = u32("product_code");
  d.revision_number = u32("revision_number");
  d.serial_number = u32("serial_number");
  identity.finish();
  std::size_t i = 0;
  for (Section& o : top.sections("objects")) {
    d.objects.push_back(read_dictionary_object(o, d, origin, "objects[" + std::to_string(i++) + "]"));
  }
  i = 0;
  for (Section& p : top.sections("pdos")) {
    d.pdos.push_back(read_pdo_default(p, d, origin, "pdos[" + std::to_string(i++) + "]"));
  }
  top.finish();
  return d;
}

DeviceDictionary load_device_dictionary(const std::string& path) {
  return parse_device_dictionary(read_file(path), path);
}

ethercat::Cia402DriveConfig parse_ethercat_config(const std::string& yaml_text, const std::string& origin,
                                                  const std::vector<ConfigOverride>& overrides) {
  YAML::Node root = parse_yaml(yaml_text, origin);
  apply_overrides(root, overrides, origin);
  ethercat::Cia402DriveConfig c;
  if (root.IsMap() && root["pdo"]) {
    const YAML::Node pdo = root["pdo"];
    if (!pdo.IsMap()) fail_at(origin, "pdo", "must be a mapping of keys, got '" + describe(pdo) + "'");
    for (const auto& kv : pdo) {
      const std::string key = kv.first.Scalar();
      if (key != "outputs" && key != "inputs") fail_at(origin, "pdo." + key, "unknown key (outputs, inputs)");
    }
    c.outputs_mapping = read_pdo_list(pdo, "outputs", origin);
    c.inputs_mapping = read_pdo_list(pdo, "inputs", origin);
    root.remove("pdo");
  }
  TableReader reader(root, origin);
  ethercat::visit_parameters(c, reader);
  reader.finish();
  reader.validate([&] { c.validate(); });
  return c;
}

ethercat::Cia402DriveConfig load_ethercat_config(const std::string& path,
                                                 const std::vector<ConfigOverride>& overrides) {
  return parse_ethercat_config(read_file(path), path, overrides);
}

}  // namespace pmlsm
