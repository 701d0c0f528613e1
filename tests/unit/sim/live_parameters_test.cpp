// Live parameters (pmlsm/sim/live_parameters.hpp): a change parsed by its entry's kind and checked
// with the file's ranges and the components' checks, refused with the reason and the old value
// kept, versioned; and the velocity controller taking it at a tick boundary with its integral kept,
// and its position loop (a dual loop: its gain live, its fall back to the motor's encoder).
#include "pmlsm/analysis/analysis_params.hpp"
#include "pmlsm/sim/live_parameters.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/compensation/accel_feedback.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/compensation/state_feedback.hpp"
#include "pmlsm/sim/velocity_controller.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

void expect_live_refused(LiveParameters& live, const std::string& key, const std::string& text, const char* reason) {
  const std::uint64_t version = live.version();
  const std::string before = live.get(key).accepted ? live.get(key).value : "";
  const LiveAnswer a = live.set(key, text);
  EXPECT_FALSE(a.accepted) << key << "=" << text;
  EXPECT_NE(a.reason.find(reason), std::string::npos) << a.reason;
  EXPECT_EQ(a.value, before);
  EXPECT_EQ(live.version(), version);
  EXPECT_FALSE(live.take_pending());
}

TEST(LiveParameters, AChangeIsCheckedLikeTheFileVersionedAndKept) {
  LiveParameters live(test::shipped_params(), live_keys(SystemParams{}, "controller"));
  EXPECT_EQ(live.keys().size(), 4u + 2u * 4u * 5u);
  EXPECT_EQ(live.get("velocity_loop.kp_n_s_per_m").value, "10000");
  const LiveAnswer a = live.set("velocity_loop.kp_n_s_per_m", "12000");
  ASSERT_TRUE(a.accepted) << a.reason;
  EXPECT_EQ(a.version, 1u);
  EXPECT_EQ(a.value, "12000");
  EXPECT_EQ(live.params().velocity_loop.kp_n_s_per_m, 12000.0);
  EXPECT_TRUE(live.take_pending());
  EXPECT_FALSE(live.take_pending());
  ASSERT_EQ(live.history().size(), 1u);
  EXPECT_EQ(live.history()[0].old_value, "10000");
  EXPECT_EQ(live.history()[0].new_value, "12000");

  expect_live_refused(live, "velocity_loop.kp_n_s_per_m", "2e6", "velocity_loop.kp_n_s_per_m: must be in [0, 1000000]");
  expect_live_refused(live, "velocity_loop.kp_n_s_per_m", "fast", "expected a number, got 'fast'");
  expect_live_refused(live, "velocity_loop.kp_n_s_per_m", "0x10", "expected a number");
  expect_live_refused(live, "velocity_loop.ki_n_per_m", "nan", "expected a number");
  expect_live_refused(live, "plant.mechanics.load_mass_kg", "5", "not a live parameter of this node");
  expect_live_refused(live, "filters.force_command.slot_1.kind", "band_pass", "must be one of none, notch");
  // A slot's kind before its values: the notch has no frequency yet (the component's check).
  expect_live_refused(live, "filters.force_command.slot_1.kind", "notch", "frequency_hz: must be in");
  for (const auto& [key, value] : {std::pair<std::string, std::string>{"frequency_hz", "10.2"},
                                   {"damping", "0.02"},
                                   {"second_damping", "0.2"},
                                   {"kind", "notch"}}) {
    const LiveAnswer set = live.set("filters.force_command.slot_1." + key, value);
    EXPECT_TRUE(set.accepted) << key << ": " << set.reason;
  }
  EXPECT_EQ(live.version(), 5u);
  EXPECT_EQ(live.get("filters.force_command.slot_1.kind").value, "notch");
  EXPECT_THROW(LiveParameters(test::shipped_params(), {"velocity_loop.no_such_gain"}), std::invalid_argument);
}

