// The Jordan network and the online-learning compensator of section 3.2, and the
// weights file.
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
#include "pmlsm/sim/rnn_training.hpp"
#include "allocation_counter.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;

const double kNan = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();
const double kPi = 3.14159265358979323846;

std::vector<double> random_weights(std::size_t n, double scale, std::uint64_t seed) {
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

RnnCompensatorParams base_params() {
  RnnCompensatorParams p;
  p.layer_sizes = {3, 6, 6, 3, 1};
  p.input_scale_s2_per_m = 0.02;
  p.gain_n = 300;
  p.period_s = 1e-3;
  p.online_learning = true;
  p.learning_rate = 3.0;
  p.momentum = 0.5;
  p.tolerance_mps = 1e-4;
  p.kc_limit_mps = 1.0;
  p.du_deadband_per_s = 1e-3;
  return p;
}

TEST(RnnCompensator, ParamsValidationNamesTheField) {
  EXPECT_NO_THROW(base_params().validate());
  auto with = [](auto change) {
    RnnCompensatorParams p = base_params();
    change(p);
    return p;
  };
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.layer_sizes = {3, 6, 2}; })); }, {"layer_sizes[2]"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.input_scale_s2_per_m = 0; })); },
                 {"input_scale_s2_per_m: must be > 0, got 0"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.gain_n = -300; })); }, {"gain_n", "-300"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.period_s = kNan; })); }, {"period_s", "nan"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.learning_rate = -1; })); }, {"learning_rate", "-1"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.momentum = 1.0; })); },
                 {"momentum: must be in [0, 1), got 1"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.tolerance_mps = -1e-3; })); }, {"tolerance_mps"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.kc_limit_mps = 0; })); }, {"kc_limit_mps: must be > 0"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.kc_limit_mps = 2.0; })); },
                 {"kc_limit_mps", "momentum * kc_limit_mps must be < 1", "0.5 * 2 = 1"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.du_deadband_per_s = 0; })); }, {"du_deadband_per_s"});
}

TEST(RnnCompensator, FeedsScaledAccelerationHistoryAndStateUnit) {
  // 3-1 network: u(k) = tanh(w0 s a(k) + w1 s a(k-1) + w2 u(k-1) + b), force = G u.
  RnnCompensatorParams p = base_params();
  p.layer_sizes = {3, 1};
  p.online_learning = false;
  RnnCompensator comp(p);
  EXPECT_EQ(comp.weights(), std::vector<double>(4, 0.0));
  const std::vector<double> w{0.8, -0.4, 0.6, 0.1};
  comp.set_weights(w);
  const double s = p.input_scale_s2_per_m;
  const double a[4] = {3.0, -5.0, 12.0, 0.5};
  double a_prev = 0, u_prev = 0;
  for (double ak : a) {
    const CompensatorStep out = comp.step({ak, 0.0, 0.0});
    const double u = std::tanh(w[3] + w[0] * (s * ak) + w[1] * (s * a_prev) + w[2] * u_prev);
    EXPECT_EQ(out.u_n, u);
    EXPECT_EQ(out.force_n, p.gain_n * u);
    EXPECT_FALSE(out.input_rejected);
    a_prev = ak;
    u_prev = u;
  }
  EXPECT_EQ(comp.counters().steps, 4u);
  EXPECT_EQ(comp.counters().updates, 0u);
  // reset(): state unit and the a_L history back to 0, so the first output repeats.
  comp.reset();
  EXPECT_EQ(comp.step({a[0], 0.0, 0.0}).u_n, std::tanh(w[3] + w[0] * (s * a[0])));
}

