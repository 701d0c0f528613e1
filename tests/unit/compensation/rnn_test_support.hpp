// What the RNN tests share: seeded random weights, constants and the expectation of a refusal
// naming its field.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/compensation/jordan_rnn.hpp"

namespace pmlsm::rnn_test {

inline const double kNan = std::numeric_limits<double>::quiet_NaN();
inline const double kInf = std::numeric_limits<double>::infinity();
inline const double kPi = 3.14159265358979323846;

inline std::vector<double> random_weights(std::size_t n, double scale, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-scale, scale);
  std::vector<double> w(n);
  for (double& x : w) x = u(rng);
  return w;
}

/// Runs f, expects std::invalid_argument whose message contains every part.
template <typename F>
void expect_invalid(F&& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one containing '" << parts.front() << "'";
  } catch (const std::invalid_argument& e) {
    for (const std::string& p : parts) EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
  }
}

/// The compensator the tests start from: Table 1's network, online learning on.
inline RnnCompensatorParams base_params() {
  RnnCompensatorParams p;
  p.layer_sizes = {3, 6, 6, 3, 1};
  p.input_scale_s2_per_m = 0.02;
  p.gain_n = 300;
  p.output_scale = 1.0;
  p.period_s = 1e-3;
  p.online_learning = true;
  p.learning_rate = 3.0;
  p.momentum = 0.5;
  p.tolerance_mps = 1e-4;
  p.kc_limit_mps = 1.0;
  p.du_deadband_per_s = 1e-3;
  return p;
}

}  // namespace pmlsm::rnn_test