// A tuner's result taken together: a notch's values and its kind in one request, in an order one
// change at a time refuses (the kind first: a notch at 0 Hz), checked once with all of them in;
// one refused entry refuses them all and changes nothing.
TEST(LiveParameters, ChangesTakenTogetherAreAllOrNothing) {
  LiveParameters live(test::shipped_params(), live_keys(SystemParams{}, "controller"));
  const std::string slot = "filters.force_command.slot_1.";
  EXPECT_FALSE(live.set(slot + "kind", "notch").accepted);  // alone: its frequency is still 0
  std::vector<std::pair<std::string, std::string>> notch{{slot + "kind", "notch"},
                                                         {slot + "frequency_hz", "243.2"},
                                                         {slot + "damping", "0.12"},
                                                         {slot + "second_damping", "1.01"},
                                                         {"velocity_loop.kp_n_s_per_m", "5980"}};
  auto with_refused = notch;
  with_refused.emplace_back("velocity_loop.ki_n_per_m", "-1");
  LiveAnswer a = live.set_many(with_refused);
  EXPECT_FALSE(a.accepted);
  EXPECT_NE(a.reason.find("velocity_loop.ki_n_per_m"), std::string::npos) << a.reason;
  EXPECT_EQ(live.version(), 0u);
  EXPECT_FALSE(live.take_pending());
  EXPECT_EQ(live.params().force_command_filters.slots[0].kind, FilterKind::kNone);
  auto twice = notch;
  twice.emplace_back(slot + "damping", "0.1");
  EXPECT_NE(live.set_many(twice).reason.find("given more than once"), std::string::npos);
  EXPECT_FALSE(live.set_many({{"plant.mechanics.load_mass_kg", "5"}}).accepted);
  EXPECT_FALSE(live.set_many({}).accepted);

  a = live.set_many(notch);
  ASSERT_TRUE(a.accepted) << a.reason;
  EXPECT_EQ(a.version, 5u);
  EXPECT_TRUE(live.take_pending());
  EXPECT_EQ(live.params().force_command_filters.slots[0].kind, FilterKind::kNotch);
  EXPECT_EQ(live.params().force_command_filters.slots[0].frequency_hz, 243.2);
  EXPECT_EQ(live.params().velocity_loop.kp_n_s_per_m, 5980.0);
  ASSERT_EQ(live.history().size(), 5u);
  EXPECT_EQ(live.history()[0].key, slot + "kind");
  EXPECT_EQ(live.history()[0].old_value, "none");
  EXPECT_EQ(live.history()[0].new_value, "notch");
  EXPECT_EQ(live.history()[4].old_value, "10000");
  EXPECT_EQ(live.history()[4].version, 5u);
}

TEST(LiveParameters, TextIsReadAndWrittenByTheEntrysKind) {
  SystemParams p = test::shipped_params();
  set_parameter(p, "kalman.friction_input.enabled", "false");
  EXPECT_FALSE(p.kalman.friction_input.enabled);
  EXPECT_EQ(parameter_text(p, "kalman.friction_input.enabled"), "false");
  set_parameter(p, "plant.integrator", "rk4");
  EXPECT_EQ(parameter_text(p, "plant.integrator"), "rk4");
  set_parameter(p, "commissioning.frequency_response.measure_periods", "8");
  EXPECT_EQ(frequency_response_params(p).measure_periods, 8u);
  EXPECT_THROW(set_parameter(p, "commissioning.frequency_response.measure_periods", "8.5"), std::invalid_argument);
  EXPECT_THROW(set_parameter(p, "commissioning.frequency_response.measure_periods", "-4"), std::invalid_argument);
  EXPECT_EQ(frequency_response_params(p).measure_periods, 8u);
  EXPECT_THROW(set_parameter(p, "compensator.guard.windows_to_trip", "-4"), std::invalid_argument);
  EXPECT_THROW(set_parameter(p, "kalman.friction_input.enabled", "yes"), std::invalid_argument);
  EXPECT_THROW(set_parameter(p, "kalman.process_noise_diag", "1"), std::invalid_argument);
  EXPECT_THROW(parameter_text(p, "no.such.key"), std::invalid_argument);
}