TEST(RnnCompensator, OnTheReferenceErrorFeedsTheAccelerationErrorInstead) {
  RnnCompensatorParams p = base_params();
  p.layer_sizes = {3, 1};
  p.online_learning = false;
  RnnCompensator paper(p);
  p.on_reference_error = true;
  RnnCompensator on_error(p);
  const std::vector<double> w{0.8, -0.4, 0.6, 0.1};
  paper.set_weights(w);
  on_error.set_weights(w);
  // (a_L, dV_ref/dt): the error network sees a_L - dV_ref/dt where the paper's sees a_L.
  const double a[4][2] = {{3.0, 1.0}, {-5.0, 2.5}, {12.0, -4.0}, {0.5, 0.5}};
  for (const auto& ak : a) {
    const double u_error = on_error.step({ak[0], 0.0, 0.0, ak[1]}).u_n;
    EXPECT_EQ(u_error, paper.step({ak[0] - ak[1], 0.0, 0.0, 123.0}).u_n);
  }
  // A non-finite reference acceleration is a rejected input there, ignored by the paper's form.
  EXPECT_TRUE(on_error.step({1.0, 0.0, 0.0, std::nan("")}).input_rejected);
  EXPECT_FALSE(paper.step({1.0, 0.0, 0.0, std::nan("")}).input_rejected);
}

TEST(RnnCompensator, GeneralisesToLongerAccelerationHistory) {
  RnnCompensatorParams p = base_params();
  p.layer_sizes = {4, 1};  // s a(k), s a(k-1), s a(k-2), state unit
  p.online_learning = false;
  RnnCompensator comp(p);
  const std::vector<double> w{0.3, 0.5, -0.7, 0.0, 0.0};
  comp.set_weights(w);
  const double s = p.input_scale_s2_per_m;
  comp.step({10.0, 0, 0});
  comp.step({20.0, 0, 0});
  EXPECT_EQ(comp.step({30.0, 0, 0}).u_n, std::tanh(0.0 + 0.3 * (s * 30.0) + 0.5 * (s * 20.0) + -0.7 * (s * 10.0)));
}

/// The toy plant of the online-learning tests: m dv/dt = sign * F - b v, exact
/// ZOH over each tick, time constant m/b = 0.5 ms (V_load follows the force
/// almost statically: the regime in which k_c = a_L / dU_n estimates dV_L/dU_n
/// = sign * G_n / b). a_L is the mean acceleration of the last tick, as an
/// estimator delivers it; V_ref = 0.05 sin(2 pi 2 t) m/s. Returns the mean
/// |V_ref - V_load| over the second second.
struct ToyRun {
  double mean_abs_error = 0;
  double mean_kc = 0;
  CompensatorCounters counters;
};

ToyRun run_toy_plant(const RnnCompensatorParams& p, double plant_sign, std::uint64_t seed) {
  RnnCompensator comp(p);
  comp.set_weights(random_weights(comp.weights().size(), 0.3, seed));
  const double mass = 1.5, damping = 3000, ts = p.period_s;
  const double phi = std::exp(-ts * damping / mass);
  double v = 0, a = 0, err_sum = 0, kc_sum = 0;
  int err_n = 0, kc_n = 0;
  const int ticks = 2000;
  for (int k = 0; k < ticks; ++k) {
    const double v_ref = 0.05 * std::sin(2 * kPi * 2.0 * k * ts);
    const CompensatorStep out = comp.step({a, v_ref, v});
    const double v_ss = plant_sign * out.force_n / damping;
    const double v_next = v_ss + (v - v_ss) * phi;
    a = (v_next - v) / ts;
    v = v_next;
    if (k >= ticks / 2) {
      err_sum += std::abs(v_ref - v);
      ++err_n;
    }
    if (out.weights_updated) {
      kc_sum += out.k_c_mps;
      ++kc_n;
    }
  }
  return {err_sum / err_n, kc_n ? kc_sum / kc_n : 0.0, comp.counters()};
}

