#include "pmlsm/config/parameter_reference.hpp"

#include <algorithm>
#include <array>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/ethercat_config.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {

std::string unit_of_key(const std::string& key_path) {
  // Longest suffixes first: "_n_s_per_m" before "_n_per_m" before "_m".
  static const std::array<std::pair<const char*, const char*>, 25> kSuffixes{{
      {"_n_s_per_m", "N s/m"},
      {"_v_per_a_s", "V/(A s)"},
      {"_rad_per_m", "rad/m"},
      {"_s2_per_m", "s^2/m"},
      {"_n_per_m", "N/m"},
      {"_n_per_a", "N/A"},
      {"_v_per_a", "V/A"},
      {"_rad_s", "rad/s"},
      {"_per_s", "1/s"},
      {"_mps2", "m/s^2"},
      {"_mps", "m/s"},
      {"_ohm", "Ohm"},
      {"_hz", "Hz"},
      {"_kg", "kg"},
      {"_wb", "Wb"},
      {"_us", "us"},
      {"_ms", "ms"},
      {"_per_metre", "1/m"},
      {"_s", "s"},
      {"_m", "m"},
      {"_n", "N"},
      {"_h", "H"},
      {"_v", "V"},
      {"_a", "A"},
      {"_bps", "bit/s"},
  }};
  const std::string name = key_path.substr(key_path.rfind('.') + 1);
  for (const auto& [suffix, unit] : kSuffixes) {
    const std::string s(suffix);
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) return unit;
  }
  return "";
}

namespace {

struct ReferenceRow {
  std::string key_path;
  std::string kind;  ///< what the reader takes and the range it checks
  std::string reason;
  std::string value;           ///< as loaded: what the page shows for an entry the file leaves to its declaration
  std::string default_source;  ///< the source shown then
};

// Walks the parameter table and writes down each entry's declaration.
class DeclarationCollector {
 public:
  void real(const std::string& path, const double& value, const Plausible& r) {
    add(path, "real in " + range(r) + live(r.live_at), r.reason, format_value(value));
  }
  template <typename T>
  void integer(const std::string& path, const T& value, const Plausible& r) {
    add(path, "whole number in " + range(r) + live(r.live_at), r.reason, std::to_string(value));
  }
  void flag(const std::string& path, const bool& value) { add(path, "true or false", "", value ? "true" : "false"); }
  template <typename E, typename F>
  void choice(const std::string& path, const E&, F from_string, const char* live_at = nullptr) {
    // The set of names is the parser's own: its refusal lists them ("must be one of a, b, got 'x'").
    std::string names = "a name";
    try {
      from_string("");
    } catch (const std::invalid_argument& e) {
      names = e.what();
      const std::size_t got = names.rfind(", got");
      if (got != std::string::npos) names.resize(got);
      if (names.rfind("must be ", 0) == 0) names.erase(0, 8);
    }
    add(path, "a name: " + names + live(live_at), "");
  }
  void vector3(const std::string& path, const Eigen::Vector3d&, const Plausible& r) {
    add(path, "3 reals, each in " + range(r), r.reason);
  }
  void integer_list(const std::string& path, const std::vector<int>&, const Plausible& r) {
    add(path, "whole numbers, each in " + range(r), r.reason);
  }

  std::vector<ReferenceRow> rows;

