// What the trainer ships to remote workers (nodes/training/training_support.hpp, make_setup): the
// texts go into TrainingSetup whole, and a text past its field's bound (the IDL's, which the
// generated fixed_string would cut without a word) is refused naming it.
#include "training_support.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

namespace pmlsm::training {
namespace {

const std::string kShippedSystem = std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml";

std::string error_of_setup(const std::string& system_path, const std::vector<std::string>& overrides) {
  try {
    make_setup(1, system_path, overrides, TrainingParams{});
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(TrainingSetupText, TheShippedSystemFileGoesWhole) {
  const auto setup = make_setup(7, kShippedSystem, {"plant.mechanics.load_mass_kg=4.5"}, TrainingParams{});
  EXPECT_EQ(setup.system_yaml().to_string(), read_text(kShippedSystem));
  EXPECT_EQ(setup.system_origin().to_string(), kShippedSystem);
  ASSERT_EQ(setup.system_overrides().size(), 1u);
  EXPECT_EQ(setup.system_overrides()[0].to_string(), "plant.mechanics.load_mass_kg=4.5");
}

TEST(TrainingSetupText, ATextPastItsFieldsBoundIsRefusedNamingTheBound) {
  const std::string path = testing::TempDir() + "/training_setup_too_long.yaml";
  {
    std::ofstream out(path, std::ios::binary);
    out << std::string(65537, '#');
  }
  EXPECT_NE(error_of_setup(path, {}).find(path + ": 65537 characters, TrainingSetup carries at most 65536"),
            std::string::npos);
  const std::string long_override = "plant.mechanics.load_mass_kg=" + std::string(230, '4');
  EXPECT_NE(error_of_setup(kShippedSystem, {long_override}).find("259 characters, TrainingSetup carries at most 256"),
            std::string::npos);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace pmlsm::training