TEST(RnnCompensator, OnlineLearningReducesTheVelocityError) {
  // The update (19) descends e^2/2; with the wrong sign (or k_c's sign ignored,
  // checked by the reversed plant) the network runs into saturation and the
  // error grows to ~0.1 m/s instead.
  RnnCompensatorParams on = base_params();
  RnnCompensatorParams off = on;
  off.online_learning = false;
  for (double sign : {+1.0, -1.0}) {
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
      const ToyRun with = run_toy_plant(on, sign, seed);
      const ToyRun without = run_toy_plant(off, sign, seed);
      EXPECT_GT(without.mean_abs_error, 0.025) << "sign " << sign << " seed " << seed;
      EXPECT_LT(with.mean_abs_error, 0.5 * without.mean_abs_error) << "sign " << sign << " seed " << seed;
      EXPECT_GT(with.counters.updates, 1900u);
      EXPECT_EQ(with.counters.reverted_updates, 0u);
      EXPECT_EQ(without.counters.updates, 0u);
      // k_c (17)-(18) recovers the plant's static gain dV/dU_n = sign * G_n / b.
      EXPECT_NEAR(with.mean_kc, sign * on.gain_n / 3000.0, 0.02) << "sign " << sign << " seed " << seed;
    }
  }
}

TEST(RnnCompensator, NoUpdateWithinTolerance) {
  RnnCompensatorParams p = base_params();
  p.tolerance_mps = 0.01;
  RnnCompensator comp(p);
  const std::vector<double> w = random_weights(91, 0.5, 4);
  comp.set_weights(w);
  for (int k = 0; k < 50; ++k) {
    const CompensatorStep out = comp.step({std::sin(0.3 * k) * 20.0, 0.105, 0.1});  // |e| = 0.005
    EXPECT_FALSE(out.weights_updated);
    EXPECT_NEAR(out.training_error_mps, 0.005, 1e-12);
  }
  EXPECT_EQ(comp.weights(), w);
  EXPECT_EQ(comp.counters().updates, 0u);
  EXPECT_EQ(comp.counters().kc_deadband, 0u);
}

TEST(RnnCompensator, DeadbandStopsUpdatesWhenTheOutputDoesNotMove) {
  // Zero weights: u_n = 0 every tick, dU_n = 0, k_c undefined -> no update.
  RnnCompensator comp(base_params());
  for (int k = 0; k < 20; ++k) {
    const CompensatorStep out = comp.step({5.0, 0.1, 0.0});
    EXPECT_TRUE(out.kc_guarded);
    EXPECT_FALSE(out.weights_updated);
    EXPECT_EQ(out.k_c_mps, 0.0);
  }
  EXPECT_EQ(comp.counters().kc_deadband, 20u);
  EXPECT_EQ(comp.counters().updates, 0u);
  EXPECT_EQ(comp.weights(), std::vector<double>(91, 0.0));
}

TEST(RnnCompensator, KcIsClampedAndCounted) {
  RnnCompensatorParams p = base_params();
  p.kc_limit_mps = 0.01;  // below the toy plant's k_c of 0.1
  RnnCompensator comp(p);
  comp.set_weights(random_weights(91, 0.3, 5));
  int clamped = 0;
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> accel(-50.0, 50.0);
  for (int k = 0; k < 200; ++k) {
    const CompensatorStep out = comp.step({accel(rng), 0.1, 0.0});
    EXPECT_LE(std::abs(out.k_c_mps), p.kc_limit_mps);
    if (out.weights_updated && std::abs(out.k_c_mps) == p.kc_limit_mps) {
      EXPECT_TRUE(out.kc_guarded);
      ++clamped;
    }
  }
  EXPECT_GT(clamped, 0);
  EXPECT_EQ(comp.counters().kc_clamped, static_cast<std::uint64_t>(clamped));
  EXPECT_EQ(comp.counters().updates + comp.counters().kc_deadband, 200u);
}

