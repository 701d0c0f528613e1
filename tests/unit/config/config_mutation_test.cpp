// Every parameter of configs/system.yaml, mutated by every class of bad value a careless or
// hostile user could write, through the real loader: each must be refused with a
// ConfigError naming the file, the key path and the value. The leaves come from the
// parameter table (visit_parameters), which is checked to cover every leaf of the file.
// Whole-file classes (empty, binary, oversized, anchor bombs, deep nesting, duplicated
// keys) follow. tests/unit/config/config_cli_check.cmake runs some of them through the programs.
#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "config_edit.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {
namespace {

constexpr const char* kMutatedOrigin = "mutated.yaml";
using test::system_text;

enum class Kind { kReal, kInteger, kFlag, kChoice, kVector3, kIntegerList };

struct Leaf {
  std::string path;
  Kind kind;
};

// Lists the table's entries.
struct CollectLeaves {
  std::vector<Leaf> leaves;
  void real(const std::string& p, const double&, const Plausible&) { leaves.push_back({p, Kind::kReal}); }
  template <typename T>
  void integer(const std::string& p, const T&, const Plausible&) {
    leaves.push_back({p, Kind::kInteger});
  }
  void flag(const std::string& p, const bool&) { leaves.push_back({p, Kind::kFlag}); }
  template <typename E, typename F>
  void choice(const std::string& p, const E&, F, const char* /*live_at*/ = nullptr) {
    leaves.push_back({p, Kind::kChoice});
  }
  void vector3(const std::string& p, const Eigen::Vector3d&, const Plausible&) {
    leaves.push_back({p, Kind::kVector3});
  }
  void integer_list(const std::string& p, const std::vector<int>&, const Plausible&) {
    leaves.push_back({p, Kind::kIntegerList});
  }
};

std::vector<Leaf> table_leaves() {
  const SystemParams p;
  CollectLeaves collect;
  visit_parameters(p, collect);
  return collect.leaves;
}

// The message of the ConfigError the text raises, or "" when it loads.
std::string load_error(const std::string& text) {
  try {
    parse_system_params(text, kMutatedOrigin);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// The message names the value: its text, or the number it reads as, formatted.
bool names_value(const std::string& message, const std::string& value) {
  if (message.find(value) != std::string::npos) return true;
  // A nested list is named by the element that is wrong: [[1]] by its [1].
  if (value.size() > 2 && value.front() == '[' &&
      message.find(value.substr(1, value.size() - 2)) != std::string::npos) {
    return true;
  }
  char* end = nullptr;
  const double x = std::strtod(value.c_str(), &end);
  return end != value.c_str() && *end == '\0' && message.find(format_value(x)) != std::string::npos;
}

struct Mutation {
  const char* name;
  const char* yaml;
};

// Wrong for every kind of leaf.
const std::vector<Mutation> kAnyLeaf = {
    {"nan", ".nan"},
    {"inf", ".inf"},
    {"-inf", "-.inf"},
    {"huge", "1e308"},
    {"-huge", "-1e308"},
    {"subnormal", "1e-320"},
    {"-subnormal", "-4.9e-324"},
    {"string", "abc"},
    {"nested list", "[[1]]"},
    {"map", "{a: 1}"},
    {"null", "~"},
};
// Wrong for every leaf but a flag.
const Mutation kBoolean{"boolean", "true"};
// Wrong where the quantity is a whole number.
const std::vector<Mutation> kWholeNumber = {
    {"fraction", "1.5"}, {"negative", "-1"}, {"hexadecimal", "0x10"}, {"exponent", "1e2"}};

// The file with the leaf's line written twice (the emitter cannot write a duplicate).
std::string with_duplicated_line(const std::string& text, const std::string& path) {
  std::istringstream in(text);
  std::ostringstream out;
  std::vector<std::string> stack;
  bool done = false;
  for (std::string line; std::getline(in, line);) {
    out << line << "\n";
    const auto indent = line.find_first_not_of(' ');
    if (done || indent == std::string::npos || line[indent] == '#') continue;
    const auto colon = line.find(':', indent);
    if (colon == std::string::npos) continue;
    stack.resize(indent / 2);
    stack.push_back(line.substr(indent, colon - indent));
    std::string at;
    for (const auto& k : stack) at += (at.empty() ? "" : ".") + k;
    if (at == path) {
      out << line << "\n";
      done = true;
    }
  }
  if (!done) throw std::logic_error("no line for " + path);
  return out.str();
}

TEST(ConfigMutations, TableCoversEveryLeafOfTheShippedFile) {
  std::set<std::string> table;
  for (const Leaf& leaf : table_leaves()) EXPECT_TRUE(table.insert(leaf.path).second) << leaf.path << " twice";
  std::set<std::string> file;
  for (const SourcedLeaf& leaf : list_leaf_sources(system_text(), kMutatedOrigin)) file.insert(leaf.key_path);
  EXPECT_EQ(table, file);
  EXPECT_GE(table.size(), 60u);
}

// No default lives in two places: a value comes from the file (or --set), never from a literal in
// a component's struct that the file must be kept equal to. SystemParams made from nothing holds
// zeros, false and each choice's first name for every entry of the table.
struct CollectNonZero {
  std::vector<std::string> found;
  void real(const std::string& p, const double& value, const Plausible&) { check(p, value != 0.0); }
  template <typename T>
  void integer(const std::string& p, const T& value, const Plausible&) {
    check(p, value != T{});
  }
  void flag(const std::string& p, const bool& value) { check(p, value); }
  template <typename E, typename F>
  void choice(const std::string& p, const E& value, F, const char* /*live_at*/ = nullptr) {
    check(p, static_cast<int>(value) != 0);
  }
  void vector3(const std::string& p, const Eigen::Vector3d& value, const Plausible&) { check(p, !value.isZero()); }
  void integer_list(const std::string& p, const std::vector<int>& value, const Plausible&) { check(p, !value.empty()); }
  void check(const std::string& p, bool literal) {
    if (literal) found.push_back(p);
  }
};

TEST(ConfigMutations, NoEntryHasADefaultBesideTheFile) {
  const SystemParams nothing{};
  CollectNonZero collect;
  visit_parameters(nothing, collect);
  std::string found;
  for (const std::string& p : collect.found) found += " " + p;
  EXPECT_TRUE(collect.found.empty()) << "literal defaults beside configs/system.yaml:" << found;
}

TEST(ConfigMutations, EveryLeafEveryClassIsRefusedNamingKeyAndValue) {
  std::map<std::string, int> refused_by_class;
  int total = 0;
  const auto expect_refused = [&](const std::string& what, const std::string& text, const std::string& path,
                                  const std::string& value) {
    ++total;
    const std::string message = load_error(text);
    if (message.empty()) {
      ADD_FAILURE() << what << ": accepted";
      return;
    }
    EXPECT_EQ(message.rfind(std::string(kMutatedOrigin) + ": ", 0), 0u) << what << ": " << message;
    EXPECT_NE(message.find(path), std::string::npos) << what << ": key not named: " << message;
    if (!value.empty()) {
      EXPECT_TRUE(names_value(message, value)) << what << ": value not named: " << message;
    }
    ++refused_by_class[what.substr(0, what.find(' '))];
  };

  for (const Leaf& leaf : table_leaves()) {
    SCOPED_TRACE(leaf.path);
    std::vector<Mutation> classes = kAnyLeaf;
    if (leaf.kind != Kind::kFlag) classes.push_back(kBoolean);
    if (leaf.kind == Kind::kInteger) classes.insert(classes.end(), kWholeNumber.begin(), kWholeNumber.end());
    for (const Mutation& m : classes) {
      expect_refused(std::string(m.name) + " " + leaf.path,
                     test::edited(system_text(), {{leaf.path + ".value", m.yaml}}), leaf.path, m.yaml);
    }
    // Inside a list: one element mutated.
    if (leaf.kind == Kind::kVector3 || leaf.kind == Kind::kIntegerList) {
      std::vector<Mutation> element_classes = kAnyLeaf;
      element_classes.push_back(kBoolean);
      if (leaf.kind == Kind::kIntegerList) {
        element_classes.insert(element_classes.end(), kWholeNumber.begin(), kWholeNumber.end());
      }
      for (const Mutation& m : element_classes) {
        const std::string list = leaf.kind == Kind::kVector3 ? std::string("[1, ") + m.yaml + ", 1]"
                                                             : std::string("[3, ") + m.yaml + ", 6, 3, 1]";
        expect_refused(std::string("element-") + m.name + " " + leaf.path,
                       test::edited(system_text(), {{leaf.path + ".value", list}}), leaf.path + "[1]", m.yaml);
      }
    }
    expect_refused("missing " + leaf.path, test::edited(system_text(), {{leaf.path, std::nullopt}}),
                   leaf.path + ": missing key", "");
    expect_refused("unknown " + leaf.path,
                   test::edited(system_text(), {{leaf.path + "_typo", "{value: 1, source: paper}"}}),
                   leaf.path + "_typo: unknown key", "");
    expect_refused("duplicated " + leaf.path, with_duplicated_line(system_text(), leaf.path),
                   leaf.path + ": duplicate key", "");
  }
  std::printf("config mutations refused: %d in all;", total);
  for (const auto& [what, n] : refused_by_class) std::printf(" %s %d", what.c_str(), n);
  std::printf("\n");
}

// The issue's cases one by one, with the reason of the range in the message.
TEST(ConfigMutations, ImplausibleValuesNameTheRangeAndReason) {
  struct Case {
    const char* path;
    const char* value;
    const char* expected;
  };
  for (const Case& c : {
           Case{"plant.mechanics.spring_n_per_m", "1e308", "must be in [1, 1000000000]"},
           Case{"plant.mechanics.spring_n_per_m", "5e8", "the load mode"},  // in range, too stiff for 10 us
           Case{"plant.mechanics.load_mass_kg", "1e-320", "subnormal"},
           Case{"plant.mechanics.load_mass_kg", "1e-6", "from a 10 g load"},
           Case{"velocity_loop.kp_n_s_per_m", "1e308", "one encoder count per tick"},
           Case{"plant.mechanics.motor_mass_kg", "1e308", "10 t gantry"},
           Case{"plant.electrical.pole_pairs", "1.5", "expected a non-negative integer"},
           Case{"plant.electrical.resistance_ohm", "900", "fastest d-axis pole"},
       }) {
    SCOPED_TRACE(std::string(c.path) + " = " + c.value);
    const std::string message = load_error(test::edited(system_text(), {{std::string(c.path) + ".value", c.value}}));
    EXPECT_NE(message.find(c.path), std::string::npos) << message;
    EXPECT_NE(message.find(c.expected), std::string::npos) << message;
    EXPECT_TRUE(names_value(message, c.value)) << message;
  }
  // The same ranges hold for SystemParams built in code.
  SystemParams p = parse_system_params(system_text(), kMutatedOrigin);
  p.plant.electrical.pole_pairs = 1.5;
  EXPECT_THROW(p.validate(), std::invalid_argument);
}

// What the file as a whole can be.
TEST(ConfigMutations, WholeFileClassesAreRefused) {
  std::mt19937_64 rng(15);
  std::string binary(4096, '\0');
  for (char& c : binary) c = static_cast<char>(rng());
  std::string binary_no_nul = binary;
  for (char& c : binary_no_nul) {
    if (c == '\0') c = '\x01';
  }
  // "Billion laughs": nine levels of nine aliases expand to 9^9 = 387 million strings.
  std::string bomb = "a: &a [\"lol\",\"lol\",\"lol\",\"lol\",\"lol\",\"lol\",\"lol\",\"lol\",\"lol\"]\n";
  for (char level = 'b'; level <= 'i'; ++level) {
    const char prev = static_cast<char>(level - 1);
    bomb += std::string(1, level) + ": &" + level + " [";
    for (int i = 0; i < 9; ++i) bomb += std::string(i ? "," : "") + "*" + prev;
    bomb += "]\n";
  }
  const std::string alias_value = test::edited(system_text(), {}) + "\nextra: &x 1\nmore: *x\n";
  const std::string deep_lists = "timing: " + std::string(100000, '[') + std::string(100000, ']') + "\n";
  std::string deep_maps = "timing:";
  for (int i = 0; i < 200; ++i) deep_maps += " {a" + std::to_string(i) + ":";
  deep_maps += " 1" + std::string(200, '}') + "\n";
  struct Case {
    const char* what;
    std::string text;
    const char* expected;
  };
  for (const Case& c : {
           Case{"empty", "", "top level must be a mapping"},
           Case{"blank", "  \n\n", "top level must be a mapping"},
           Case{"binary with NUL bytes", binary, "NUL"},
           Case{"binary without NUL bytes", binary_no_nul, ""},
           Case{"top-level list", "- 1\n- 2\n", "top level must be a mapping"},
           Case{"oversized", system_text() + "#" + std::string(2 << 20, 'x') + "\n", "bytes, more than"},
           Case{"billion laughs", bomb, "anchors"},
           Case{"alias", alias_value, "anchors"},
           Case{"deep lists", deep_lists, ""},
           Case{"deep maps", deep_maps, "nested deeper than"},
           Case{"two documents", system_text() + "---\n" + system_text(), "more than one YAML document"},
           Case{"list as a key", "? [a, b]\n: 1\n", "a key must be a plain name"},
           Case{"duplicated section", system_text() + "timing:\n  control_period_s: 1\n", "timing: duplicate key"},
       }) {
    SCOPED_TRACE(c.what);
    const std::string message = load_error(c.text);
    ASSERT_FALSE(message.empty()) << "accepted";
    EXPECT_EQ(message.rfind(std::string(kMutatedOrigin) + ": ", 0), 0u) << message;
    EXPECT_NE(message.find(c.expected), std::string::npos) << message;
  }
}

// Overrides go through the same checks as the file.
TEST(ConfigMutations, OverridesAreCheckedAsTheFile) {
  for (const char* text : {"plant.mechanics.spring_n_per_m=1e308", "plant.electrical.pole_pairs=1.5",
                           "plant.mechanics.load_mass_kg=1e-320", "plant.mechanics.load_mass_kg=&a 1",
                           "velocity_loop.kp_n_s_per_m={a: 1, a: 2}"}) {
    SCOPED_TRACE(text);
    const ConfigOverride o = ConfigOverride::parse(text);
    try {
      parse_system_params(system_text(), kMutatedOrigin, {o});
      ADD_FAILURE() << "accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(o.key_path), std::string::npos) << e.what();
    }
  }
}

// configs/training.yaml: sizes that would exhaust memory or time are refused with the key.
TEST(ConfigMutations, TrainingSizesArePlausible) {
  const std::string origin = test::source_path("configs/training.yaml");
  const std::string text = test::read_text("configs/training.yaml");
  struct Case {
    const char* path;
    const char* value;
  };
  for (const Case& c : {Case{"population_size", "18446744073709551615"}, Case{"population_size", "100001"},
                        Case{"max_evaluations", "1000000000000"}, Case{"init_upper", "1e300"},
                        Case{"init_lower", "-1e300"}, Case{"target_cost", "1e308"}, Case{"mutation_factor", "1e-320"},
                        Case{"population_size", "1.5"}, Case{"seed", "-1"}}) {
    SCOPED_TRACE(std::string(c.path) + " = " + c.value);
    try {
      parse_training_params(test::edited(text, {{std::string(c.path) + ".value", c.value}}), origin, 1e-3);
      ADD_FAILURE() << "accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(c.path), std::string::npos) << e.what();
    }
  }
  EXPECT_NO_THROW(parse_training_params(text, origin, 1e-3));
}

}  // namespace
}  // namespace pmlsm