// The controller takes new gains at a tick boundary with its integral: with a constant velocity
// error e, F_k = K_p e + k K_i T e before and K_p' e + k K_i T e after.
TEST(LiveParameters, TheVelocityControllerTakesThemAtATickBoundaryWithItsIntegral) {
  const SystemParams& shipped = test::shipped_params();
  LiveParameters live(shipped, live_keys(SystemParams{}, "controller"));
  VelocityController controller(shipped, test::shipped_scenario("pulse"));
  const double e = 0.001, ki = shipped.velocity_loop.ki_n_per_m, t = shipped.timing.control_period_s;
  for (int k = 0; k < 100; ++k) {
    if (k == 50) {
      ASSERT_TRUE(live.set("velocity_loop.kp_n_s_per_m", "12000").accepted);
      ASSERT_TRUE(live.take_pending());
      controller.retune(live.params());
    }
    const double kp = k < 50 ? 10000.0 : 12000.0;
    const VelocityControllerOutput out = controller.step_command(0.0, -e, {});
    EXPECT_NEAR(out.force_n, kp * e + k * ki * t * e, 1e-9) << k;
  }
  // A filter slot set live acts from the next tick: a full notch at 10 Hz on the compensation.
  for (const auto& [key, value] :
       {std::pair<std::string, std::string>{"frequency_hz", "10"}, {"second_damping", "0.3"}, {"kind", "notch"}}) {
    ASSERT_TRUE(live.set("filters.compensation.slot_2." + key, value).accepted) << key;
  }
  controller.retune(live.params());
  double peak = 0;
  for (int k = 0; k < 3000; ++k) {
    const double compensation_n = 50.0 * std::sin(2 * M_PI * 10.0 * k * t);
    const VelocityControllerOutput out = controller.step_command(0.0, -e, {compensation_n, 0.1});
    if (k > 2000) peak = std::max(peak, std::fabs(out.compensation_applied_n));
  }
  EXPECT_LT(peak, 0.5);  // 50 N at the notch's centre: gone
}