TEST(RnnCompensator, RejectsNonFiniteInputLeavingStateAndWeights) {
  RnnCompensator comp(base_params()), twin(base_params());
  const std::vector<double> w = random_weights(91, 0.5, 8);
  comp.set_weights(w);
  twin.set_weights(w);
  comp.step({4.0, 0.1, 0.0});
  twin.step({4.0, 0.1, 0.0});
  const std::vector<double> learned = comp.weights();
  const CompensatorInput bad[] = {{kNan, 0.1, 0.0}, {1.0, kInf, 0.0}, {1.0, 0.1, -kInf}};
  for (const CompensatorInput& in : bad) {
    const CompensatorStep out = comp.step(in);
    EXPECT_TRUE(out.input_rejected);
    EXPECT_EQ(out.force_n, 0.0);
    EXPECT_FALSE(out.weights_updated);
  }
  EXPECT_EQ(comp.counters().rejected_inputs, 3u);
  EXPECT_EQ(comp.counters().steps, 4u);
  EXPECT_EQ(comp.weights(), learned);
  // State unit, a_L history and momentum untouched: the next ticks match the twin's.
  for (int k = 0; k < 5; ++k) {
    const CompensatorStep a = comp.step({-3.0 + k, 0.1, 0.0});
    const CompensatorStep b = twin.step({-3.0 + k, 0.1, 0.0});
    EXPECT_EQ(a.u_n, b.u_n);
    EXPECT_EQ(a.weights_updated, b.weights_updated);
  }
  EXPECT_EQ(comp.weights(), twin.weights());
}

TEST(RnnCompensator, RevertsAnUpdateThatWouldMakeWeightsNonFinite) {
  RnnCompensatorParams p = base_params();
  p.learning_rate = 1e300;
  RnnCompensator comp(p);
  comp.set_weights(random_weights(91, 0.5, 10));
  comp.step({1.0, 0.0, 0.0});  // |e| = 0: no update, the output moves from 0
  const std::vector<double> before = comp.weights();
  const CompensatorStep out = comp.step({2.0, 1e10, 0.0});  // eta * e overflows
  EXPECT_FALSE(out.weights_updated);
  EXPECT_EQ(comp.counters().reverted_updates, 1u);
  EXPECT_EQ(comp.counters().updates, 0u);
  EXPECT_EQ(comp.weights(), before);
}

TEST(RnnCompensator, SetWeightsValidatesAndKeepsOldWeights) {
  RnnCompensator comp(base_params());
  const std::vector<double> good = random_weights(91, 0.5, 11);
  comp.set_weights(good);
  expect_invalid([&] { comp.set_weights(std::vector<double>(92, 0.0)); }, {"weights: expected 91 values, got 92"});
  std::vector<double> bad = good;
  bad[3] = kNan;
  expect_invalid([&] { comp.set_weights(bad); }, {"weights[3]: must be finite"});
  EXPECT_EQ(comp.weights(), good);
}

TEST(RnnCompensator, StepDoesNotAllocate) {
  RnnCompensator comp(base_params());
  comp.set_weights(random_weights(91, 0.5, 12));
  comp.step({1.0, 0.1, 0.0});
  const std::uint64_t before = pmlsm::test::allocations();
  double sink = 0;
  for (int k = 0; k < 1000; ++k) sink += comp.step({std::sin(0.01 * k) * 30.0, 0.1, 0.0}).force_n;
  comp.step({kNan, 0.0, 0.0});
  EXPECT_EQ(pmlsm::test::allocations(), before);
  EXPECT_TRUE(std::isfinite(sink));
  EXPECT_GT(comp.counters().updates, 0u);
}

// ---------------------------------------------------------------- weights file

class WeightsFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("pmlsm_rnn_test_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  static RnnWeightsFile sample() {
    RnnWeightsFile f;
    f.layer_sizes = {3, 6, 6, 3, 1};
    f.input_scale_s2_per_m = 0.02;
    f.gain_n = 300.0;
    f.cost = 5.3;
    f.source = "de_trainer seed 1 gen 433";
    f.weights = random_weights(91, 2.0, 21);
    return f;
  }

  // The sample file's text with one line replaced (or removed when with is empty).
  std::string write_variant(const std::string& name, const std::string& line_start, const std::string& with) {
    save_rnn_weights(path("base.yaml"), sample());
    std::ifstream in(path("base.yaml"));
    std::ostringstream out;
    std::string line;
    bool replaced = false;
    while (std::getline(in, line)) {
      if (!replaced && line.rfind(line_start, 0) == 0) {
        replaced = true;
        if (!with.empty()) out << with << "\n";
        continue;
      }
      out << line << "\n";
    }
    EXPECT_TRUE(replaced) << line_start;
    std::ofstream(path(name)) << out.str();
    return path(name);
  }

  // The sample with the weights written as given (one flow list).
  std::string write_weights(const std::string& name, const std::string& weights_list) {
    save_rnn_weights(path("base.yaml"), sample());
    std::ifstream in(path("base.yaml"));
    std::ostringstream out;
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("weights:", 0) == 0) break;
      out << line << "\n";
    }
    out << "weights: [" << weights_list << "]\n";
    std::ofstream(path(name)) << out.str();
    return path(name);
  }

  static std::string list_of(const std::vector<std::string>& values) {
    std::string s;
    for (std::size_t i = 0; i < values.size(); ++i) s += (i ? ", " : "") + values[i];
    return s;
  }

  void expect_load_error(const std::string& file, const std::vector<std::string>& parts) {
    try {
      load_rnn_weights(file);
      ADD_FAILURE() << file << ": loaded; expected an error containing '" << parts.front() << "'";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file + ": ", 0), 0u) << what;  // names the file first
      for (const std::string& p : parts) EXPECT_NE(what.find(p), std::string::npos) << what;
    }
  }

  fs::path dir_;
};

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST_F(WeightsFile, RoundTripIsBitExact) {
  RnnWeightsFile f = sample();
  f.source = "de \"trainer\" \\ seed: 1 # gen 433\nline two\ttab";
  f.input_scale_s2_per_m = 1.0 / 3.0;
  f.cost = -1;
  // Within the +-100 a set may hold (JordanRnn::kMaxAbsWeight), every digit counts.
  const double specials[] = {0.1,
                             1.0 / 3.0,
                             -0.0,
                             1e-300,
                             4.9406564584124654e-324,
                             99.999999999999986,
                             -2.2250738585072014e-308,
                             -98.765432109876543};
  for (std::size_t i = 0; i < std::size(specials); ++i) f.weights[i * 11] = specials[i];
  save_rnn_weights(path("w.yaml"), f);
  EXPECT_FALSE(fs::exists(path("w.yaml.tmp")));
  const RnnWeightsFile g = load_rnn_weights(path("w.yaml"));
  EXPECT_EQ(g.layer_sizes, f.layer_sizes);
  EXPECT_TRUE(same_bits(g.input_scale_s2_per_m, f.input_scale_s2_per_m));
  EXPECT_TRUE(same_bits(g.gain_n, f.gain_n));
  EXPECT_TRUE(same_bits(g.cost, f.cost));
  EXPECT_EQ(g.source, f.source);
  ASSERT_EQ(g.weights.size(), f.weights.size());
  for (std::size_t i = 0; i < f.weights.size(); ++i) {
    EXPECT_TRUE(same_bits(g.weights[i], f.weights[i])) << i << ": " << g.weights[i] << " vs " << f.weights[i];
  }
  // And the loaded set drives a network of its sizes.
  RnnCompensatorParams p = base_params();
  p.layer_sizes = g.layer_sizes;
  RnnCompensator comp(p);
  EXPECT_NO_THROW(comp.set_weights(g.weights));
}

TEST_F(WeightsFile, CarriesTheInputItWasTrainedOnAndReadsOlderSetsAsThePapers) {
  RnnWeightsFile f = sample();
  f.on_reference_error = true;
  save_rnn_weights(path("error.yaml"), f);
  EXPECT_TRUE(load_rnn_weights(path("error.yaml")).on_reference_error);
  f.on_reference_error = false;
  save_rnn_weights(path("paper.yaml"), f);
  EXPECT_FALSE(load_rnn_weights(path("paper.yaml")).on_reference_error);
  // A set written before the key existed was trained on a_L.
  const std::string older = write_variant("older.yaml", "input:", "");
  EXPECT_FALSE(load_rnn_weights(older).on_reference_error);
}

