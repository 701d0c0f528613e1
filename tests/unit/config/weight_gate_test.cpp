// The gate a compensator takes NetworkWeights through: versions, rollbacks, implausible sets.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <fstream>
#include <limits>
#include <new>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "pmlsm/analysis/rnn_training.hpp"
#include "compensation/rnn_test_support.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using namespace rnn_test;

class WeightGate : public ::testing::Test {
 protected:
  WeightGate() : params_(load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml")) {}

  RnnWeightsFile fitting(double scale, std::uint64_t seed, double cost) const {
    RnnWeightsFile f;
    f.layer_sizes = params_.compensator.rnn.layer_sizes;
    f.input_scale_s2_per_m = params_.compensator.rnn.input_scale_s2_per_m;
    f.on_reference_error = params_.compensator.rnn.on_reference_error;
    f.gain_n = params_.compensator.rnn.gain_n;
    f.cost = cost;
    f.source = "de_trainer gen " + std::to_string(seed);
    f.weights = random_weights(91, scale, seed);
    return f;
  }

  SystemParams params_;
};

TEST_F(WeightGate, TakesIncreasingVersionsAndLogsEachWithSourceAndCost) {
  WeightSetGate gate(params_);
  EXPECT_EQ(gate.offer(fitting(1.0, 1, 9.5), 3, "the NetworkWeights topic"), "");
  EXPECT_EQ(gate.version(), 3u);
  EXPECT_NE(gate.last_log().find("weight set 3 from 'de_trainer gen 1' (the NetworkWeights topic, cost 9.5) taken"),
            std::string::npos)
      << gate.last_log();
  EXPECT_EQ(gate.offer(fitting(1.0, 2, 8.25), 110, "the NetworkWeights topic"), "");
  EXPECT_NE(gate.last_log().find("weight set 110"), std::string::npos);
  EXPECT_NE(gate.last_log().find("cost 8.25"), std::string::npos);
  EXPECT_NE(gate.last_log().find("replacing version 3"), std::string::npos);
  EXPECT_EQ(gate.taken(), 2u);
}

TEST_F(WeightGate, RefusesRollbacksAndRepeats) {
  WeightSetGate gate(params_);
  ASSERT_EQ(gate.offer(fitting(1.0, 1, 9.5), 110, "the NetworkWeights topic"), "");
  for (std::uint64_t version : {0u, 1u, 110u}) {
    SCOPED_TRACE(version);
    const std::string why = gate.offer(fitting(1.0, 4, 1.0), version, "the NetworkWeights topic");
    EXPECT_NE(why.find("does not increase on version 110"), std::string::npos) << why;
    EXPECT_NE(why.find("--first-version"), std::string::npos) << why;
    EXPECT_NE(gate.last_log().find("refused, keeping version 110"), std::string::npos) << gate.last_log();
    EXPECT_EQ(gate.version(), 110u);
  }
  EXPECT_EQ(gate.refused(), 3u);
  EXPECT_EQ(gate.offer(fitting(1.0, 5, 1.0), 111, "the NetworkWeights topic"), "");
}

TEST_F(WeightGate, RefusesImplausibleSetsKeepingTheCurrentOne) {
  WeightSetGate gate(params_);
  ASSERT_EQ(gate.offer(fitting(1.0, 1, 9.5), 1, "configs/rnn_weights.yaml"), "");
  RnnWeightsFile huge = fitting(1.0, 2, 0.1);
  std::fill(huge.weights.begin(), huge.weights.end(), 1e300);
  const std::string why = gate.offer(huge, 2, "the NetworkWeights topic");
  EXPECT_NE(why.find("weights[0]: must be in [-100, 100]"), std::string::npos) << why;
  RnnWeightsFile gain = fitting(1.0, 3, 0.1);
  gain.gain_n = 1e300;
  EXPECT_NE(gate.offer(gain, 3, "the NetworkWeights topic").find("gain"), std::string::npos);
  // A set trained on the other input would read every acceleration as something else.
  RnnWeightsFile other_input = fitting(1.0, 3, 0.1);
  other_input.on_reference_error = !params_.compensator.rnn.on_reference_error;
  EXPECT_NE(
      gate.offer(other_input, 3, "the NetworkWeights topic").find("differs from compensator.rnn.on_reference_error"),
      std::string::npos);
  EXPECT_EQ(gate.version(), 1u);
  // The optimisers' candidates beyond the bound cost +inf (never become the best set).
  const Scenario pulse =
      load_scenario(std::string(PMLSM_SOURCE_DIR) + "/configs/scenarios/pulse.yaml", params_.timing.control_period_s);
  const RnnCost cost(params_, {TrainingScenario{pulse, "pulse.yaml", 1.0}}, CostVelocity::truth);
  EXPECT_TRUE(std::isinf(cost(huge.weights)));
  // And the network itself refuses them.
  JordanRnn net(params_.compensator.rnn.layer_sizes);
  EXPECT_THROW(net.set_weights(huge.weights), std::invalid_argument);
}

}  // namespace
}  // namespace pmlsm
