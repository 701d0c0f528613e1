// The generated configuration reference (pmlsm/config/parameter_reference.hpp): every
// parameter of the table on the page with the file's value and source, units read from the
// keys' names, an invalid file refused as the loader refuses it.
#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "config_edit.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/parameter_reference.hpp"

namespace pmlsm {
namespace {

using test::edited;
using test::system_text;

constexpr const char* kShippedOrigin = "configs/system.yaml";

TEST(ParameterReference, ReadsTheUnitFromTheKeysName) {
  EXPECT_EQ(unit_of_key("velocity_loop.kp_n_s_per_m"), "N s/m");
  EXPECT_EQ(unit_of_key("plant.mechanics.spring_n_per_m"), "N/m");
  EXPECT_EQ(unit_of_key("velocity_loop.force_limit_n"), "N");
  EXPECT_EQ(unit_of_key("current_loop.ki_v_per_a_s"), "V/(A s)");
  EXPECT_EQ(unit_of_key("compensator.rnn.input_scale_s2_per_m"), "s^2/m");
  EXPECT_EQ(unit_of_key("timing.control_period_s"), "s");
  EXPECT_EQ(unit_of_key("compensator.guard.min_oscillation_mps"), "m/s");
  EXPECT_EQ(unit_of_key("plant.electrical.resistance_ohm"), "Ohm");
  // No unit in the name, none on the page: ratios, shares, counts, flags, names.
  EXPECT_EQ(unit_of_key("reference_model.damping_ratio"), "");
  EXPECT_EQ(unit_of_key("compensator.guard.windows_to_trip"), "");
  EXPECT_EQ(unit_of_key("plant.integrator"), "");
  // A suffix is a whole word of the name: "_s" of "sizes" is none.
  EXPECT_EQ(unit_of_key("compensator.rnn.layer_sizes"), "");
}

/// Every leaf of `text` has one row on `page`, in its section's table, with its value and source;
/// the other rows are the entries of parameter sections (the commissioning's, the compensators')
/// the file leaves to their declarations.
void expect_every_leaf_on_the_page(const std::string& page, const std::string& text, const std::string& origin) {
  std::size_t rows = 0;
  std::size_t declared_defaults = 0;
  std::istringstream lines(page);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("| `", 0) != 0) continue;
    ++rows;
    if (line.find("| the default declared in ") != std::string::npos) ++declared_defaults;
  }
  const auto leaves = list_leaf_sources(text, origin);
  EXPECT_EQ(rows - declared_defaults, leaves.size());
  for (const SourcedLeaf& leaf : leaves) {
    const std::string key = leaf.key_path.substr(leaf.key_path.rfind('.') + 1);
    const std::string section = leaf.key_path.substr(0, leaf.key_path.rfind('.'));
    const std::size_t at = page.find("\n## `" + section + "`\n");
    ASSERT_NE(at, std::string::npos) << leaf.key_path;
    const std::size_t row = page.find("| `" + key + "` | " + leaf.value + " |", at);
    ASSERT_NE(row, std::string::npos) << leaf.key_path;
    std::string source_cell;  // a '|' of the source is escaped in its table cell
    for (char c : leaf.source) source_cell += c == '|' ? std::string("\\|") : std::string(1, c);
    EXPECT_NE(page.find(source_cell, row), std::string::npos) << leaf.key_path;
  }
}

TEST(ParameterReference, ListsEveryLeafOfTheFileOnceWithItsValueAndSource) {
  expect_every_leaf_on_the_page(system_parameter_reference(system_text(), kShippedOrigin), system_text(),
                                kShippedOrigin);
}

TEST(ParameterReference, ListsEveryLeafOfTheCanopenRigFile) {
  const std::string text = test::read_text("configs/canopen/drive.yaml");
  const std::string page = canopen_parameter_reference(text, "configs/canopen/drive.yaml");
  expect_every_leaf_on_the_page(page, text, "configs/canopen/drive.yaml");
  EXPECT_NE(page.find("| `node_id` | 1 |  | whole number in [1, 127] | a CANopen node id"), std::string::npos);
}

TEST(ParameterReference, StatesTheDeclaredRangeAndItsReason) {
  const std::string page = system_parameter_reference(system_text(), kShippedOrigin);
  EXPECT_NE(page.find("| `load_mass_kg` | 4.0 | kg | real in [0.01, 10000] | from a 10 g load to a 10 t one |"),
            std::string::npos);
  EXPECT_NE(page.find("| `integrator` | ab2 |  | a name: one of rk4, heun, ab2 |"), std::string::npos);
}

TEST(ParameterReference, FollowsTheFilesValues) {
  const std::string changed =
      edited(system_text(), {{"plant.mechanics.load_mass_kg", std::string("{value: 5.5, source: \"chosen: test\"}")}});
  const std::string page = system_parameter_reference(changed, kShippedOrigin);
  EXPECT_NE(page.find("| `load_mass_kg` | 5.5 | kg |"), std::string::npos);
  EXPECT_NE(page.find("| chosen: test |"), std::string::npos);
}

TEST(ParameterReference, RefusesAFileTheLoaderRefuses) {
  const std::string bad =
      edited(system_text(), {{"plant.mechanics.load_mass_kg", std::string("{value: -1, source: \"chosen: x\"}")}});
  const std::string what = test::error_of([&] { system_parameter_reference(bad, "bad.yaml"); });
  EXPECT_NE(what.find("bad.yaml: plant.mechanics.load_mass_kg: must be in [0.01, 10000]"), std::string::npos) << what;
}

}  // namespace
}  // namespace pmlsm