TEST_F(WeightsFile, ReadsTheDocumentedFormat) {
  std::vector<std::string> w(9, "0.5");
  std::ofstream(path("doc.yaml")) << "format: pmlsm-rnn-weights/1\n"
                                     "layer_sizes: [2, 2, 1]\n"
                                     "input_scale_s2_per_m: 0.02\n"
                                     "gain_n: 300.0\n"
                                     "cost: 5.3            # cost (23)\n"
                                     "source: \"de_trainer seed 1 gen 433\"\n"
                                     "weights: ["
                                  << list_of(w) << "]\n";
  const RnnWeightsFile f = load_rnn_weights(path("doc.yaml"));
  EXPECT_EQ(f.layer_sizes, (std::vector<int>{2, 2, 1}));
  EXPECT_EQ(f.gain_n, 300.0);
  EXPECT_EQ(f.cost, 5.3);
  EXPECT_EQ(f.source, "de_trainer seed 1 gen 433");
  EXPECT_EQ(f.weights, std::vector<double>(9, 0.5));
}

TEST_F(WeightsFile, SaveReplacesAtomicallyWithoutLeavingTmp) {
  RnnWeightsFile f = sample();
  save_rnn_weights(path("w.yaml"), f);
  f.cost = 1.25;
  f.weights[0] = 42.0;
  save_rnn_weights(path("w.yaml"), f);  // over an existing file
  EXPECT_FALSE(fs::exists(path("w.yaml.tmp")));
  const RnnWeightsFile g = load_rnn_weights(path("w.yaml"));
  EXPECT_EQ(g.cost, 1.25);
  EXPECT_EQ(g.weights[0], 42.0);
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) {
    EXPECT_EQ(entry.path().extension(), ".yaml") << entry.path();
    ++files;
  }
  EXPECT_EQ(files, 1u);
}

TEST_F(WeightsFile, SaveRejectsInvalidContentAndWritesNothing) {
  RnnWeightsFile f = sample();
  f.weights[3] = kNan;
  try {
    save_rnn_weights(path("w.yaml"), f);
    ADD_FAILURE() << "saved a nan weight";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("weights[3]: must be finite, got nan"), std::string::npos) << e.what();
  }
  f = sample();
  f.weights.pop_back();
  EXPECT_THROW(save_rnn_weights(path("w.yaml"), f), std::runtime_error);
  EXPECT_FALSE(fs::exists(path("w.yaml")));
  EXPECT_FALSE(fs::exists(path("w.yaml.tmp")));
  EXPECT_THROW(save_rnn_weights(path("no/such/dir/w.yaml"), sample()), std::runtime_error);
}

TEST_F(WeightsFile, ValidateNamesTheField) {
  RnnWeightsFile f = sample();
  EXPECT_NO_THROW(validate_rnn_weights(f));
  f.gain_n = 0;
  expect_invalid([&] { validate_rnn_weights(f); }, {"gain_n: must be > 0, got 0"});
  f = sample();
  f.cost = -2;
  expect_invalid([&] { validate_rnn_weights(f); }, {"cost", "-2"});
  f = sample();
  f.layer_sizes = {3, 6, 6, 3, 2};
  expect_invalid([&] { validate_rnn_weights(f); }, {"layer_sizes[4]"});
}