// The compensator nodes' live keys: acceleration feedback's K_a, state feedback's design ratios
// and the RNN's online rule, each checked with the file's ranges, reaching the law at a tick
// boundary; state feedback and the RNN keep their state and refuse a change of what they were
// built on.
TEST(LiveParameters, TheCompensatorsTakeTheirGainsLive) {
  const SystemParams& shipped = test::shipped_params();
  LiveParameters accel_live(shipped, live_keys(SystemParams{}, "accel_feedback"));
  ASSERT_TRUE(accel_live.set("compensator.acceleration_feedback.gain_kg", "120").accepted);
  EXPECT_FALSE(accel_live.set("compensator.acceleration_feedback.gain_kg", "-1").accepted);
  EXPECT_FALSE(accel_live.set("velocity_loop.kp_n_s_per_m", "9000").accepted);  // the controller's
  AccelFeedback accel(shipped.accel_feedback_params());
  ASSERT_TRUE(accel_live.take_pending());
  accel.set_params(accel_live.params().accel_feedback_params());
  EXPECT_DOUBLE_EQ(accel.step({1.0, 0.0}), -120.0 * shipped.compensator_gain_scale());

  LiveParameters state_live(shipped, live_keys(SystemParams{}, "state_feedback"));
  ASSERT_TRUE(state_live.set("compensator.state_feedback.correction_damping_ratio", "0.3").accepted);
  StateFeedback state(shipped.state_feedback_params());
  for (int k = 0; k < 50; ++k) state.step({0.2, 0.1, 1.0, 0.1, 5.0});
  const double model_spring_n = state.model_spring_force_n();
  state.set_params(state_live.params().state_feedback_params());
  EXPECT_EQ(state.params().correction_damping_ratio, 0.3);
  ASSERT_TRUE(state_live.set("compensator.state_feedback.friction_feedforward.coulomb_n", "15").accepted);
  state.set_params(state_live.params().state_feedback_params());
  EXPECT_EQ(state.params().friction_coulomb_n, 15.0);
  EXPECT_EQ(state.model_spring_force_n(), model_spring_n);  // the model's state kept
  StateFeedbackParams other_model = state.params();
  other_model.model.load_mass_kg = 5.0;
  EXPECT_THROW(state.set_params(other_model), std::invalid_argument);
  EXPECT_EQ(state.params().model.load_mass_kg, shipped.state_feedback_params().model.load_mass_kg);

  // The RNN's online rule: its settings live, its weights and state kept; the momentum's
  // contraction (alpha k_c < 1) checked with the change in it; its network's scales not live.
  LiveParameters rnn_live(shipped, live_keys(SystemParams{}, "rnn_compensator"));
  ASSERT_TRUE(rnn_live.set("compensator.rnn.learning_rate", "0.002").accepted);
  const LiveAnswer contraction = rnn_live.set("compensator.rnn.kc_limit_mps", "2");
  EXPECT_FALSE(contraction.accepted);
  EXPECT_NE(contraction.reason.find("momentum * kc_limit_mps must be < 1"), std::string::npos) << contraction.reason;
  EXPECT_FALSE(rnn_live.set("compensator.rnn.gain_n", "500").accepted);
  RnnCompensator rnn(shipped.rnn_compensator_params(true));
  std::vector<double> weights(rnn.weights().size(), 0.1);
  rnn.set_weights(weights);
  for (int k = 0; k < 20; ++k) rnn.step({0.5 * k, 0.1, 0.0, 0.0});
  const std::vector<double> learned = rnn.weights();
  const CompensatorStep before = rnn.step({2.0, 0.1, 0.0, 0.0});
  RnnCompensator twin = rnn;
  rnn.set_learning(rnn_live.params().rnn_compensator_params(true));
  EXPECT_EQ(rnn.params().learning_rate, 0.002);
  EXPECT_EQ(rnn.weights(), twin.weights());
  EXPECT_EQ(rnn.step({2.0, 0.1, 0.0, 0.0}).force_n, twin.step({2.0, 0.1, 0.0, 0.0}).force_n);  // state kept
  EXPECT_NE(learned, weights);
  EXPECT_TRUE(std::isfinite(before.force_n));
  RnnCompensatorParams other = rnn.params();
  other.gain_n = 500.0;
  EXPECT_THROW(rnn.set_learning(other), std::invalid_argument);
  other = rnn.params();
  other.online_learning = false;
  EXPECT_THROW(rnn.set_learning(other), std::invalid_argument);
  // Its output scale (what the commissioning tunes) is live: the next force scaled, nothing else.
  ASSERT_TRUE(rnn_live.set("compensator.rnn.output_scale", "1.25").accepted);
  twin = rnn;
  rnn.set_learning(rnn_live.params().rnn_compensator_params(true));
  EXPECT_EQ(rnn.params().output_scale, 1.25 * twin.params().output_scale);
  EXPECT_EQ(rnn.weights(), twin.weights());
  EXPECT_DOUBLE_EQ(rnn.step({2.0, 0.1, 0.0, 0.0}).force_n, 1.25 * twin.step({2.0, 0.1, 0.0, 0.0}).force_n);
  EXPECT_FALSE(rnn_live.set("compensator.rnn.output_scale", "0").accepted);
  EXPECT_EQ(rnn.params().gain_n, shipped.rnn_compensator_params(true).gain_n);
}

