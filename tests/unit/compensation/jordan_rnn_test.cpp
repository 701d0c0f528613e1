// The Jordan network of section 3.2 (Table 1's sizes, the forward pass by hand, gradients).
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
#include "rnn_test_support.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using namespace rnn_test;

// ------------------------------------------------------------------ JordanRnn

TEST(JordanRnn, ParameterCountTable1) {
  EXPECT_EQ(JordanRnn::parameter_count({3, 6, 6, 3, 1}), 91u);  // Table 1: 91 weights
  EXPECT_EQ(JordanRnn::parameter_count({2, 1}), 3u);
  EXPECT_EQ(JordanRnn::parameter_count({2, 2, 1}), 2u * 3 + 3);
  EXPECT_EQ(JordanRnn::parameter_count({3, 5, 1}), 5u * 4 + 6);
  EXPECT_EQ(JordanRnn::parameter_count({4, 1}), 5u);
  JordanRnn net({3, 6, 6, 3, 1});
  EXPECT_EQ(net.parameter_count(), 91u);
  EXPECT_EQ(net.external_input_count(), 2u);
  EXPECT_EQ(net.layer_sizes(), (std::vector<int>{3, 6, 6, 3, 1}));
  EXPECT_EQ(net.weights(), std::vector<double>(91, 0.0));
}

TEST(JordanRnn, RejectsBadLayerSizesNamingTheEntry) {
  expect_invalid([] { JordanRnn n(std::vector<int>{}); }, {"layer_sizes", "at least 2"});
  expect_invalid([] { JordanRnn n({3}); }, {"layer_sizes", "got 1"});
  expect_invalid([] { JordanRnn n({1, 1}); }, {"layer_sizes[0]", "got 1"});
  expect_invalid([] { JordanRnn n({3, 0, 1}); }, {"layer_sizes[1]", ">= 1", "got 0"});
  expect_invalid([] { JordanRnn n({3, 4, -2, 1}); }, {"layer_sizes[2]", "got -2"});
  expect_invalid([] { JordanRnn n({3, 6, 2}); }, {"layer_sizes[2]", "1 neuron", "got 2"});
  expect_invalid([] { JordanRnn n({3, 100000, 1}); }, {"layer_sizes[1]", "got 100000"});
  expect_invalid([] { JordanRnn::parameter_count({3, 0, 1}); }, {"layer_sizes[1]"});
}

TEST(JordanRnn, ForwardMatches2_1ByHand) {
  // One tanh neuron: inputs x (external) and s (the state unit), then the bias.
  JordanRnn net({2, 1});
  const double w0 = 0.7, w1 = -1.3, b = 0.25;
  net.set_weights({w0, w1, b});
  net.reset_state(0.4);
  const double x = -0.9;
  const double u = net.forward(&x);
  EXPECT_EQ(u, std::tanh(b + w0 * x + w1 * 0.4));
  EXPECT_EQ(net.output(), u);
  EXPECT_EQ(net.state_unit(), 0.4);  // forward() does not advance the state unit
}

TEST(JordanRnn, ForwardMatches2_2_1ByHand) {
  JordanRnn net({2, 2, 1});
  // hidden 0: w00 w01 b0, hidden 1: w10 w11 b1, output: v0 v1 c
  const std::vector<double> w{0.5, -0.2, 0.1, -1.1, 0.8, -0.3, 1.7, -0.6, 0.05};
  net.set_weights(w);
  net.reset_state(-0.35);
  const double x = 1.2, s = -0.35;
  const double h0 = std::tanh(w[2] + w[0] * x + w[1] * s);
  const double h1 = std::tanh(w[5] + w[3] * x + w[4] * s);
  const double u = std::tanh(w[8] + w[6] * h0 + w[7] * h1);
  EXPECT_EQ(net.forward(&x), u);
}

TEST(JordanRnn, OutputIsBoundedByOne) {
  JordanRnn net({3, 6, 6, 3, 1});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> big(-1e3, 1e3);
  for (int trial = 0; trial < 200; ++trial) {
    net.set_weights(random_weights(91, 50.0, 100 + trial));
    net.reset_state(big(rng) > 0 ? 1.0 : -1.0);
    const double x[2] = {big(rng), big(rng)};
    const double u = net.forward(x);
    ASSERT_TRUE(std::isfinite(u));
    ASSERT_LE(std::abs(u), 1.0);
  }
}