 private:
  static std::string range(const Plausible& r) { return "[" + format_value(r.min) + ", " + format_value(r.max) + "]"; }
  /// Who takes it live (`pmlsm param`), said after what is accepted.
  static std::string live(const char* live_at) {
    return live_at == nullptr ? std::string() : std::string("; live at `") + live_at + "`";
  }
  void add(const std::string& path, std::string kind, const std::string& reason, std::string value = "") {
    rows.push_back({path, std::move(kind), reason, std::move(value), ""});
  }
};

// A table cell: one line, no column separator.
std::string cell(std::string text) {
  std::string out;
  for (char c : text) {
    if (c == '|') {
      out += "\\|";
    } else if (c == '\n') {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}

// The page: an introduction, then a table a section of the file, a row a declared parameter.
std::string reference_page(const std::vector<ReferenceRow>& rows, const std::string& yaml_text,
                           const std::string& origin, const std::string& introduction) {
  std::map<std::string, SourcedLeaf> leaves;
  for (SourcedLeaf& leaf : list_leaf_sources(yaml_text, origin)) leaves.emplace(leaf.key_path, std::move(leaf));
  std::ostringstream out;
  out << "# Configuration reference: `" << origin << "`\n\n" << introduction;
  // One table a section, the sections in the order the declarations first name them.
  std::vector<std::string> sections;
  for (const ReferenceRow& row : rows) {
    const std::string parent = row.key_path.substr(0, row.key_path.rfind('.'));
    if (std::find(sections.begin(), sections.end(), parent) == sections.end()) sections.push_back(parent);
  }
  for (const std::string& section : sections) {
    out << "\n## `" << section << "`\n\n"
        << "| key | value | unit | accepted | why that range | source |\n"
        << "|---|---|---|---|---|---|\n";
    for (const ReferenceRow& row : rows) {
      const std::size_t dot = row.key_path.rfind('.');
      if (row.key_path.compare(0, dot, section) != 0 || dot != section.size()) continue;
      const auto leaf = leaves.find(row.key_path);
      // An entry the file does not name has its declaration's default (a compensator's section).
      const std::string value = leaf != leaves.end() ? leaf->second.value : row.value;
      const std::string source = leaf != leaves.end() ? leaf->second.source : row.default_source;
      out << "| `" << row.key_path.substr(dot + 1) << "` | " << cell(value) << " | " << unit_of_key(row.key_path)
          << " | " << cell(row.kind) << " | " << cell(row.reason) << " | " << cell(source) << " |\n";
    }
  }
  return out.str();
}

}  // namespace

std::string system_parameter_reference(const std::string& yaml_text, const std::string& origin) {
  const SystemParams params = parse_system_params(yaml_text, origin);
  DeclarationCollector collector;
  visit_parameters(params, collector);
  for (ReferenceRow& row : collector.rows) {
    for (const ParameterSection& section : params.sections) {
      if (row.key_path.rfind(std::string(section.at) + ".", 0) == 0) {
        row.default_source = std::string("the default declared in ") + section.declared_in;
      }
    }
  }
  return reference_page(
      collector.rows, yaml_text, origin,
      "Generated from the parameter declarations (each component's `declare`, next to its code, in the\n"
      "layout `visit_parameters` of `common/sim/include/pmlsm/sim/system_params.hpp` gives them) and the\n"
      "values and sources of `" +
          origin +
          "`\n"
          "by `./build/bin/pmlsm config reference -o docs/configuration-reference.md`; the test\n"
          "`config_reference` fails when this page and either of them disagree. Do not edit it by hand.\n\n"
          "A value outside its range is refused with the range and its reason; the unit is the one the\n"
          "key's name carries. `live at NODE`: that node takes a change of it while it runs, at a tick\n"
          "boundary (`pmlsm param`, [commissioning.md](commissioning.md)); the others are read at start.\n"
          "A compensator added in its own folder ([writing-a-compensator.md](writing-a-compensator.md)) has\n"
          "its section here with its declaration's defaults, which the file may leave out.\n"
          "Where a source needs more than a sentence or two, the rest is in\n"
          "[parameters.md](parameters.md); how the file is read and overridden: [configuration.md](configuration.md).\n"
          "The CANopen rig file: [canopen-reference.md](canopen-reference.md).\n");
}

std::string canopen_parameter_reference(const std::string& yaml_text, const std::string& origin) {
  const CanopenRigConfig config = parse_canopen_config(yaml_text, origin);
  DeclarationCollector collector;
  visit_rig_parameters(config, collector);
  return reference_page(
      collector.rows, yaml_text, origin,
      "Generated from the parameter declarations (`visit_rig_parameters` in\n"
      "`common/config/include/pmlsm/config/canopen_config.hpp` and `canopen::visit_parameters` in\n"
      "`common/canopen/include/pmlsm/canopen/cia402_drive.hpp`) and the values and sources of `" +
          origin +
          "`\n"
          "by `./build/bin/pmlsm config reference --kind canopen -o docs/canopen-reference.md`; the test\n"
          "`canopen_reference` fails when this page and either of them disagree. Do not edit it by hand.\n\n"
          "Both ends of the bus read this file (drive_bridge, the master; virtual_drive, the simulated\n"
          "drive), so they agree; a value outside its range is refused with the range and its reason.\n"
          "Connecting a drive: [real-drive.md](real-drive.md).\n");
}

std::string ethercat_parameter_reference(const std::string& yaml_text, const std::string& origin) {
  ethercat::Cia402DriveConfig config = parse_ethercat_config(yaml_text, origin);
  DeclarationCollector collector;
  ethercat::visit_parameters(config, collector);
  return reference_page(
      collector.rows, yaml_text, origin,
      "Generated from the parameter declarations (`ethercat::visit_parameters` in\n"
      "`common/ethercat/include/pmlsm/ethercat/cia402_drive.hpp`) and the values and sources of `" +
          origin +
          "`\n"
          "by `./build/bin/pmlsm config reference --kind ethercat -o docs/ethercat-reference.md`; the test\n"
          "`ethercat_reference` fails when this page and either of them disagree. Do not edit it by hand.\n\n"
          "Both ends of the link read this file (drive_bridge --bus ethercat, the master; virtual_drive\n"
          "--bus ethercat, the simulated drive), so they agree; a value outside its range is refused with\n"
          "the range and its reason. Connecting a drive: [ethercat.md](ethercat.md).\n");
}

}  // namespace pmlsm
