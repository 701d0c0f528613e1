// Bad configs under the launcher with the real nodes: every node refuses the file with exit 2
// and the launch ends with 2 naming the key (the 1e-320 load mass used to pass the
// loader and fail later in the Kalman filter's discretisation with exit 1, no key path).
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "child_process.hpp"
#include "integration_support.hpp"

namespace pmlsm::test {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

// configs/system.yaml with one value replaced.
std::string config_with(const fs::path& dir, const std::string& name, const std::string& key,
                        const std::string& value) {
  const std::string text = read_file(source("configs/system.yaml"));
  const std::string changed = std::regex_replace(text, std::regex(key + ": \\{value: [^,}]+"),
                                                 key + ": {value: " + value, std::regex_constants::format_first_only);
  EXPECT_NE(changed, text) << key;
  const fs::path path = dir / name;
  std::ofstream(path) << changed;
  return path.string();
}

TEST(LauncherConfigError, RealNodesMakeTheLaunchExit2NamingTheKey) {
  const fs::path dir = fresh_dir("pmlsm_hardening", "launch");
  struct Case {
    const char* name;
    std::string config;
    const char* named;
  };
  const Case cases[] = {
      {"subnormal load mass", config_with(dir, "mass.yaml", "load_mass_kg", "1e-320"), "plant.mechanics.load_mass_kg"},
      {"huge spring", config_with(dir, "spring.yaml", "spring_n_per_m", "1e308"), "plant.mechanics.spring_n_per_m"},
      {"fractional pole pairs", config_with(dir, "poles.yaml", "pole_pairs", "1.5"), "plant.electrical.pole_pairs"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    ChildProcess launcher({bin("launcher"), source("launch/sim.yaml"), "--arg", "config=" + c.config, "--arg",
                           "domain=" + test_domain(60), "--arg", "out=" + (dir / "out").string(), "--arg",
                           "profiles=" + source("configs/dds/profiles.xml"), "--arg",
                           "scenario=" + source("configs/scenarios/pulse.yaml")},
                          (dir / "launcher.log").string());
    const auto code = launcher.wait_for(seconds(60));
    ASSERT_TRUE(code.has_value()) << launcher.output();
    EXPECT_EQ(*code, 2) << launcher.output();
    EXPECT_NE(launcher.output().find("launch failed with exit code 2"), std::string::npos) << launcher.output();
    EXPECT_NE(launcher.output().find(c.named), std::string::npos) << launcher.output();
  }
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm::test