// Who takes a parameter live is said once, in its declaration: each node's live keys are the
// entries that name it, in the table's order, and nobody else gets any.
TEST(LiveParameters, EachNodesLiveKeysAreTheDeclarationsThatNameIt) {
  const std::vector<std::string> controller = live_keys(SystemParams{}, "controller");
  ASSERT_EQ(controller.size(), 4u + 2u * 4u * 5u);
  EXPECT_EQ(controller[0], "velocity_loop.kp_n_s_per_m");
  EXPECT_EQ(controller[1], "velocity_loop.ki_n_per_m");
  EXPECT_EQ(controller[2], "position_loop.gain_per_s");
  EXPECT_EQ(controller[3], "position_loop.max_correction_mps");
  EXPECT_EQ(controller[4], "filters.force_command.slot_1.kind");
  EXPECT_EQ(controller.back(), "filters.compensation.slot_4.second_damping");
  EXPECT_EQ(live_keys(SystemParams{}, "accel_feedback"),
            std::vector<std::string>{"compensator.acceleration_feedback.gain_kg"});
  const std::string sf = "compensator.state_feedback.";
  EXPECT_EQ(live_keys(SystemParams{}, "state_feedback"),
            (std::vector<std::string>{
                sf + "model_frequency_ratio", sf + "model_damping_ratio", sf + "correction_damping_ratio",
                sf + "max_correction_gain", sf + "friction_feedforward.coulomb_n",
                sf + "friction_feedforward.viscous_n_s_per_m", sf + "friction_feedforward.band_mps"}));
  const std::string rnn = "compensator.rnn.";
  EXPECT_EQ(live_keys(SystemParams{}, "rnn_compensator"),
            (std::vector<std::string>{rnn + "output_scale", rnn + "learning_rate", rnn + "momentum",
                                      rnn + "tolerance_mps", rnn + "kc_limit_mps", rnn + "du_deadband_per_s",
                                      rnn + "rest_settle_s", rnn + "rest_fade_s"}));
  EXPECT_TRUE(live_keys(SystemParams{}, "plant_sim").empty());
  EXPECT_TRUE(live_keys(SystemParams{}, "").empty());
}

// A change the controller would take but a value derived from it elsewhere refuses (state
// feedback's model needs a positive Kp) is refused whole, the old value kept, both named.
TEST(LiveParameters, AChangeADerivedValueRefusesIsRefusedNamingBoth) {
  LiveParameters live(test::shipped_params(), live_keys(SystemParams{}, "controller"));
  expect_live_refused(live, "velocity_loop.kp_n_s_per_m", "0",
                      "velocity_loop.kp_n_s_per_m = 0 refused by a value derived");
  const LiveAnswer a = live.set("velocity_loop.kp_n_s_per_m", "0");
  EXPECT_NE(a.reason.find("compensator.state_feedback.velocity_gain_n_s_per_m"), std::string::npos) << a.reason;
  const LiveAnswer many = live.set_many({{"velocity_loop.kp_n_s_per_m", "0"}, {"velocity_loop.ki_n_per_m", "1000"}});
  EXPECT_FALSE(many.accepted);
  EXPECT_NE(many.reason.find("the 2 changes refused by a value derived from them: compensator.state_feedback."),
            std::string::npos)
      << many.reason;
  EXPECT_EQ(live.get("velocity_loop.ki_n_per_m").value, format_value(test::shipped_params().velocity_loop.ki_n_per_m));
}

// A Kp change retimes the input shaper to the loop's new mode, its past commands kept: at speed
// the output does not move, and the taps are the new mode's.
TEST(LiveParameters, AGainChangeRetimesTheInputShaperWithItsPastKept) {
  const SystemParams& shipped = test::shipped_params();
  Scenario scenario = test::shipped_scenario("pulse");
  scenario.input_shaper = ShaperKind::kZvd;
  VelocityController controller(shipped, scenario);
  ASSERT_NE(controller.input_shaper(), nullptr);
  const std::vector<double> before = controller.input_shaper()->tap_weights();
  double out = 0;
  for (int k = 0; k < 500; ++k) out = controller.step_command(0.1, 0.1, {}).command_mps;
  EXPECT_NEAR(out, 0.1, 1e-12);
  LiveParameters live(shipped, live_keys(SystemParams{}, "controller"));
  ASSERT_TRUE(live.set("velocity_loop.kp_n_s_per_m", "14000").accepted);
  controller.retune(live.params());
  const std::vector<double> after = controller.input_shaper()->tap_weights();
  EXPECT_EQ(after, InputShaper(live.params().input_shaper_params(ShaperKind::kZvd)).tap_weights());
  EXPECT_NE(after, before);
  EXPECT_NEAR(controller.step_command(0.1, 0.1, {}).command_mps, 0.1, 1e-12);

  // The shaper alone: a step's past is kept across a retune to a longer span.
  InputShaperParams p = shipped.input_shaper_params(ShaperKind::kZv);
  InputShaper shaper(p);
  for (int k = 0; k < 3; ++k) shaper.step(1.0);
  InputShaper twin(p);
  p.frequency_hz *= 0.5;
  twin.retune(p);
  shaper.retune(p);
  InputShaper fresh(p);
  for (int k = 0; k < 3; ++k) fresh.step(1.0);
  for (int k = 0; k < 400; ++k) EXPECT_DOUBLE_EQ(shaper.step(1.0), fresh.step(1.0)) << k;
  EXPECT_DOUBLE_EQ(twin.step(0.0), 0.0);
}