TEST(JordanRnn, GradientMatchesCentralDifferences) {
  JordanRnn net({3, 6, 6, 3, 1});
  const std::size_t n = net.parameter_count();
  std::vector<double> g(n), w;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    w = random_weights(n, 0.8, seed);
    std::mt19937_64 rng(seed + 50);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const double x[2] = {u(rng), u(rng)};
    const double s = u(rng);
    net.set_weights(w);
    net.reset_state(s);
    net.forward(x);
    net.gradient(g.data());
    double err2 = 0, norm2 = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double h = 1e-5;
      std::vector<double> wp = w, wm = w;
      wp[i] += h;
      wm[i] -= h;
      net.set_weights(wp);
      const double fp = net.forward(x);
      net.set_weights(wm);
      const double fm = net.forward(x);
      const double fd = (fp - fm) / (2 * h);
      EXPECT_NEAR(g[i], fd, 1e-6 * std::max(std::abs(fd), 1e-3)) << "seed " << seed << " weight " << i;
      err2 += (g[i] - fd) * (g[i] - fd);
      norm2 += fd * fd;
    }
    EXPECT_LT(std::sqrt(err2 / norm2), 1e-6) << "seed " << seed;
    net.set_weights(w);
  }
}

// The chain of linear_chain_weights: for small inputs the network is u = gain x_0, whatever the
// other inputs and the state unit; the links are even (|gain|^(1/4) for 3-6-6-3-1), the sign on
// the output's; large inputs saturate towards sign(gain x_0). A gain whose links would pass the
// largest weight, a zero or non-finite gain, are refused.
TEST(JordanRnn, LinearChainWeightsActAsTheLinearLawForSmallInputs) {
  const std::vector<int> sizes{3, 6, 6, 3, 1};
  const double gain = -11.85;
  const std::vector<double> w = JordanRnn::linear_chain_weights(sizes, gain);
  ASSERT_EQ(w.size(), 91u);
  JordanRnn net(sizes);
  net.set_weights(w);
  for (double x0 : {-1e-3, 2e-4, 5e-3}) {
    for (double other : {0.0, 0.7}) {
      net.reset_state(other);
      const double inputs[2] = {x0, -other};
      EXPECT_NEAR(net.forward(inputs), gain * x0, 5e-3 * std::abs(gain * x0)) << x0 << " " << other;
    }
  }
  const double big[2] = {1.4, 0.0};
  EXPECT_LT(net.forward(big), -0.9);
  std::size_t nonzero = 0;
  for (double x : w) nonzero += x != 0.0;
  EXPECT_EQ(nonzero, 4u);
  EXPECT_NEAR(std::abs(w[0]), std::pow(11.85, 0.25), 1e-12);
  JordanRnn direct({2, 1});
  direct.set_weights(JordanRnn::linear_chain_weights({2, 1}, 0.5));
  EXPECT_EQ(direct.weights(), (std::vector<double>{0.5, 0.0, 0.0}));
  expect_invalid([&] { JordanRnn::linear_chain_weights(sizes, 0.0); }, {"gain: must be finite and not 0"});
  expect_invalid([&] { JordanRnn::linear_chain_weights(sizes, kNan); }, {"gain"});
  expect_invalid([&] { JordanRnn::linear_chain_weights({2, 1}, 150.0); }, {"gain: 150", "above the largest weight"});
  expect_invalid([&] { JordanRnn::linear_chain_weights({2, 2}, 1.0); }, {"layer_sizes[1]"});
}

TEST(JordanRnn, StateUnitCarriesThePreviousOutput) {
  JordanRnn net({2, 1});
  const double w0 = 0.3, w1 = 0.9, b = 0.2;
  net.set_weights({w0, w1, b});
  const double x = 0.5;
  const double u1 = net.forward(&x);
  EXPECT_EQ(net.forward(&x), u1);  // without commit_output: same state, same output
  net.commit_output();
  EXPECT_EQ(net.state_unit(), u1);
  const double u2 = net.forward(&x);
  EXPECT_EQ(u2, std::tanh(b + w0 * x + w1 * u1));
  EXPECT_NE(u2, u1);
  net.reset_state();
  EXPECT_EQ(net.state_unit(), 0.0);
  EXPECT_EQ(net.forward(&x), u1);
}

TEST(JordanRnn, SetWeightsRejectsWrongSizeAndNonFiniteKeepingOldWeights) {
  JordanRnn net({3, 6, 6, 3, 1});
  const std::vector<double> good = random_weights(91, 1.0, 9);
  net.set_weights(good);
  expect_invalid([&] { net.set_weights(std::vector<double>(90, 0.0)); }, {"weights: expected 91 values, got 90"});
  std::vector<double> bad = good;
  bad[17] = kNan;
  expect_invalid([&] { net.set_weights(bad); }, {"weights[17]: must be finite, got nan"});
  bad[17] = -kInf;
  expect_invalid([&] { net.set_weights(bad); }, {"weights[17]: must be finite, got -inf"});
  EXPECT_EQ(net.weights(), good);
}

// ------------------------------------------------------------- RnnCompensator

}  // namespace
}  // namespace pmlsm
