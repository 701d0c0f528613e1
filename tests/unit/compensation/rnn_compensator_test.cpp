// The RNN compensator: its inputs, online learning (section 3.2) and its guards against bad input.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
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
#include "allocation_counter.hpp"
#include "rnn_test_support.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using namespace rnn_test;

TEST(RnnCompensator, ParamsValidationNamesTheField) {
  EXPECT_NO_THROW(base_params().validate());
  auto with = [](auto change) {
    RnnCompensatorParams p = base_params();
    change(p);
    return p;
  };
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.layer_sizes = {3, 6, 2}; })); }, {"layer_sizes[2]"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.input_scale_s2_per_m = 0; })); },
                 {"input_scale_s2_per_m: must be in [", "got 0"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.gain_n = -300; })); }, {"gain_n", "-300"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.period_s = kNan; })); }, {"period_s", "nan"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.learning_rate = -1; })); }, {"learning_rate", "-1"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.learning_rate = 300; })); },
                 {"learning_rate: must be in [0, 100]", "got 300"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.momentum = 1.0; })); },
                 {"momentum: must be in [0, 0.999]", "got 1"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.tolerance_mps = -1e-3; })); }, {"tolerance_mps"});
  expect_invalid([&] { RnnCompensator c(with([](auto& p) { p.kc_limit_mps = 0; })); },
                 {"kc_limit_mps: must be in [", "got 0"});
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
  p.learning_rate = 100.0;  // the largest declared
  RnnCompensator comp(p);
  comp.set_weights(random_weights(91, 0.5, 10));
  comp.step({1.0, 0.0, 0.0});  // |e| = 0: no update, the output moves from 0
  const std::vector<double> before = comp.weights();
  const CompensatorStep out = comp.step({2.0, 1e308, -1e308});  // finite inputs, e = V_ref - V_load overflows
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

/// The fixed point of u = tanh(b + w_s u), found by iterating it here (the 3-1 network with no signal).
double fixed_point(double bias, double state_weight) {
  double u = 0;
  for (int i = 0; i < 10000; ++i) u = std::tanh(bias + state_weight * u);
  return u;
}

// A network's biases hold a load at rest with a force of their own: the fixed point u* of its state
// unit with no signal. Once the reference has rested rest_settle_s, u* is taken out over
// rest_fade_s; the tick the reference moves the network's force is whole again.
TEST(RnnCompensator, TakesTheNetworksOutputAtRestOutOnceTheReferenceRests) {
  RnnCompensatorParams p = base_params();
  p.layer_sizes = {3, 1};
  p.online_learning = false;
  p.remove_rest_output = true;
  p.rest_settle_s = 0.05;  // 50 ticks
  p.rest_fade_s = 0.02;    // 20 ticks
  p.rest_velocity_mps = 1e-3;
  RnnCompensator comp(p);
  comp.set_weights({0.8, -0.4, 0.6, 0.1});
  const double u_rest = fixed_point(0.1, 0.6);
  EXPECT_NEAR(comp.rest_output(), u_rest, 1e-10);
  EXPECT_NEAR(comp.rest_force_n(), p.gain_n * u_rest, 1e-9);
  ASSERT_GT(comp.rest_force_n(), 50.0) << "a network with a force of its own at rest";
  RnnCompensatorParams kept_params = p;
  kept_params.remove_rest_output = false;
  RnnCompensator kept(kept_params);
  kept.set_weights(comp.weights());
  CompensatorInput rest;  // no signal, the command and V_ref at 0
  for (int k = 1; k <= 100; ++k) {
    const CompensatorStep out = comp.step(rest);
    const CompensatorStep bare = kept.step(rest);
    EXPECT_EQ(out.u_n, bare.u_n) << "the network itself is untouched";
    EXPECT_EQ(bare.force_n, p.gain_n * bare.u_n);
    // Tick k has rested k ticks: w = clamp((k T - settle) / fade, 0, 1).
    const double share = std::clamp((k * 1e-3 - 0.05) / 0.02, 0.0, 1.0);
    EXPECT_NEAR(out.force_n, p.gain_n * (out.u_n - share * u_rest), 1e-9) << "tick " << k;
  }
  EXPECT_NEAR(comp.step(rest).force_n, 0.0, 1e-9) << "at rest, nothing pushes the motor";
  EXPECT_NEAR(kept.step(rest).force_n, p.gain_n * u_rest, 1e-9);
  // Within rest_velocity_mps the reference still rests; beyond, the force is whole at once.
  rest.v_ref_mps = 0.9e-3;
  EXPECT_NEAR(comp.step(rest).force_n, 0.0, 1e-9);
  rest.command_mps = 0.01;
  const CompensatorStep moving = comp.step(rest);
  EXPECT_EQ(moving.force_n, p.gain_n * moving.u_n);
  // reset(): the rest is counted again from the start.
  rest.command_mps = 0.0;
  rest.v_ref_mps = 0.0;
  comp.reset();
  const CompensatorStep first = comp.step(rest);
  EXPECT_EQ(first.force_n, p.gain_n * first.u_n);
}