// The owner's changes followed by a dependent (state feedback follows the controller's Kp): taken
// at the tick the owner computed with them, a version not heard yet said missing, repeats
// ignored, gaps and bad entries refused, an owner that restarted forgotten.
TEST(FollowedParameters, TheOwnersChangesApplyAtTheTickItComputedWithThem) {
  const SystemParams& shipped = test::shipped_params();
  FollowedParameters followed("controller", shipped);
  EXPECT_EQ(followed.offer(1, {{"velocity_loop.kp_n_s_per_m", "12000"}}), "");
  FollowedParameters::Step step = followed.at_tick(0);
  EXPECT_FALSE(step.changed);
  EXPECT_FALSE(step.missing);
  step = followed.at_tick(1);
  EXPECT_TRUE(step.changed);
  ASSERT_EQ(followed.applied_now().size(), 1u);
  EXPECT_EQ(followed.applied_now()[0].old_value, "10000");
  EXPECT_EQ(followed.applied_now()[0].new_value, "12000");
  SystemParams mine = shipped;
  mine.compensator.state_feedback.model_damping_ratio = 0.9;  // the node's own change stays
  followed.overlay(mine);
  EXPECT_EQ(mine.state_feedback_params().velocity_gain_n_s_per_m, 12000.0);
  EXPECT_EQ(mine.compensator.state_feedback.model_damping_ratio, 0.9);
  EXPECT_FALSE(followed.at_tick(1).changed);

  EXPECT_EQ(followed.offer(1, {{"velocity_loop.kp_n_s_per_m", "12000"}}), "");  // a repeat
  step = followed.at_tick(3);
  EXPECT_TRUE(step.missing);
  EXPECT_FALSE(step.changed);
  EXPECT_NE(followed.offer(5, {{"velocity_loop.ki_n_per_m", "1"}}).find("was not heard"), std::string::npos);
  EXPECT_NE(followed.offer(2, {{"velocity_loop.no_such", "1"}}).find("no such parameter"), std::string::npos);
  EXPECT_NE(followed.offer(2, {{"velocity_loop.ki_n_per_m", "x"}}).find("expected a number"), std::string::npos);
  EXPECT_EQ(followed.offer(3, {{"velocity_loop.ki_n_per_m", "2000"}, {"velocity_loop.kp_n_s_per_m", "9000"}}), "");
  EXPECT_EQ(followed.offered_version(), 3u);
  step = followed.at_tick(3);
  EXPECT_TRUE(step.changed);
  EXPECT_FALSE(step.missing);
  ASSERT_EQ(followed.applied_now().size(), 2u);
  EXPECT_EQ(followed.applied_now()[1].old_value, "12000");
  EXPECT_EQ(followed.applied_version(), 3u);
  mine = shipped;
  followed.overlay(mine);
  EXPECT_EQ(mine.velocity_loop.kp_n_s_per_m, 9000.0);
  EXPECT_EQ(mine.velocity_loop.ki_n_per_m, 2000.0);

  step = followed.at_tick(0);  // the controller restarted from its file
  EXPECT_TRUE(step.owner_restarted);
  EXPECT_TRUE(step.changed);
  mine = shipped;
  followed.overlay(mine);
  EXPECT_EQ(mine.velocity_loop.kp_n_s_per_m, shipped.velocity_loop.kp_n_s_per_m);
  EXPECT_EQ(followed.offer(1, {{"velocity_loop.kp_n_s_per_m", "11000"}}), "");
  EXPECT_TRUE(followed.at_tick(1).changed);
}