TEST_F(WeightsFile, BadFilesFailNamingTheProblem) {
  expect_load_error(path("missing.yaml"), {"cannot open"});
  expect_load_error(write_variant("unknown.yaml", "cost:", "cost: 5.3\nlearning_rate: 0.1"),
                    {"learning_rate: unknown key"});
  expect_load_error(write_variant("missing_key.yaml", "cost:", ""), {"cost: missing key"});
  expect_load_error(write_variant("tag.yaml", "format:", "format: pmlsm-rnn-weights/2"),
                    {"format: expected 'pmlsm-rnn-weights/1', got 'pmlsm-rnn-weights/2'"});
  expect_load_error(write_variant("sizes.yaml", "layer_sizes:", "layer_sizes: [3, 6, 6, 3, 2]"),
                    {"layer_sizes[4]", "got 2"});
  expect_load_error(write_variant("sizes_text.yaml", "layer_sizes:", "layer_sizes: [3, six, 6, 3, 1]"),
                    {"layer_sizes[1]: expected an integer, got 'six'"});
  expect_load_error(write_variant("gain.yaml", "gain_n:", "gain_n: -1"), {"gain_n: must be > 0, got -1"});
  expect_load_error(write_variant("scale.yaml", "input_scale_s2_per_m:", "input_scale_s2_per_m: fast"),
                    {"input_scale_s2_per_m: expected a number, got 'fast'"});
  expect_load_error(write_variant("dup.yaml", "cost:", "cost: 5.3\ncost: 4.0"), {"cost: duplicate key"});
  expect_load_error(write_variant("input.yaml", "input:", "input: load_velocity"),
                    {"input: expected load_accel or accel_error, got 'load_velocity'"});
  expect_load_error(write_variant("input_dup.yaml", "input:", "input: accel_error\ninput: load_accel"),
                    {"input: duplicate key"});

  std::vector<std::string> w(91, "0.25");
  expect_load_error(write_weights("count.yaml", list_of(std::vector<std::string>(90, "0.25"))),
                    {"weights: expected 91 values", "got 90"});
  std::vector<std::string> with_nan = w;
  with_nan[3] = ".nan";
  expect_load_error(write_weights("nan.yaml", list_of(with_nan)), {"weights[3]: must be finite, got .nan"});
  std::vector<std::string> with_inf = w;
  with_inf[7] = "-.inf";
  expect_load_error(write_weights("inf.yaml", list_of(with_inf)), {"weights[7]: must be finite, got -.inf"});
  std::vector<std::string> with_text = w;
  with_text[5] = "abc";
  expect_load_error(write_weights("text.yaml", list_of(with_text)), {"weights[5]: expected a number, got 'abc'"});
  std::vector<std::string> with_quoted = w;
  with_quoted[6] = "\"0.5\"";
  expect_load_error(write_weights("quoted.yaml", list_of(with_quoted)), {"weights[6]: expected a number"});

  std::ofstream(path("broken.yaml")) << "format: [unclosed\n";
  expect_load_error(path("broken.yaml"), {"YAML parse error"});
  std::ofstream(path("list.yaml")) << "- 1\n- 2\n";
  expect_load_error(path("list.yaml"), {"mapping"});
}

TEST_F(WeightsFile, ImplausibleWeightsAreRefused) {
  // All 1e300: finite, but the compensator would be a +-G_n bang-bang.
  expect_load_error(write_weights("huge.yaml", list_of(std::vector<std::string>(91, "1e300"))),
                    {"weights[0]: must be in [-100, 100]", "got 1e+300"});
  std::vector<std::string> w(91, "0.25");
  w[90] = "-100.5";
  expect_load_error(write_weights("edge.yaml", list_of(w)), {"weights[90]", "got -100.5"});
  w[90] = "-100";
  EXPECT_NO_THROW(load_rnn_weights(write_weights("bound.yaml", list_of(w))));
}

// ---------------------------------------------------------------- weight sets offered to a running compensator

class WeightGate : public ::testing::Test {
 protected:
  WeightGate() : params_(load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml")) {}

  RnnWeightsFile fitting(double scale, std::uint64_t seed, double cost) const {
    RnnWeightsFile f;
    f.layer_sizes = params_.compensator.rnn_layer_sizes;
    f.input_scale_s2_per_m = params_.compensator.rnn_input_scale_s2_per_m;
    f.on_reference_error = params_.compensator.rnn_on_reference_error;
    f.gain_n = params_.compensator.rnn_gain_n;
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
  other_input.on_reference_error = !params_.compensator.rnn_on_reference_error;
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
  JordanRnn net(params_.compensator.rnn_layer_sizes);
  EXPECT_THROW(net.set_weights(huge.weights), std::invalid_argument);
}

}  // namespace
}  // namespace pmlsm