// A network whose state unit oscillates with no signal has no output at rest: nothing is taken
// out, and finding that out leaves its state unit as it was.
TEST(RnnCompensator, ANetworkThatOscillatesWithNoSignalHasNoOutputAtRest) {
  JordanRnn net({2, 1});
  net.set_weights({0.0, -5.0, 1.0});  // u(k) = tanh(1 - 5 u(k-1)): a two-cycle near +-1
  net.reset_state(0.25);
  EXPECT_FALSE(net.rest_output().has_value());
  EXPECT_EQ(net.state_unit(), 0.25);
  JordanRnn settles({2, 1});
  settles.set_weights({0.0, 0.6, 0.1});
  ASSERT_TRUE(settles.rest_output().has_value());
  EXPECT_NEAR(*settles.rest_output(), fixed_point(0.1, 0.6), 1e-10);

  RnnCompensatorParams p = base_params();
  p.layer_sizes = {2, 1};
  p.online_learning = false;
  p.remove_rest_output = true;
  p.rest_velocity_mps = 1e-3;
  RnnCompensator comp(p);
  comp.set_weights({0.0, -5.0, 1.0});
  EXPECT_EQ(comp.rest_output(), 0.0);
  for (int k = 0; k < 100; ++k) {
    const CompensatorStep out = comp.step({});
    EXPECT_EQ(out.force_n, p.gain_n * out.u_n);
  }
}

// With online learning the weights move, and u* with them: one pass of the fixed-point iteration
// a tick follows it, so once the weights stop moving it is the new weights' output at rest.
TEST(RnnCompensator, WithOnlineLearningTheOutputAtRestFollowsTheWeights) {
  RnnCompensatorParams p = base_params();
  p.remove_rest_output = true;
  p.rest_velocity_mps = 1e-3;
  RnnCompensator comp(p);
  comp.set_weights(random_weights(91, 0.3, 7));
  const double before = comp.rest_output();
  for (int k = 0; k < 2000; ++k) comp.step({30.0 * std::sin(0.05 * k), 0.1, 0.1 + 0.05 * std::sin(0.02 * k)});
  ASSERT_GT(comp.counters().updates, 500u);
  for (int k = 0; k < 500; ++k) comp.step({0.0, 0.1, 0.1});  // inside the tolerance: no update
  RnnCompensator fresh(p);
  fresh.set_weights(comp.weights());
  std::printf("[ rest output ] u* %.6f before learning, %.6f after (%.6f found afresh)\n", before, comp.rest_output(),
              fresh.rest_output());
  EXPECT_GT(std::abs(fresh.rest_output() - before), 1e-3) << "the learning moved u*";
  EXPECT_NEAR(comp.rest_output(), fresh.rest_output(), 1e-9);
}

TEST(RnnCompensator, StepDoesNotAllocate) {
  RnnCompensatorParams p = base_params();
  p.remove_rest_output = true;  // and the pass a tick that follows u* while learning
  p.rest_velocity_mps = 1e-3;
  RnnCompensator comp(p);
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

}  // namespace
}  // namespace pmlsm