// The position loop in the velocity controller: the PI follows V_ref + K_x (x_ref - x_L) from the
// load's encoder, its gain taken live, and a load reading the controller's monitor refuses (here
// NaN: a silent sensor) hands the loop to the motor's encoder without a step in the force.
TEST(LiveParameters, TheDualLoopFollowsTheLoadTakesItsGainLiveAndFallsBackWithoutAStep) {
  SystemParams p = test::shipped_params();
  p.load_sensor.kind = LoadSensorKind::kEncoder;
  p.position_loop.closes_on = PositionFeedback::kLoad;
  p.position_loop.gain_per_s = 2.0;
  p.validate();
  LiveParameters live(p, live_keys(SystemParams{}, "controller"));
  VelocityController controller(p, test::shipped_scenario("pulse"));
  const double kp = p.velocity_loop.kp_n_s_per_m;
  // At rest, the motor at 1 mm, the load held 30 um short of where it started (the scales'
  // zeros differ): 2/s x 30 um = 60 um/s asked of the motor, K_p times it in force.
  LoadWitness witness;
  witness.motor_position_m = 1e-3;
  witness.reading.position_m = 0.5;
  controller.step_command(0.0, 0.0, {}, witness);
  witness.reading.position_m = 0.5 - 30e-6;
  VelocityControllerOutput out = controller.step_command(0.0, 0.0, {}, witness);
  EXPECT_TRUE(out.position.on_load);
  EXPECT_NEAR(out.position.correction_mps, 60e-6, 1e-12);
  EXPECT_NEAR(out.force_n, kp * 60e-6 + p.velocity_loop.ki_n_per_m * p.timing.control_period_s * 60e-6, 1e-6);
  ASSERT_TRUE(live.set("position_loop.gain_per_s", "4").accepted);
  ASSERT_TRUE(live.take_pending());
  controller.retune(live.params());
  out = controller.step_command(0.0, 0.0, {}, witness);
  EXPECT_NEAR(out.position.correction_mps, 120e-6, 1e-12);
  EXPECT_FALSE(live.set("position_loop.closes_on", "motor").accepted)
      << "the encoder a loop closes on is read at start";
  // Silent: the motor's encoder from the same error on, and it follows the motor from there.
  witness.reading.position_m = std::numeric_limits<double>::quiet_NaN();
  out = controller.step_command(0.0, 0.0, {}, witness);
  EXPECT_FALSE(out.position.on_load);
  EXPECT_NEAR(out.position.correction_mps, 120e-6, 1e-12);
  witness.motor_position_m += 10e-6;
  out = controller.step_command(0.0, 0.0, {}, witness);
  EXPECT_NEAR(out.position.position_error_m, 20e-6, 1e-12);
  EXPECT_EQ(controller.position_loop().counters().switches_to_motor, 1u);
  // The paper's loop (closes_on none) is not moved by either encoder.
  VelocityController paper(test::shipped_params(), test::shipped_scenario("pulse"));
  EXPECT_EQ(paper.step_command(0.0, 0.0, {}, witness).position.correction_mps, 0.0);
}

TEST(LiveParameters, ADualLoopWithoutALoadEncoderIsRefusedNamingTheSensor) {
  SystemParams p = test::shipped_params();
  p.position_loop.closes_on = PositionFeedback::kLoad;
  for (const LoadSensorKind kind : {LoadSensorKind::kNone, LoadSensorKind::kAccelerometer}) {
    p.load_sensor.kind = kind;
    try {
      p.validate();
      ADD_FAILURE() << "closes_on load taken with sensors.load.kind " << to_string(kind);
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("closes_on: load needs an encoder on the load"), std::string::npos)
          << e.what();
    }
  }
  p.position_loop.closes_on = PositionFeedback::kMotor;
  EXPECT_NO_THROW(p.validate());
}

}  // namespace
}  // namespace pmlsm
